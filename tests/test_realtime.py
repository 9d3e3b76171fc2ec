"""Real-time on a CPU (issue 14): the viewer's reduced frames without MSAA. Timings are benchmarks
(`dermis bench`, `dermis bench --viewer`), never asserted here."""

from __future__ import annotations

import numpy as np

from dermis.renderer import Renderer
from dermis.verification import quad_scene


def test_a_frame_can_drop_msaa_without_touching_the_renderers_own_samples(gl_ctx):
    sc = quad_scene(25.6, 25.6)
    sc.camera.position = (8.0, 5.0, 70.0)  # the quad's edges cross pixels: MSAA changes them
    with Renderer(sc, (48, 48), ctx=gl_ctx, samples=4, irradiance_size=128, shadow_size=512) as r:
        full = r.render("lambert")
        one = r.render("lambert", samples=0)
        again = r.render("lambert")
        assert r.samples == 4
    with Renderer(sc, (48, 48), ctx=gl_ctx, samples=0, irradiance_size=128, shadow_size=512) as r1:
        ref_one = r1.render("lambert")
    np.testing.assert_array_equal(again, full)  # the 4x targets were kept and are used again
    np.testing.assert_allclose(one, ref_one, atol=1e-6)  # the same frame as a 1x Renderer's
    edge = np.abs(full - one).max(axis=2) > 1e-4
    assert 0 < edge.mean() < 0.2  # only the antialiased edges differ


def test_refine_waits_after_input_but_not_after_a_drags_release():
    """The progressive viewer refines REFINE_AFTER_S after the last input, never while a drag is
    held, and at once after a drag's mouse button is released (the release ends the input)."""
    import time

    from dermis.viewer.progressive import REFINE_AFTER_S, ProgressiveRenderer

    p = ProgressiveRenderer(full=None)
    assert not p.needs_refine()  # the last image is the full one
    p.quality = "interactive"
    p.last_input_time = now = time.perf_counter()
    assert not p.needs_refine(now + 0.5 * REFINE_AFTER_S)
    assert p.needs_refine(now + 1.5 * REFINE_AFTER_S)
    assert not p.needs_refine(now + 1.5 * REFINE_AFTER_S, input_held=True)
    p.input_released()
    assert p.needs_refine(now)  # no wait after the release
    assert not p.needs_refine(now, input_held=True)


def test_reduced_frames_sample_the_maps_without_anisotropic_filtering(gl_ctx, example_head_toml):
    """A reduced (interactive) frame draws with the material maps at 1x anisotropy (8x costs
    llvmpipe's final pass up to 13x); the full frame that follows has the maps' own 8x back."""
    import dermis
    from dermis.renderer import Renderer
    from dermis.viewer.progressive import ProgressiveRenderer

    scene = dermis.load_scene(example_head_toml)
    with Renderer(scene, (96, 64), ctx=gl_ctx, irradiance_size=128, shadow_size=256) as full:
        full.render("tsd")  # the first full frame: the maps are uploaded
        mipmapped = [t for t in full.gpu.textures.values() if t.anisotropy > 1.0]
        assert mipmapped, "the head's maps are mipmapped with anisotropic filtering"
        seen = []
        render = full.render

        def recording_render(*args, **kwargs):
            seen.append(sorted({t.anisotropy for t in mipmapped}))
            return render(*args, **kwargs)

        full.render = recording_render
        p = ProgressiveRenderer(full)
        p._full_lighting = full.last_frame.lighting_key  # the orbit case: the full renderer draws it
        small = p.render("tsd", (96, 64), None, interactive=True)
        assert p.stats["renderer"] == "full" and small.shape[0] < 64
        after = sorted({t.anisotropy for t in mipmapped})
        p.render("tsd", (96, 64), None, interactive=False)
        assert seen == [[1.0], after] and after == [8.0], (seen, after)
