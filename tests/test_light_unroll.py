"""The light loops of lambert (lambert.frag), ssss (its irradiance pass, common/skin_irradiance.glsl,
and its final pass's specular, common/skin_specular.glsl) and preintegrated (preintegrated/skin.frag) unrolled at constant indices: SKIN_LIGHT_COUNT,
DERMIS_FOR_EACH_LIGHT in common/lights.glsl, one program per light count through
dermis.techniques.shared.LightCountPrograms (tsd's irradiance pass: tests/test_tsd_light_unroll.py).
The reference is the loop over uLightCount compiled from the same sources and defines but
SKIN_LIGHT_COUNT: the same arithmetic, so the images must agree to float rounding (1e-5 of the
largest value) for 1, 2, 3 and 5 lights, the key light in the last slot (a light dropped or read
from another slot differs there by far more, which the guard test checks); a live Renderer
switching light counts draws what fresh ones draw; the pore-free variant (shading_program) is
compiled from the per-count program."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from dermis.gl.shaders import program
from dermis.renderer import Renderer
from dermis.techniques.shared import LIGHT_COUNT_DEFINE, SIGNATURE_DEFINES, interreflection_on

from test_shadow_edge_rim import H, W
from test_tsd_sharp_shadow import _scene

KW = dict(samples=0, irradiance_size=256, shadow_size=1024)
REL = 1e-5
TECHNIQUES = ("lambert", "ssss", "preintegrated")


def _swapped(gl_ctx, lcp, lights, count):
    """``lcp``'s program for ``lights`` compiled again without SKIN_LIGHT_COUNT and the light signature
    (``count`` None: the loop over uLightCount) or unrolled for ``count`` lights."""
    vertex, fragment, defines, _ = lcp(len(lights), lights).extra["sources"]
    defines = {k: v for k, v in defines.items() if k not in (LIGHT_COUNT_DEFINE, *SIGNATURE_DEFINES)}
    if count is not None:
        defines[LIGHT_COUNT_DEFINE] = count
    return program(gl_ctx, vertex, fragment, defines)


def _render(sc, gl_ctx, technique, count=None, loop=False):
    """The technique's image; with ``loop`` its light loop drawn from the program without
    SKIN_LIGHT_COUNT, with ``count`` from the program unrolled for ``count`` lights. ssss's final
    pass (its specular's light loop, per count as well: ScreenSpaceSSS.p_finals) is swapped alike."""
    with Renderer(sc, (W, H), ctx=gl_ctx, **KW) as r:
        t = r.technique(technique)
        prog = final = None
        if loop or count is not None:
            prog = _swapped(gl_ctx, t.light_programs(sc, interreflection_on(sc)), sc.lights, count)
            t.override_light_program(prog)
            if technique == "ssss":
                final = t.p_final = _swapped(gl_ctx, t.p_finals, sc.lights, count)
        try:
            return r.render(technique).astype(np.float64)
        finally:
            if prog is not None:
                t.override_light_program(None)
                prog.release()
            if final is not None:
                t.p_final = None
                final.release()


def _close(a, b):
    return np.abs(a - b).max() <= REL * max(np.abs(b).max(), 1e-30)


@pytest.mark.parametrize("technique", TECHNIQUES)
@pytest.mark.parametrize("count", [1, 2, 3, 5])
def test_unrolled_lights_equal_the_loop(gl_ctx, technique, count):
    sc, _ = _scene(count - 1, count)
    img = _render(sc, gl_ctx, technique)
    ref = _render(sc, gl_ctx, technique, loop=True)
    assert ref.max() > 0.05
    assert _close(img, ref), np.abs(img - ref).max()


@pytest.mark.parametrize("technique", TECHNIQUES)
def test_a_light_missing_from_the_unroll_is_seen(gl_ctx, technique):
    """The comparison above can fail, and the swapped-in program is the one drawn: the scene drawn
    with SKIN_LIGHT_COUNT = 2 of 3 lights (the key light, in the last slot, left out) is far from
    the loop's."""
    sc, _ = _scene(2, 3)
    ref = _render(sc, gl_ctx, technique, loop=True)
    img = _render(sc, gl_ctx, technique, count=2)
    assert np.abs(img - ref).max() > 0.1 * ref.max()


@pytest.mark.parametrize("technique", TECHNIQUES)
def test_light_count_change_in_a_live_renderer(gl_ctx, technique):
    """3 lights, then 1, then 5, then 3 again: the live Renderer draws the program for the new count
    (its image equals a fresh Renderer's) and keeps one program per count."""
    sc3, _ = _scene(2, 3)
    sc1 = replace(sc3, lights=[sc3.lights[2]])
    sc5, _ = _scene(4, 5)
    with Renderer(sc3, (W, H), ctx=gl_ctx, **KW) as r:
        a3 = r.render(technique)
        r.set_scene(sc1)
        a1 = r.render(technique)
        r.set_scene(sc5)
        a5 = r.render(technique)
        r.set_scene(sc3)
        b3 = r.render(technique)
        lcp = r.technique(technique).light_programs(sc3, interreflection_on(sc3))
        assert sorted(p.extra["sources"][2][LIGHT_COUNT_DEFINE] for p in lcp.values()) == [1, 3, 5]
        if technique == "ssss":  # its final pass too: one program per count, none compiled per frame
            finals = r.technique(technique).p_finals
            assert sorted(p.extra["sources"][2][LIGHT_COUNT_DEFINE] for p in finals.values()) == [1, 3, 5]
    fresh = {}
    for n, sc in ((1, sc1), (5, sc5)):
        with Renderer(sc, (W, H), ctx=gl_ctx, **KW) as r:
            fresh[n] = r.render(technique)
    assert np.array_equal(a1, fresh[1])
    assert np.array_equal(a5, fresh[5])
    assert np.array_equal(a3, b3)
    assert np.abs(a3.astype(np.float64) - a1).max() > 0.002  # the two decoys light the shadowed side


def test_pore_free_variant_is_unrolled_for_the_same_count(gl_ctx):
    """shading_program's pore-free variant of a per-count program (of the three, only
    preintegrated's evaluates pores; it draws through its own vertex arrays, lambert's and ssss's
    through draw_mesh evaluate none) is compiled from that program's own sources: unrolled for the
    same count, and a different program per count."""
    from dermis.techniques.shared import pores_invisible, shading_program

    sc, _ = _scene(2, 3)
    sc = replace(sc, material=replace(sc.material, pore_strength=0.0))
    with Renderer(sc, (W, H), ctx=gl_ctx, **KW) as r:
        r.render("preintegrated")
        frame = r.last_frame
        assert pores_invisible(frame)
        lcp = r.technique("preintegrated").programs
        lights = {3: sc.lights, 5: _scene(4, 5)[0].lights}
        variants = {n: shading_program(frame, lcp(n, lights[n])) for n in (3, 5)}
        for n, v in variants.items():
            assert v is not lcp(n, lights[n])
            assert v.extra["sources"][2][LIGHT_COUNT_DEFINE] == n
            assert {**lcp(n, lights[n]).extra["sources"][2], "DERMIS_PORES_INVISIBLE": None} == v.extra["sources"][2]


def test_preintegrated_programs_follow_the_profiles_gaussian_count(gl_ctx):
    """preintegrated compiles its blurred normals' loop for the profile's Gaussian count
    (PREINTEGRATED_GAUSSIANS, dermis.techniques.preintegrated): a live Renderer whose profile goes
    from 3 of d'Eon's Gaussians to all 6 and back draws, each time, what the loop over uGaussianCount
    compiled from the same sources draws (a program for fewer Gaussians than the profile's would
    drop the rest)."""
    import dermis
    from dermis.bench import HEAD_TOML
    from dermis.profiles.gaussians import SumOfGaussians, deon_skin
    from dermis.techniques.preintegrated import GAUSSIANS_DEFINE

    sc = dermis.load_scene(str(HEAD_TOML))  # its normal map: the blurred normals differ per Gaussian
    six = deon_skin()
    three = SumOfGaussians(six.variances_mm2[::2], six.weights[::2], "every other of d'Eon's")
    sc.profile = three
    with Renderer(sc, (48, 48), ctx=gl_ctx, samples=0, irradiance_size=128, shadow_size=512) as r:
        t = r.technique("preintegrated")
        live = {}
        for name, profile in (("three", three), ("six", six), ("three again", three)):
            sc.profile = profile
            live[name] = r.render("preintegrated").astype(np.float64)
            vertex, fragment, defines, _ = t.light_programs(sc, interreflection_on(sc))(len(sc.lights), sc.lights).extra["sources"]
            assert defines[GAUSSIANS_DEFINE] == profile.k
            loop = program(gl_ctx, vertex, fragment, {k: v for k, v in defines.items() if k != GAUSSIANS_DEFINE})
            t.override_light_program(loop)
            try:
                reference = r.render("preintegrated").astype(np.float64)
            finally:
                t.override_light_program(None)
                loop.release()
            assert _close(live[name], reference), (name, np.abs(live[name] - reference).max())
    assert np.abs(live["three"] - live["six"]).max() > 0.002 * live["six"].max()  # the count matters (0.7% here)
    np.testing.assert_array_equal(live["three again"], live["three"])


# ---------------------------------------------------------------------- the light passes per light signature
# Round 24 (sig24): the light loops above, the shared bounce's light pass (dermis.gl.interreflection, rho E
# from tsd/irradiance.frag) and tsd's pixel detail (tsd/final.frag PIXEL_DETAIL) are compiled per light
# signature as tsd's irradiance light pass is (shared.light_signature: each light's kind and shadow kernel
# as constants; tests/test_tsd_light_unroll.py, irr24). The reference is the same program with the kinds and
# kernels read from the uniforms at run time (its sources without SKIN_LIGHT_KINDS / SKIN_SHADOW_FILTERS):
# the same arithmetic on each light's path, so the image and rho E must be equal BIT FOR BIT on the scene
# that takes every kind and kernel (a point light's box, a spot's one tap, the key's parabola); a kernel
# compiled wrong (the box as a parabola, the one tap as a box) differs. Fails with light_signature's
# kernels swapped (box <-> parabola) or every kind taken as directional (both checked, round 24).
def _without_signature(gl_ctx, prog, signature=None):
    """``prog`` compiled from its own sources with the kinds and kernels left to run time, or with the
    defines ``signature`` (signature_defines' names) in their place."""
    vertex, fragment, defines, _ = prog.extra["sources"]
    defines = {k: v for k, v in defines.items() if k not in SIGNATURE_DEFINES}
    return program(gl_ctx, vertex, fragment, {**defines, **(signature or {})})


def _targets(r, technique):
    """The technique's image and the shared bounce's rho E (bytes), every pass drawn again."""
    r.invalidate()
    r.interreflection._exitant_key = None  # rho E drawn again (its key holds across invalidate)
    img = r.render(technique)
    rho_e = r.interreflection.exitant(r.last_frame)
    return {"image": img, "rho_e": np.frombuffer(rho_e.read(), np.float32).astype(np.float64)}


def _swap(r, t, technique, prog):
    """Draw ``prog`` as the technique's light loop (tsd: its pixel detail's program); returns the undo."""
    if technique != "tsd":
        t.override_light_program(prog)
        return lambda: t.override_light_program(None)
    key, = [k for k in t._programs if k[0] == "detail"]
    own, t._programs[key] = t._programs[key], prog
    return lambda: t._programs.__setitem__(key, own)


@pytest.mark.parametrize("technique", ("tsd",) + TECHNIQUES)
def test_light_signature_passes_equal_the_runtime_kernels_bit_for_bit(gl_ctx, technique):
    from test_tsd_light_unroll import _signature_scene

    from dermis.techniques.shared import light_signature, signature_defines

    sc = _signature_scene("three")
    sig = light_signature(sc.lights)
    wrong = {**signature_defines(sig), "SKIN_SHADOW_FILTERS": "1, 2, 2"}  # box -> parabola, one tap -> box
    with Renderer(sc, (W, H), ctx=gl_ctx, **KW) as r:
        t = r.technique(technique)
        if technique == "tsd":  # its pixel detail (tsd/final.frag PIXEL_DETAIL), compiled on the first frame
            r.render(technique)
            own_prog, = [p for k, p in t._programs.items() if k[0] == "detail"]
        else:
            own_prog = t.light_programs(sc, interreflection_on(sc))(len(sc.lights), sc.lights)
        assert set(SIGNATURE_DEFINES) <= set(own_prog.extra["sources"][2])
        bounce = r.interreflection.programs
        bounce_prog = bounce(len(sc.lights), sc.lights)
        assert set(SIGNATURE_DEFINES) <= set(bounce_prog.extra["sources"][2])
        own = _targets(r, technique)
        outs = []
        for defines in (None, wrong):
            prog, bprog = _without_signature(gl_ctx, own_prog, defines), _without_signature(gl_ctx, bounce_prog, defines)
            undo = _swap(r, t, technique, prog)
            r.interreflection.programs = lambda n, lights=None, p=bprog: p
            try:
                outs.append(_targets(r, technique))
            finally:
                undo()
                r.interreflection.programs = bounce
                prog.release()
                bprog.release()
    ref, bad = outs
    assert ref["image"].max() > 0.05 and ref["rho_e"].max() > 0.05
    for k in own:
        assert np.array_equal(own[k], ref[k]), (k, np.abs(own[k] - ref[k]).max())
    # the wrong kernels are seen: in rho E by > 0.1 %, in the image at all (ssss's blurs spread the
    # penumbrae's change to < 0.1 %: 0.0005 of 0.55)
    assert np.abs(bad["rho_e"] - ref["rho_e"]).max() > 1e-3 * ref["rho_e"].max()
    assert not np.array_equal(bad["image"], ref["image"])
