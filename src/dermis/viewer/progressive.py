"""Progressive rendering for the viewer: cheap frames while the user drags, the full frame after.

On a CPU rasteriser a full tsd frame of the head costs about a second when the lights move and
a few hundred ms when only the camera does, far from interactive. While input is active the
viewer therefore draws *interactive* frames, and when input stops it draws one *full* frame:

- interactive, camera or output changed: the full-quality renderer (its texture-space passes are
  cached on the lighting key, so only the final pass runs) at a reduced output size and without
  MSAA (the final pass's cost on a CPU rasteriser is per sample);
- interactive, lighting changed (light drag, skin or material sliders): a second, small renderer
  (irradiance and shadow textures at a fraction of the full size, no MSAA) at a reduced output
  size: every view-independent pass re-runs, on 1/16 of the texels;
- full: the full-quality renderer at the window's size: the same image ``dermis render`` makes
  of that view with the same settings.

The reduced output size adapts: after each interactive frame the scale moves one step (of 1/8)
towards the one that would have met ``target_ms``, so the frame rate holds on slow and fast
machines alike without flickering between sizes.
"""

from __future__ import annotations

import math
import time

SCALE_STEPS = (0.25, 0.375, 0.5, 0.625, 0.75, 0.875, 1.0)
# texels per side of the interactive renderer's texture space (at most): a preview while a light or a
# slider moves; at the reduced sizes the viewer settles on (1/4-1/2 of the window) the head gets about
# one texel per 2-4 pixels. 128 instead of 256 made a light-drag frame of the head 1.7x cheaper
# (764 vs 1296 ms at 240x160, load 9.9; benchmarks/RESULTS.md, issue 14)
FAST_IRRADIANCE = 128
FAST_SHADOW = 512      # shadow tile size of the interactive renderer
# orders of the bounce light in a preview while a light moves: the one bounce (each further order
# costs a texture-space raster and a gather per lighting change: +50 ms a frame on llvmpipe, round 13)
FAST_BOUNCE_ORDERS = 1
REFINE_AFTER_S = 0.2   # an interactive session refines this long after the last input
# ... except after a mouse drag's release, which ends the input for sure: the refine starts with the
# next frame (input_released), 0.2 s of the wait for the full frame after a light drag saved
INTERACTIVE_SAMPLES = 0  # MSAA samples of a reduced frame (the full frame has the Renderer's)


def _without_anisotropy(renderer):
    """A reduced frame samples the material maps (skin and non-skin surfaces) without anisotropic
    filtering (8x costs llvmpipe's tsd final pass 1.2-13x: RESULTS, round 4); the maps' own setting
    comes back for the full frame."""
    from dermis.gl.resources import maps_without_anisotropy

    return maps_without_anisotropy(getattr(renderer, "gpu", None))


class ProgressiveRenderer:
    """Chooses and renders each frame's quality. ``render(view_changed, ...)`` returns the image
    and the quality it was drawn at: "interactive" or "full"."""

    def __init__(self, full, *, target_ms: float = 80.0, start_scale: float = 0.5, enabled: bool = True):
        self.full = full          # the Renderer whose frames are the reference
        self.fast = None          # created on the first lighting change
        self.target_ms = float(target_ms)
        self.scale_index = SCALE_STEPS.index(min(SCALE_STEPS, key=lambda s: abs(s - start_scale)))
        self.enabled = enabled
        self.quality = "full"     # of the image last drawn
        self._full_lighting = None  # lighting key the full renderer's texture space holds
        self.last_input_time = -math.inf
        self._released_at = None  # when a drag's mouse button was released (input_released)
        self._pinned = False      # pin_scale: the scale is set, not adapted
        self.stats = {}

    @property
    def scale(self) -> float:
        return SCALE_STEPS[self.scale_index]

    def _fast_renderer(self):
        from dermis.renderer import Renderer

        full = self.full
        irr = min(FAST_IRRADIANCE, full.irradiance_size)
        if self.fast is None:
            self.fast = Renderer(full.scene, full.size, ctx=full.ctx, samples=0, irradiance_size=irr,
                                 shadow_size=min(FAST_SHADOW, full.shadows.tile_size))
            self.fast.target_sizes_kept = 1  # it only ever draws the current reduced size
            self.fast.bounce_orders = FAST_BOUNCE_ORDERS
        else:
            if self.fast.irradiance_size != irr:
                self.fast.set_irradiance_size(irr)  # keeps its render targets and programs
            if self.fast.scene is not full.scene:
                self.fast.set_scene(full.scene)
        # the same techniques as the full renderer, built up front: a switch mid-drag does not
        # compile (and the viewer's GPU objects settle once both renderers are warm)
        for name in full.techniques_built:
            self.fast.technique(name)
        return self.fast

    def needs_refine(self, now: float | None = None, input_held: bool = False) -> bool:
        """Whether the last image is a reduced one that should now be replaced by the full frame."""
        if self.quality == "full" or input_held:
            return False
        if self._released_at is not None:
            return True
        now = time.perf_counter() if now is None else now
        return now - self.last_input_time >= REFINE_AFTER_S

    def input_released(self):
        """The drag ended (mouse button released): the next frame may refine without waiting."""
        self._released_at = time.perf_counter()

    def render(self, technique: str, size, camera, *, interactive: bool, lighting_key: str | None = None):
        """Render one frame; ``interactive`` asks for a reduced frame (input is active).
        ``lighting_key``: the full renderer's lighting key of this frame if the caller has it
        (computing it hashes the material maps)."""
        full = self.full
        if interactive and self.enabled:
            self.last_input_time = time.perf_counter()
            # input after the release (not the drag's last motion, drawn just after it) waits again
            if self._released_at is not None and self.last_input_time - self._released_at > REFINE_AFTER_S:
                self._released_at = None
            w, h = size
            small = (max(1, int(round(w * self.scale))), max(1, int(round(h * self.scale))))
            lighting = lighting_key or full.lighting_key()
            r = full if lighting == self._full_lighting else self._fast_renderer()
            with _without_anisotropy(r):
                img = r.render(technique, size=small, camera=camera, samples=INTERACTIVE_SAMPLES)
            self._adapt(r.stats["frame_ms"])
            self.stats = dict(r.stats, quality="interactive", scale=self.scale,
                              renderer="full" if r is full else "fast")
            self.quality = "interactive"
            return img
        img = full.render(technique, size=size, camera=camera)
        self._released_at = None
        self._full_lighting = full.last_frame.lighting_key  # the key this frame was built with
        self.stats = dict(full.stats, quality="full", scale=1.0, renderer="full")
        self.quality = "full"
        return img

    def pin_scale(self, scale: float | None):
        """Draw the reduced frames at ``scale`` (one of SCALE_STEPS) instead of adapting it to the
        frame time (None: adapt again, from ``scale``'s step): a scripted session's frames then do
        not depend on the machine's speed or load."""
        self._pinned = scale is not None
        if scale is not None:
            self.scale_index = SCALE_STEPS.index(scale)

    def _adapt(self, frame_ms: float):
        """One step of the output scale towards the one that would have met target_ms
        (time ~ pixels ~ scale^2)."""
        if self._pinned:
            return
        want = self.scale * math.sqrt(self.target_ms / max(frame_ms, 1e-3))
        if want < self.scale * 0.9 and self.scale_index > 0:
            self.scale_index -= 1
        elif want > SCALE_STEPS[min(self.scale_index + 1, len(SCALE_STEPS) - 1)] * 1.1 \
                and self.scale_index < len(SCALE_STEPS) - 1:
            self.scale_index += 1

    def release(self):
        if self.fast is not None:
            self.fast.release()
            self.fast = None
