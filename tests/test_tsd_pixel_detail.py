"""tsd's pixel detail (tsd/final.frag with PIXEL_DETAIL, tsd/gaussians.glsl: diffuse_irradiance_detail):
where the irradiance texture's texels are wider than the narrow Gaussians, the narrow terms take
the part of I_0 the texels cannot hold from I_0 evaluated at each pixel (issue 12: the side view's
scapha drew as a comb of red stripes at the adaptive irradiance size).

The surface: a plane corrugated by folds of wavelength 2.4 texels of the coarse irradiance texture
(4 pixels per texel), oblique to the texel grid, lit from the side so that N.L turns from 0.97 to
below 0 across each fold. Reference: the same technique with the texture 8x finer (texels of half
a pixel: nothing left for the detail to add), and in closed form max(N.L, 0) per pixel of the
analytic surface where the profile is far narrower than a pixel."""

from __future__ import annotations

import functools
import math

import numpy as np
import pytest

from dermis.profiles.gaussians import SumOfGaussians, deon_skin
from dermis.renderer import Renderer
from dermis.scene.builtin import grid_mesh
from dermis.scene.loaders import finish_mesh
from dermis.scene.model import Camera, Environment, Light, Scene, SkinMaterial
from dermis.techniques.shared import OutputMode, SIGNATURE_DEFINES


SIZE_MM = 16.0  # the plane's side; mm_per_unit = 1
COARSE, FINE, PIXELS = 64, 512, 256  # irradiance texels across; the frame (16 px per mm)
WAVELENGTH_MM = 0.6  # 2.4 coarse texels (0.25 mm), 9.6 pixels
AMPLITUDE_MM = 0.08  # slope 2 pi A / lambda = 0.84: normals swing +-40 degrees
FOLD_ANGLE_DEG = 30.0  # the folds' direction against the u axis
LIGHT_DEG = 60.0  # from the plane's normal, across the folds
CAMERA_Z = 400.0  # far away: rays within 1.2 degrees of -z


def _fold_direction():
    a = math.radians(FOLD_ANGLE_DEG)
    return np.array([math.cos(a), math.sin(a)])


def corrugated_scene(profile, amplitude_mm: float = AMPLITUDE_MM, n: int = 320) -> Scene:
    """The corrugated plane z = A sin(2 pi s / lambda), s = (x, y) . d (d at FOLD_ANGLE_DEG to the u axis),
    UVs its (x, y) over [0, 1]^2, white, no specular, a directional light of irradiance pi at
    LIGHT_DEG from the normal in the plane of d and z; no ambient, no bounce."""
    d = _fold_direction()
    b = math.radians(LIGHT_DEG)
    light = (-math.sin(b) * d[0], -math.sin(b) * d[1], -math.cos(b))  # travelling along +d, down
    return Scene(mesh=_corrugated_mesh(amplitude_mm, n), profile=profile,
                 material=SkinMaterial(albedo_color=(1.0, 1.0, 1.0), rho_s=0.0, pore_strength=0.0),
                 lights=[Light(direction=light, intensity=np.pi, cast_shadows=False)],
                 camera=Camera(position=(0.0, 0.0, CAMERA_Z), target=(0.0, 0.0, 0.0), up=(0.0, 1.0, 0.0),
                               fov_deg=math.degrees(2 * math.atan(0.5 * SIZE_MM / CAMERA_Z))),
                 environment=Environment(color=(0.0, 0.0, 0.0)), mm_per_unit=1.0, name="corrugated",
                 interreflection=False, directional_albedo=False)


@functools.lru_cache(maxsize=2)
def _corrugated_mesh(amplitude_mm: float, n: int):
    """corrugated_scene's mesh, built once per shape for the module (103 k vertices and their tangents:
    ~1 s each; the scenes only read it)."""
    d = _fold_direction()
    k = 2 * math.pi / WAVELENGTH_MM

    def fn(u, v):
        x, y = (u - 0.5) * SIZE_MM, (v - 0.5) * SIZE_MM
        s = x * d[0] + y * d[1]
        z = amplitude_mm * np.sin(k * s)
        g = amplitude_mm * k * np.cos(k * s)  # dz/ds
        n = np.stack([-g * d[0], -g * d[1], np.ones_like(g)], -1)
        return np.stack([x, y, z], -1), n / np.linalg.norm(n, axis=-1, keepdims=True)

    p, nn, uv, t = grid_mesh(n, n, fn)  # n = 320: 0.05 mm, 12 vertices per wavelength
    return finish_mesh(p, nn, uv, t, "test:corrugated", "v-up")


def _render(scene, irradiance_size, gl_ctx, **options):
    return _renders(scene, irradiance_size, gl_ctx, options)[0]


def _renders(scene, irradiance_size, gl_ctx, *option_sets):
    """tsd's image per set of options, from one Renderer (the texture-space passes, which the pixel
    detail does not change, are drawn once; the same bits as a Renderer per image)."""
    with Renderer(scene, (PIXELS, PIXELS), ctx=gl_ctx, samples=0, irradiance_size=irradiance_size,
                  shadow_size=512) as r:
        out = []
        for options in option_sets:
            r.technique("tsd", **options)
            out.append(r.render("tsd").astype(np.float64).mean(axis=-1))
        return out


def _closed_form():
    """max(N.L, 0) at each pixel centre of the analytic surface (rays along -z: the camera is 400 mm
    away, the surface 0.08 mm from z = 0), row 0 = top (+y)."""
    c = (np.arange(PIXELS) + 0.5) / PIXELS * SIZE_MM - 0.5 * SIZE_MM
    x, y = np.meshgrid(c, -c)
    d = _fold_direction()
    k = 2 * math.pi / WAVELENGTH_MM
    g = AMPLITUDE_MM * k * np.cos(k * (x * d[0] + y * d[1]))
    n = np.stack([-g * d[0], -g * d[1], np.ones_like(g)], -1)
    n /= np.linalg.norm(n, axis=-1, keepdims=True)
    b = math.radians(LIGHT_DEG)
    to_light = np.array([math.sin(b) * d[0], math.sin(b) * d[1], math.cos(b)])
    return np.maximum(n @ to_light, 0.0)


INNER = (slice(8, -8), slice(8, -8))  # away from the plane's border


def _rms(a, b):
    return float(np.sqrt(np.mean((a[INNER] - b[INNER]) ** 2)) / np.mean(b[INNER]))


@pytest.fixture(scope="module")
def narrow_renders(gl_ctx):
    """A profile of one Gaussian far narrower than a pixel (sigma 0.01 mm; a pixel is 0.0625 mm):
    the diffuse radiance is the irradiance at the pixel over pi, here max(N.L, 0)."""
    scene = corrugated_scene(SumOfGaussians(np.array([1e-4]), np.ones((1, 3)), "narrow"))
    return (*_renders(scene, COARSE, gl_ctx, {}, {"pixel_detail": False}), _render(scene, FINE, gl_ctx, pixel_detail=False))


def test_narrow_profile_matches_the_closed_form_at_a_coarse_texture(narrow_renders):
    detail, plain, fine = narrow_renders
    exact = _closed_form()
    # the technique meets the closed form where its texels are half a pixel (0.044: the bilinear
    # reads of the texture; the mesh's normals, linear between vertices 0.05 mm apart, leave ~0.03,
    # the rms of a 2048^2 texture)
    assert _rms(fine, exact) < 0.05, _rms(fine, exact)
    # at 4 pixels per texel the plain texture point-samples folds of 2.4 texels: stripes (0.43)
    assert _rms(plain, exact) > 0.3, _rms(plain, exact)
    # the detail restores the per-pixel irradiance (0.028)
    assert _rms(detail, exact) < 0.035, _rms(detail, exact)


def test_skin_profile_at_a_coarse_texture_approaches_the_fine_one(gl_ctx):
    """d'Eon's six Gaussians: the narrow ones (sigma 0.08-0.43 mm against texels of 0.25 mm) carry
    the folds; the fine texture (texels of 0.03 mm) resolves every Gaussian (2048^2 differs from it
    by 0.007). The plain coarse texture is 0.14 off, the detail 0.043: the Gaussians as wide as a
    texel take a share a_k of the residual at the texture's Nyquist frequency (tsd/gaussians.glsl),
    an approximation (a_k at twice or half that frequency: 0.045 and 0.080)."""
    scene = corrugated_scene(deon_skin())
    detail, plain = _renders(scene, COARSE, gl_ctx, {}, {"pixel_detail": False})
    fine = _render(scene, FINE, gl_ctx, pixel_detail=False)
    assert _rms(plain, fine) > 0.1, _rms(plain, fine)
    assert _rms(detail, fine) < 0.05, _rms(detail, fine)


def test_pixel_detail_leaves_a_resolved_irradiance_alone(gl_ctx):
    """A flat plane under a light at 60 degrees: I_0 is constant, the texture holds it exactly, so the
    detail adds nothing (within the 16-bit irradiance texture's rounding)."""
    scene = corrugated_scene(deon_skin(), amplitude_mm=0.0)
    detail, plain = _renders(scene, COARSE, gl_ctx, {}, {"pixel_detail": False})
    assert np.max(np.abs(detail - plain)[INNER]) < 2e-3 * np.mean(plain[INNER])
    assert abs(np.mean(plain[INNER]) - math.cos(math.radians(LIGHT_DEG))) < 0.01


def test_pixel_detail_must_be_a_bool(gl_ctx):
    from dermis.errors import DermisError

    with Renderer(corrugated_scene(deon_skin()), (16, 16), ctx=gl_ctx, samples=0, irradiance_size=64) as r:
        with pytest.raises(DermisError, match="pixel_detail"):
            r.technique("tsd", pixel_detail=1)


def test_pixel_detail_keeps_the_bounce(gl_ctx):
    """I_1 holds the bounce the splat added (tsd/bounce_splat.frag), so I_0 at the pixel must hold the
    same bounce (the per-vertex T from a storage buffer, interpolated in the layout as the splat does).
    In the preintegrated tests' V-groove, whose walls light each other (the bounce is 32-42 % of the
    groove's light), at texels of 0.38 mm (a_1 = 0.8): the bounce's share of the image (with minus
    without) is the same with the detail as without it, per channel within 2 % (0.99-1.00); with
    the bounce left out of I_0 it is 0.27-0.74 of it."""
    import dataclasses

    from test_preintegrated_folds import groove_scene

    size = 64
    groove = (slice(size // 2 - 6, size // 2 + 6), slice(8, -8))  # the rows of the groove
    means = {}
    for bounce in (True, False):
        scene = dataclasses.replace(groove_scene(), interreflection=bounce)
        images = {}
        with Renderer(scene, (size, size), ctx=gl_ctx, samples=0, irradiance_size=64, shadow_size=1024) as r:
            for detail in (True, False):  # one Renderer: the same bits as one per image
                r.technique("tsd", pixel_detail=detail)
                images[detail] = r.render("tsd").astype(np.float64)[groove]
                means[bounce, detail] = images[detail].reshape(-1, 3).mean(axis=0)
        # the option took effect on the live Renderer: the detail changes the groove's pixels (by up to 0.29)
        assert np.abs(images[True] - images[False]).max() > 0.05
    with_detail = means[True, True] - means[False, True]
    without = means[True, False] - means[False, False]
    assert np.all(without > 0.3 * means[True, False]), (without, means[True, False])
    np.testing.assert_allclose(with_detail / without, 1.0, atol=0.02)


@pytest.mark.parametrize("k, lights", [(6, 1), (7, 3), (8, 3), (6, 4)])
def test_pixel_detail_programs_fit_the_guaranteed_samplers(gl_ctx, k, lights):
    """The PIXEL_DETAIL variants (tsd._final_program): the stored sharp shadows and the atlas with a
    blur array of the profile's K <= 7, else the per-sample shadows with MAX_GAUSSIANS blurs; the
    bounce from storage buffers, not a sampler. Each within GL 4.5's 16 samplers per stage, each
    drawing a finite image that differs from the plain one only by the detail."""
    import dataclasses

    from dermis.gl.shaders import program, sampler_count
    from dermis.techniques import shared

    v = 0.0064 * 3.0 ** np.arange(k)  # d'Eon-like spacing, 0.0064 mm^2 on
    profile = SumOfGaussians(v, np.full((k, 3), 1.0 / k), f"k{k}")
    base = corrugated_scene(profile, n=48)
    light = base.lights[0]
    scene = dataclasses.replace(base, interreflection=True,
                                lights=[dataclasses.replace(light, intensity=np.pi / lights)] * lights)
    with Renderer(scene, (32, 32), ctx=gl_ctx, samples=0, irradiance_size=64, shadow_size=256) as r:
        img = r.render("tsd")
        t = r.technique("tsd")
        detail = [(key, p) for key, p in t._programs.items() if key[0] == "detail"]
        assert len(detail) == 1
        (key, prog), = detail
        assert key[1] == (k <= 7 and lights <= 3) and key[2] is True
        assert sampler_count(prog) <= shared.GUARANTEED_TEXTURE_UNITS, sampler_count(prog)
        # round 23: the lights unrolled for the scene's count (common/lights.glsl DERMIS_FOR_EACH_LIGHT); the same
        # image as the loop over uLightCount (checked: fails with the count one short; one case: a compile costs ~1 s)
        vertex, fragment, defines, _ = prog.extra["sources"]
        assert key[4] == lights and defines[shared.LIGHT_COUNT_DEFINE] == lights
        if (k, lights) == (7, 3):
            # (round 24, sig24: without the light signature too, which needs the count; the same floats)
            looped = program(gl_ctx, vertex, fragment, {d: v for d, v in defines.items()
                                                        if d not in (shared.LIGHT_COUNT_DEFINE, *SIGNATURE_DEFINES)})
            t._programs[key] = looped
            try:
                np.testing.assert_array_equal(r.render("tsd"), img)
            finally:
                t._programs[key] = prog
                looped.release()
        r.technique("tsd", pixel_detail=False)
        plain = r.render("tsd")
    assert np.all(np.isfinite(img)) and img.max() > 0
    assert abs(float(img.mean()) - float(plain.mean())) < 0.1 * float(plain.mean())


def test_pixel_detail_draws_the_pcf_penumbra_where_the_stored_sharp_shadow_is_0_or_1(gl_ctx):
    """I_0 at the pixel takes the lights' soft (PCF) shadows there, as the irradiance pass takes them
    per texel. Round 21 (dots21) found the final pass taking them only inside the stored sharp
    shadow's bilinear band (a texel each side of its edge) and the stored 0 or 1 elsewhere: where
    the PCF's penumbra is wider than that band, the full detail then drew the band's end as a step
    (front-key's nose shadow: single dark pixels, green 51 levels where irradiance 4096 has 106).
    test_shadow_edge_rim's straight edge, shadow map 256^2 (penumbra ~2 mm), irradiance 512^2
    (texels 0.28 mm, ~2.8 pixels: the detail full) against a texture that resolves the penumbra
    (1024^2, 0.14 mm texels, no detail): max |error| / lit 0.004 (the band: 0.090, checked; both
    against 4096^2 at 512^2: 0.003 and 0.089)."""
    from test_shadow_edge_rim import H, W, _edge_scene

    sc, _ = _edge_scene()
    imgs = []
    for size, detail in ((512, True), (1024, False)):
        with Renderer(sc, (W, H), ctx=gl_ctx, samples=0, irradiance_size=size, shadow_size=256) as r:
            r.technique("tsd", pixel_detail=detail)
            imgs.append(r.render("tsd", output_mode=OutputMode.DIFFUSE).astype(np.float64))
    coarse, ref = imgs
    lit = ref[H // 2, -5:, 1].mean()
    assert lit > 0.0 and ref[H // 2, :5, 1].mean() < 0.01 * lit  # the window spans the penumbra
    err = np.abs(coarse - ref).max(axis=-1) / lit
    assert err.max() < 0.01, (err.max(), np.unravel_index(err.argmax(), err.shape))


# A plane whose layout's texel density varies smoothly along x: x = STRETCH_MM (u + a u^2), y =
# ACROSS_MM (v - 1/2), so the surface's mm per uv unit along u is X'(u) = STRETCH_MM (1 + 2 a u), 8-16
# mm, and along v ACROSS_MM = 6 mm (finer): the coarsest direction's texels per mm is N / X'(u) (u, v
# orthogonal on the plane). Eight columns of quads: a triangle's own density (its secant slope) steps
# by 1/8 / (1 + u) = 6-12 % between columns, as between the head's concha triangles (10-15 %).
STRETCH_MM, STRETCH_A, ACROSS_MM, STRETCH_COLUMNS = 8.0, 0.5, 6.0, 8


def _stretched_plane_scene():
    def fn(u, v):
        x = STRETCH_MM * (u + STRETCH_A * u * u) - 0.75 * STRETCH_MM  # centred: x in [-6, 6] mm
        p = np.stack([x, ACROSS_MM * (v - 0.5), np.zeros_like(u)], -1)
        return p, np.broadcast_to(np.array([0.0, 0.0, 1.0]), p.shape)

    p, nn, uv, t = grid_mesh(STRETCH_COLUMNS, 4, fn)
    mesh = finish_mesh(p, nn, uv, t, "test:stretched-plane", "v-up")
    width = 1.5 * STRETCH_MM
    return Scene(mesh=mesh, profile=deon_skin(),
                 material=SkinMaterial(albedo_color=(1.0, 1.0, 1.0), rho_s=0.0, pore_strength=0.0),
                 lights=[Light(direction=(0.0, 0.0, -1.0), intensity=np.pi, cast_shadows=False)],
                 camera=Camera(position=(0.0, 0.0, CAMERA_Z), target=(0.0, 0.0, 0.0), up=(0.0, 1.0, 0.0),
                               fov_deg=math.degrees(2 * math.atan(0.5 * width / CAMERA_Z))),
                 environment=Environment(color=(0.0, 0.0, 0.0)), mm_per_unit=1.0, name="stretched-plane",
                 interreflection=False, directional_albedo=False)


def test_pixel_detail_texel_density_is_continuous_across_triangle_edges(gl_ctx, monkeypatch):
    """The detail's a_k = exp(-pi^2 v_k texels_per_mm^2 / 2) take I_1's texels per mm along the layout's
    coarsest direction. Round 21 (dots21) found it per triangle (screen derivatives): where R = I_0 - I_1
    is large, a 10-15 % step of it across a triangle edge drew a one-pixel dark dip (front-key's concha,
    13 levels beside 17-19). Now the corners' averaged metric, interpolated: on a plane of known,
    smoothly varying density (N / X'(u), numpy from the pixel's own layout uv) the final pass's value is
    within 1 % where the corners are interior vertices (0.6 %; per triangle, main 8521753: 5.3 %, fails,
    checked) and its ratio to the analytic one changes by < 2 % between neighbouring pixels (0.7 %; per
    triangle: 10.2 % at a column edge, fails, checked). The final pass is patched, as text, to write
    (texels_per_mm, uv_ts) in place of its colour."""
    import dermis.gl.shaders as shaders

    load = shaders.load_shader_source

    def patched(name, defines=None):
        src = load(name, defines)
        if name == "tsd/final.frag" and defines and "PIXEL_DETAIL" in defines:
            assert "f_color = vec4(color, 1.0);" in src
            src = src.replace("f_color = vec4(color, 1.0);", "f_color = vec4(texels_per_mm, uv_ts, 1.0);")
        return src

    monkeypatch.setattr(shaders, "load_shader_source", patched)
    size, n = 128, 64  # the frame (~10.7 px per mm); I_1 at 64^2: the detail program is drawn at any size
    with Renderer(_stretched_plane_scene(), (size, size), ctx=gl_ctx, samples=0, irradiance_size=n,
                  shadow_size=256) as r:
        t = r.technique("tsd")
        out = r.render("tsd").astype(np.float64)
        texels = float(r.irradiance_size >> t.levels[0])
    assert any(key[0] == "detail" for key in t._programs)
    density, u, v = out[..., 0], out[..., 1], out[..., 2]
    covered = density > 0.1  # the background holds the clear colour (0.02)
    expected = texels / (STRETCH_MM * (1.0 + 2.0 * STRETCH_A * u))
    ratio = np.log(np.where(covered, density / expected, 1.0))
    # the value, where every corner is an interior vertex (the border's vertices average the triangles
    # of one side only: an O(h) bias there, 6 % at u = 0, as a triangle's own); the plane spans rows ~32-96
    inner = covered & (u > 1.0 / STRETCH_COLUMNS) & (u < 1.0 - 1.0 / STRETCH_COLUMNS) & (v > 0.25) & (v < 0.75)
    assert inner.sum() > 2000 and np.abs(ratio[inner]).max() < 0.01, np.abs(ratio[inner]).max()
    # no step between neighbouring covered pixels: the ratio to the analytic density changes smoothly
    # (<= 0.7 % per pixel across the border's columns), where a triangle's own steps by 6-12 %
    for axis in (0, 1):
        both = np.diff(covered.astype(int), axis=axis) == 0
        step = np.abs(np.diff(ratio, axis=axis))[both & np.delete(covered, 0, axis=axis)]
        assert step.max() < 0.02, (axis, step.max())
