"""The light-independent inputs of tsd/irradiance.frag in texture space, and the full-screen pass
that adds the lights to them.

The irradiance entering the skin (d'Eon & Luebke 2007, 14.4.1 and 14.5.2; common/skin_irradiance.glsl)
is E = sum_lights E_i(P, Ng, N, rho_s, m, c) + E_a(N, Ng, rho_s, m, vis), times albedo^mix. Everything
but the lights' sum depends on the content alone (mesh, layout, material, environment, the directional
albedo): it is rasterised once per product key "interreflection_inputs" (dermis.invalidation) into
five targets (tsd/irradiance.frag with SKIN_BOUNCE_INPUTS):

  0: P (world units), rho_s     1: N (normal-mapped), m     2: Ng (0 off the mesh: coverage), E_a.b
  3: c (directional albedo), E_a.r     4: albedo^mix, E_a.g

and, for tsd's bounce, a sixth (SKIN_INPUTS_ALBEDO_REST): albedo^(1 - mix). Per lighting change one
full-screen pass over the same texels (tsd/irradiance.frag with SKIN_BOUNCE_FROM_INPUTS, its lights
unrolled per count: LightCountPrograms) reads them back with texel fetches and adds the lights: the same
sums in the same order as the one mesh raster, so the same floats where the inputs are 32-bit.

Used by the shared bounce (dermis.gl.interreflection.SharedBounce: rho E, mix = 1, since round 11) and by
tsd's irradiance pass (dermis.techniques.tsd, since round 16). Why: on llvmpipe the mesh raster of ~18k
triangles of ~14 texels each shades many half-covered 4x4 blocks and samples 4 filtered maps, the normal
map and the environment per texel; the full-screen pass shades each texel once with 5-6 texel fetches
(benchmarks/RESULTS.md, "Round 11, branch perf11" and "Round 16, branch perf16")."""

from __future__ import annotations

import moderngl

BOUNCE_INPUTS = 5
"""Targets of the light-independent inputs read as the sampler array uBounceInputs (tsd/irradiance.frag)."""

ALBEDO_REST = 5
"""The sixth target's index (tsd only): albedo^(1 - mix), read as uAlbedoRest."""


class IrradianceInputs:
    """The input targets on one context (made as 1x1 stand-ins, re-made at their size on first use: the
    count of live GPU objects never changes) and the program that rasterises them.

    ``albedo_rest``: add the sixth target (tsd's rho E = I_0 albedo^(1 - mix)).
    ``dtypes``: each target's moderngl dtype ("f4" or "f2"); P and the normals stay 32-bit (they place
    the shadow lookups), the colour factors may go to 16 bits (what the irradiance target itself holds)."""

    def __init__(self, ctx, *, albedo_rest: bool = False, dtypes: tuple | None = None):
        from dermis.gl.shaders import program

        self.ctx = ctx
        self.count = BOUNCE_INPUTS + (1 if albedo_rest else 0)
        self.dtypes = tuple(dtypes) if dtypes is not None else ("f4",) * self.count
        if len(self.dtypes) != self.count:
            raise ValueError(f"{self.count} dtypes needed, got {len(self.dtypes)}")
        defines = {"SKIN_BOUNCE_INPUTS": 1, **({"SKIN_INPUTS_ALBEDO_REST": 1} if albedo_rest else {})}
        self.prog = program(ctx, "tsd/uv_space.vert", "tsd/irradiance.frag", defines)
        self.textures = []
        self.fbo = None
        self._make((1, 1))
        self.key = None

    def _make(self, size: tuple):
        self._release_targets()
        for dtype in self.dtypes:
            t = self.ctx.texture(size, 4, dtype=dtype)
            t.filter = (moderngl.NEAREST, moderngl.NEAREST)
            self.textures.append(t)
        self.fbo = self.ctx.framebuffer(color_attachments=self.textures)

    def _release_targets(self):
        if self.fbo is not None:
            self.fbo.release()
        for t in self.textures:
            t.release()
        self.fbo, self.textures = None, []

    @property
    def nbytes(self) -> int:
        """GPU memory of the targets (bytes)."""
        return sum(t.size[0] * t.size[1] * 4 * (4 if d == "f4" else 2) for t, d in zip(self.textures, self.dtypes))

    def draw(self, frame, size: tuple, mix: float | None = None, pass_name: str = "interreflection_inputs") -> bool:
        """Rasterise the inputs at ``size`` when their key ("interreflection_inputs", the size, ``mix``)
        changed; ``mix``: albedo^mix's exponent (None: the material's, as bind_scene sets it). Times
        itself as ``pass_name`` and appends it to frame.passes_run when drawn. Returns whether it drew."""
        size = tuple(int(s) for s in size)
        key = (frame.keys["interreflection_inputs"], size, mix)
        if key == self.key:
            return False
        with frame.timer(pass_name):
            self._raster(frame, size, mix)
        self.key = key
        frame.passes_run.append(pass_name)
        return True

    def _raster(self, frame, size, mix):
        from dermis.gl.resources import maps_without_anisotropy, set_uniform
        from dermis.techniques.base import bind_scene
        from dermis.techniques.shared import directional_albedo_uniforms

        if self.textures[0].size != size:
            self._make(size)
        prog = self.prog
        bind_scene(frame, prog)
        directional_albedo_uniforms(prog, frame.scene)
        if mix is not None:
            set_uniform(prog, "uMix", float(mix))  # after bind_scene's material uniforms
        self.fbo.use()
        self.fbo.viewport = (0, 0, *size)
        self.fbo.clear(0.0, 0.0, 0.0, 0.0)  # Ng = 0 off the layout: coverage 0
        self.ctx.disable(moderngl.DEPTH_TEST | moderngl.CULL_FACE | moderngl.BLEND)
        # a texture-space raster: the maps' footprint is square, anisotropy only costs
        with maps_without_anisotropy(frame.gpu, surfaces=False):
            frame.gpu.vao(prog).render(moderngl.TRIANGLES)

    def bind(self, prog, first_unit: int):
        """The light pass's samplers: uBounceInputs[0..4] from ``first_unit``, uAlbedoRest after them."""
        from dermis.techniques.shared import bind_sampler, bind_sampler_array

        bind_sampler_array(prog, "uBounceInputs", self.textures[:BOUNCE_INPUTS], first_unit)
        if self.count > BOUNCE_INPUTS:
            bind_sampler(prog, "uAlbedoRest", self.textures[ALBEDO_REST], int(first_unit) + BOUNCE_INPUTS)

    def shrink(self):
        """Free the targets' memory (1x1 stand-ins, re-made at their size by the next draw)."""
        if self.textures[0].size != (1, 1):
            self._make((1, 1))
        self.key = None

    def forget(self):
        """Forget what was drawn (the next draw redraws), keeping the targets."""
        self.key = None

    def release(self):
        self._release_targets()
        self.key = None
        self.prog.release()


def light_pass(ctx, vao_cache: dict, prog, target_fbo, size):
    """Draw the full-screen light pass ``prog`` (its uniforms and samplers bound) into ``target_fbo``
    over ``size``: every texel written (0 off the mesh, as a cleared raster target)."""
    target_fbo.use()
    target_fbo.viewport = (0, 0, *size)
    ctx.disable(moderngl.DEPTH_TEST | moderngl.CULL_FACE | moderngl.BLEND)
    if prog not in vao_cache:
        vao_cache[prog] = ctx.vertex_array(prog, [])
    vao_cache[prog].render(moderngl.TRIANGLES, vertices=3)
