"""Numeric verification of texture-space diffusion: every check against an independent
closed form or numpy computation. Flat quads with a known number of mm per texel."""

from __future__ import annotations

import numpy as np
import pytest

from dermis.profiles import SumOfGaussians
from dermis.renderer import Renderer
from dermis.specular import rho_dt_table, roughness_axis
from dermis.verification import impulse_reference, impulse_response, quad_scene, rweighted_error


def _impulse(S, shape_mm, gl_ctx, multires=True, profile=None):
    return impulse_response(S, shape_mm, gl_ctx, multires, profile)


@pytest.mark.parametrize("multires", [False, True])
def test_impulse_response_matches_sum_of_gaussians(gl_ctx, multires):
    """An impulse of irradiance in one texel of a flat, unstretched quad: the diffuse result equals
    sum_k w_k G(v_k, r), integrated over each texel's footprint, within 3% (r-weighted L2) out to
    3 sigma of the widest Gaussian, per channel. Measured: ~0.05% full-res, ~0.15% multires."""
    S, texel = 256, 0.1  # 25.6 mm across; 3 sigma of the widest (v = 7.41) is 8.2 mm
    sc, comb, c, levels = _impulse(S, (S * texel, S * texel), gl_ctx, multires)
    if multires:
        assert max(levels) > 0, "the wide Gaussians should run at reduced resolution"
    ref = impulse_reference(sc.profile, (S, S), c, texel, texel)
    yy, xx = np.mgrid[:S, :S]
    r = np.hypot((yy - c[0]) * texel, (xx - c[1]) * texel)
    mask = r <= 3 * np.sqrt(sc.profile.variances_mm2[-1])
    err = rweighted_error(comb, ref, mask)
    assert np.all(err < 0.03), f"r-weighted L2 error per channel {err}"
    # and the profile is not trivially matched: a single Gaussian of the mean variance is far off
    single = impulse_reference(SumOfGaussians([np.mean(sc.profile.variances_mm2)], [[1, 1, 1]]), (S, S), c, texel, texel)
    assert np.all(rweighted_error(single, ref, mask) > 0.3)


@pytest.mark.parametrize("texel", [0.4, 0.49])
def test_impulse_response_with_narrow_gaussians(gl_ctx, texel):
    """At the head's texel size (about 0.49 mm at 1024^2) I_1 and I_2 are sub-texel (sigma 0.16-0.2 and
    0.45-0.55 texels) and come from the one 3x3 pass (tsd/blur_narrow.frag; that it runs there:
    test_narrow_pass_variances_per_texel): the impulse response still matches the closed form within
    3%. Measured: 1.04 / 0.25 / 0.18 % at 0.49 mm (round 3's four 1-D passes: 2.1 / 2.8 / 1.8 %)."""
    from dermis.verification import impulse_error

    err = impulse_error(gl_ctx, S=256, texel_mm=texel)
    assert np.all(err < 0.03), f"r-weighted L2 error per channel {err}"


def test_narrow_pass_variances_per_texel(gl_ctx):
    """I_1 and I_2 from the 3x3 pass on a 0.4 mm quad (sigma 0.2 and 0.55 texels): each is the impulse
    blurred by G(v_k) integrated over the texels: its variance along u and v equals the closed form's
    (binned_gaussian_1d) within 2% and its mass is 1 within 1%; the pass was used."""
    from dermis.verification import binned_gaussian_1d

    S, texel = 64, 0.4
    sc = quad_scene(S * texel, S * texel)
    x = (np.arange(S) - S // 2) * texel
    with Renderer(sc, (32, 32), irradiance_size=S, ctx=gl_ctx, samples=0) as r:
        r.render("tsd")
        tsd = r.technique("tsd")
        irr = np.zeros((S, S, 4), np.float32)
        irr[..., 3] = 1.0
        irr[S // 2, S // 2, :3] = 1.0
        tsd.texture_space(r.last_frame, irradiance=irr)
        assert "narrow_weights" in tsd.tex and tsd.levels[:2] == [0, 0]
        for k in range(2):
            img = tsd.blurred(k)[..., 0]
            assert abs(img.sum() - 1) < 0.01
            ref = binned_gaussian_1d(x, sc.profile.variances_mm2[k], texel)
            var_ref = (ref * x ** 2).sum() / ref.sum()
            for var in ((img.sum(axis=0) * x ** 2).sum() / img.sum(), (img.sum(axis=1) * x ** 2).sum() / img.sum()):
                assert abs(var / var_ref - 1) < 0.02, f"I_{k + 1}: variance {var:.5f} vs {var_ref:.5f} mm^2"


def test_binned_variance_is_the_variance_of_the_binned_gaussian():
    """The narrow pass's per-texel kernel variances (TextureSpaceDiffusion.binned_variance): the variance
    of a Gaussian of sigma texels integrated over unit bins, against the sum over bins -40..40 of
    j^2 m_j (binned_gaussian_1d, closed form) within 1e-9, from sigma 0 (one bin: 0) through the
    switch to Sheppard's sigma^2 + 1/12 at 1 texel to 3 texels, per texel of an array."""
    from dermis.techniques.tsd import TextureSpaceDiffusion
    from dermis.verification import binned_gaussian_1d

    sig = np.linspace(0.0, 3.0, 241).reshape(-1, 1, 1) * np.ones((1, 3, 2))
    got = TextureSpaceDiffusion.binned_variance(sig)
    j = np.arange(-40, 41, dtype=np.float64).reshape(-1, 1, 1, 1)
    ref = (j * j * binned_gaussian_1d(j, np.maximum(sig, 1e-6)[None] ** 2, 1.0)).sum(0)
    assert got.shape == sig.shape and got[0, 0, 0] < 1e-12
    np.testing.assert_allclose(got, ref, rtol=0, atol=1e-9)


def test_impulse_on_stretched_quad_measured_in_mm(gl_ctx):
    """The same impulse on a quad stretched 2x in U (texels are 0.2 mm along u, 0.1 mm along v):
    the profile, measured in mm, still matches within 5%: the stretch map corrects the blur."""
    S = 256
    tu, tv = 0.2, 0.1
    sc, comb, c, _ = _impulse(S, (S * tu, S * tv), gl_ctx)
    ref = impulse_reference(sc.profile, (S, S), c, tu, tv)
    yy, xx = np.mgrid[:S, :S]
    r = np.hypot((yy - c[0]) * tv, (xx - c[1]) * tu)
    mask = r <= 3 * np.sqrt(sc.profile.variances_mm2[-1])
    err = rweighted_error(comb, ref, mask)
    assert np.all(err < 0.05), f"stretched r-weighted error {err}"
    # without stretch correction the profile would be isotropic in TEXELS: clearly wrong in mm
    iso = impulse_reference(sc.profile, (S, S), c, tv, tv)  # u treated as if 0.1 mm per texel
    iso *= ref.sum(axis=(0, 1)) / iso.sum(axis=(0, 1))
    assert np.all(rweighted_error(iso, ref, mask) > 3 * err)


def _bilinear_to_level0(a, S):
    """A level-L texture (h, w, C), row 0 = top, read with bilinear filtering (clamped) at the
    centres of an S x S level-0 grid, as the final and combine passes read it."""
    h, w = a.shape[:2]

    def axis(n_out, n_in):
        x = np.clip((np.arange(n_out) + 0.5) * n_in / n_out - 0.5, 0, n_in - 1)
        i0 = np.floor(x).astype(int)
        i1 = np.minimum(i0 + 1, n_in - 1)
        return i0, i1, (x - i0)

    r0, r1, fr = axis(S, h)
    c0, c1, fc = axis(S, w)
    top = a[r0][:, c0] * (1 - fc)[None, :, None] + a[r0][:, c1] * fc[None, :, None]
    bot = a[r1][:, c0] * (1 - fc)[None, :, None] + a[r1][:, c1] * fc[None, :, None]
    return top * (1 - fr)[:, None, None] + bot * fr[:, None, None]


@pytest.mark.parametrize("multires", [False, True])
def test_each_blurred_level_has_the_profiles_variance(gl_ctx, multires):
    """Every I_k of the chain, read as the final pass reads it (bilinear from its level, at level-0
    texel centres), is the impulse blurred by exactly v_k: its second moment along u and v about
    the impulse equals that of the closed form G(v_k) integrated over each texel
    (binned_gaussian_1d) within 2%, and its mass is 1 within 1%, whatever level it was computed at.
    A reduced level's 2x2 boxes move a single impulse's mass by up to half a texel of that level,
    by how much depends on where the impulse sits in the box: the moments are averaged over the
    impulse's 2^L positions in a level-L texel."""
    from dermis.verification import binned_gaussian_1d

    S, texel = 256, 0.1
    sc = quad_scene(S * texel, S * texel)
    K = sc.profile.k
    x = (np.arange(S) - S // 2) * texel
    moments, masses = np.zeros((K, 2)), []
    with Renderer(sc, (32, 32), irradiance_size=S, ctx=gl_ctx, samples=0) as r:
        r.render("tsd")
        tsd = r.technique("tsd", multires=multires)
        tsd.texture_space(r.last_frame, irradiance=np.ones((S, S, 4), np.float32))
        levels = list(tsd.levels)
        phases = 2 ** max(levels)
        for p in range(phases):
            irr = np.zeros((S, S, 4), np.float32)
            irr[..., 3] = 1.0
            c = S // 2 - phases // 2 + p
            irr[c, c, :3] = 1.0
            tsd.texture_space(r.last_frame, irradiance=irr)
            for k in range(K):
                a = _bilinear_to_level0(tsd.read_texture(tsd.tex[("blur", k)]), S)
                img = a[..., 0] / np.maximum(a[..., 3], 1e-9)
                mass = img.sum()
                masses.append(mass)
                d = x - x[c]
                moments[k] += [(img.sum(axis=0) * d ** 2).sum() / mass, (img.sum(axis=1) * d ** 2).sum() / mass]
    if multires:
        assert max(levels) >= 2, levels
    assert np.all(np.abs(np.array(masses) - 1) < 0.01), masses
    for k, v in enumerate(sc.profile.variances_mm2):
        ref = binned_gaussian_1d(x, v, texel)
        var_ref = (ref * x ** 2).sum() / ref.sum()
        for var in moments[k] / phases:
            assert abs(var / var_ref - 1) < 0.02, f"I_{k + 1} (level {levels[k]}): variance {var:.5f} vs {var_ref:.5f} mm^2"


def test_chained_blurs_equal_direct_blurs(gl_ctx):
    """I_k from the chain (I_(k-1) blurred by v_k - v_(k-1)) equals the raw irradiance blurred once
    by v_k, within 1% (relative L2), for a smooth random irradiance."""
    S, texel = 128, 0.25
    sc = quad_scene(S * texel, S * texel)
    rng = np.random.default_rng(3)
    yy, xx = np.mgrid[:S, :S] * texel
    irr = np.zeros((S, S, 4), np.float32)
    for _ in range(12):  # blobs of 1-4 mm on a floor
        cy, cx, s = rng.uniform(4, S * texel - 4), rng.uniform(4, S * texel - 4), rng.uniform(1, 4)
        irr[..., :3] += rng.uniform(0.2, 1.0, 3) * np.exp(-((yy - cy) ** 2 + (xx - cx) ** 2) / (2 * s * s))[..., None]
    irr[..., :3] += 0.05
    irr[..., 3] = 1.0
    with Renderer(sc, (32, 32), irradiance_size=S, ctx=gl_ctx, samples=0) as r:
        r.render("tsd")
        tsd = r.technique("tsd", multires=False)
        tsd.texture_space(r.last_frame, irradiance=irr)
        chained = {k: tsd.read_texture(tsd.tex[("blur", k)])[..., :3] for k in range(6)}
        inner = (slice(16, S - 16), slice(16, S - 16))  # away from the quad's border
        for k, v in enumerate(sc.profile.variances_mm2):
            direct = tsd.blur_direct(r.last_frame, v)[..., :3]
            a, b = chained[k][inner], direct[inner]
            rel = np.sqrt(((a - b) ** 2).sum() / (b ** 2).sum())
            assert rel < 0.01, f"Gaussian {k + 1} (v={v}): chained vs direct {rel:.4f}"
        # the chain really blurs: the widest differs from the raw input by far more than 1%
        raw = irr[..., :3][inner]
        assert np.sqrt(((chained[5][inner] - raw) ** 2).sum() / (raw ** 2).sum()) > 0.05


def _specular_albedo(cos, m):
    """a(cos, m) from the rho_dt table with bilinear interpolation in the table's own axes."""
    tab = rho_dt_table().astype(np.float64)
    ms = roughness_axis(tab.shape[0])
    x = np.sqrt(cos) * (tab.shape[1] - 1)
    j = np.interp(np.log(m), np.log(ms), np.arange(len(ms)))
    i0, j0 = int(np.floor(x)), int(np.floor(j))
    fx, fj = x - i0, j - j0
    i1, j1 = min(i0 + 1, tab.shape[1] - 1), min(j0 + 1, tab.shape[0] - 1)
    row = lambda jj: tab[jj, i0] * (1 - fx) + tab[jj, i1] * fx
    return row(j0) * (1 - fj) + row(j1) * fj


def test_energy_uniform_irradiance(gl_ctx):
    """Uniform light on a large quad: the diffuse output equals irradiance x albedo / pi x the
    energy left by the specular on the way in (N.L) and out (N.V) x the directional albedo's
    k(N.L) k(N.V) (dermis.profiles.directional_albedo), within 0.5%."""
    from dermis.profiles.directional_albedo import factor
    sc = quad_scene(200.0, 200.0)
    albedo = np.array([0.6, 0.4, 0.3])
    sc.material.albedo_color = tuple(albedo)
    sc.material.rho_s = 0.3
    sc.material.roughness = 0.35
    E = 2.5
    sc.lights[0].intensity = E
    sc.camera.position = (0.0, 0.0, 400.0)
    with Renderer(sc, (64, 64), irradiance_size=128, ctx=gl_ctx, samples=0) as r:
        r.render("tsd")
        img = r.render("tsd", output_mode=1)  # diffuse only
    px = img[24:40, 24:40].reshape(-1, 3)
    # per pixel N.V differs slightly: use the centre pixel's view ray direction ~ along the normal
    a_in = _specular_albedo(1.0, 0.35)
    a_out = _specular_albedo(np.cos(np.radians(1.0)), 0.35)
    expected = (E * albedo / np.pi * (1 - 0.3 * a_in / np.pi) * (1 - 0.3 * a_out / np.pi)
                * factor(albedo, 1.0) * factor(albedo, np.cos(np.radians(1.0))))
    rel = np.abs(px.mean(axis=0) / expected - 1)
    assert np.all(rel < 0.005), f"energy: {px.mean(axis=0)} vs {expected} ({rel})"
    # the factors matter: without them the value would be off by more than the tolerance
    assert np.all(np.abs(E * albedo / np.pi / expected - 1) > 0.005)


def test_binned_variance_is_the_variance_of_the_binned_gaussian():
    """tsd's narrow-pass variances (TextureSpaceDiffusion.binned_variance) against the variance of
    the Gaussian's texel masses summed over 200 texels each side (independent: no Sheppard term)."""
    from dermis.techniques.tsd import TextureSpaceDiffusion
    from dermis.verification import binned_gaussian_1d

    sig = np.array([0.05, 0.2, 0.45, 0.7, 0.99, 1.0, 1.5, 3.0])
    j = np.arange(-200, 201, dtype=np.float64)
    ref = np.array([(j * j * binned_gaussian_1d(j, s * s, 1.0)).sum() for s in sig])
    np.testing.assert_allclose(TextureSpaceDiffusion.binned_variance(sig), ref, rtol=0, atol=2e-6)


def test_chain_reads_texels_through_its_sampler_exactly(gl_ctx):
    """tsd's chain (tsd/blur.frag, blur_narrow.frag, the 2x2 reductions) reads texels with textureLod at
    texel centres through the technique's NEAREST, CLAMP_TO_EDGE sampler object, not texelFetch of a
    clamped texel (cheaper on llvmpipe; round 23, chain23): a read at p + offset is that texel with the
    border clamped, bit for bit (numpy's clip of the uploaded array), on an odd, non-power-of-two size,
    offsets past every border, float16 and float32. And TextureSpaceDiffusion._draw unbinds the sampler
    after its passes: a later pass on the same unit reads the texture's own bilinear filter again (the
    final pass reads I_k so), in the same list and after it. Fails with a REPEAT sampler or without the
    unbinding (checked)."""
    import moderngl

    from dermis.gl.shaders import load_shader_source

    rng = np.random.default_rng(23)
    W, H = 37, 23
    with Renderer(quad_scene(10.0, 10.0), (16, 16), irradiance_size=64, ctx=gl_ctx, samples=0) as r:
        tsd = r.technique("tsd")
        vert = load_shader_source("common/fullscreen.vert", {})
        head = "#version 450 core\nuniform sampler2D uSource;\nuniform ivec2 uOffset;\nout vec4 f_color;\n"
        sampled = gl_ctx.program(vertex_shader=vert, fragment_shader=head + (
            "void main() { vec2 inv_size = 1.0 / vec2(textureSize(uSource, 0));\n"
            "  f_color = textureLod(uSource, (vec2(ivec2(gl_FragCoord.xy) + uOffset) + 0.5) * inv_size, 0.0); }"))
        # half a texel past the centre along u: a bilinear read is the mean of two texels, a nearest one is one
        linear = gl_ctx.program(vertex_shader=vert, fragment_shader=head + (
            "void main() { f_color = texture(uSource, (gl_FragCoord.xy + vec2(0.5, 0.0)) / vec2(textureSize(uSource, 0))); }"))
        made = [sampled, linear]
        try:
            for p in (sampled, linear):
                tsd.vaos[p] = gl_ctx.vertex_array(p, [])
            out = gl_ctx.texture((W, H), 4, dtype="f4")
            made.append(out)
            for dtype, np_dtype in (("f2", np.float16), ("f4", np.float32)):
                src = rng.standard_normal((H, W, 4)).astype(np_dtype)
                tex = gl_ctx.texture((W, H), 4, src.tobytes(), dtype=dtype)
                made.append(tex)
                tex.filter = (moderngl.LINEAR, moderngl.LINEAR)
                tex.repeat_x = tex.repeat_y = False
                for off in ((0, 0), (-5, 3), (4, -7), (W + 2, H + 1), (-W - 3, -H)):
                    type(tsd)._draw([tsd._pass(sampled, out, {"uOffset": off}, {"uSource": (tex, 0)}, nearest=True)])
                    got = np.frombuffer(out.read(), np.float32).reshape(H, W, 4)
                    yy, xx = np.mgrid[:H, :W]
                    ref = src[np.clip(yy + off[1], 0, H - 1), np.clip(xx + off[0], 0, W - 1)].astype(np.float32)
                    assert np.array_equal(got.view(np.uint32), ref.view(np.uint32)), (dtype, off)
                ref = src.astype(np.float32)
                mean = 0.5 * (ref + ref[:, np.minimum(np.arange(W) + 1, W - 1)])
                lin = tsd._pass(linear, out, {}, {"uSource": (tex, 0)})
                near = tsd._pass(sampled, out, {"uOffset": (0, 0)}, {"uSource": (tex, 0)}, nearest=True)
                for passes in ([near, lin], [lin]):  # after the nearest pass in the list, then in a later list
                    type(tsd)._draw(passes)
                    got = np.frombuffer(out.read(), np.float32).reshape(H, W, 4)
                    np.testing.assert_allclose(got, mean, rtol=0, atol=2e-3 * np.abs(ref).max())
        finally:
            for p in (sampled, linear):
                v = tsd.vaos.pop(p, None)
                if v is not None:
                    v.release()
            for o in made:
                o.release()


def test_texel_reads_equal_clamped_texel_fetch(gl_ctx):
    """common/texel.glsl's TEXEL (textureLod at texel centres, round 23 fetch23) reads exactly the texel
    texelFetch of the clamped texel read, bit for bit (numpy's clip of the uploaded array), offsets past
    every border, wherever the passes now read so: (a) through dermis.gl.resources.nearest_sampler on a
    LINEAR texture (tsd's chain and dilation); (b) ssss's own targets, NEAREST and CLAMP_TO_EDGE without a
    sampler object (its blurs, grain filter, final pass); (c) LevelChain.reduce (the bounce's 2x2
    reductions), against numpy's 2x2 mean. The data holds +-inf: a bilinear read at a centre weights the
    neighbour by 0 but 0 * inf is NaN, so a missing sampler (the texture's LINEAR filter) fails, as a
    REPEAT one fails at the borders (both checked)."""
    import moderngl

    from dermis.gl.interreflection import SOURCE_FINER_LEVELS, LevelChain
    from dermis.gl.resources import nearest_sampler
    from dermis.gl.shaders import load_shader_source

    rng = np.random.default_rng(14)
    W, H = 37, 23
    src = rng.standard_normal((H, W, 4)).astype(np.float32)
    src[3, 5, 0] = np.inf  # beside interior texels and on the borders: a bilinear read there is NaN
    src[0, 9, 1] = -np.inf
    src[H - 1, W - 1, 2] = np.inf
    src[11, 0, 3] = np.inf
    frag = load_shader_source("common/texel.glsl").replace("#version 450 core\n", "") + (
        "uniform sampler2D uSource;\nuniform ivec2 uOffset;\nout vec4 f_color;\n"
        "void main() { f_color = TEXEL(uSource, ivec2(gl_FragCoord.xy) + uOffset); }\n")
    prog = gl_ctx.program(vertex_shader=load_shader_source("common/fullscreen.vert"),
                          fragment_shader="#version 450 core\n" + frag)
    vao = gl_ctx.vertex_array(prog, [])
    out = gl_ctx.texture((W, H), 4, dtype="f4")
    fbo = gl_ctx.framebuffer(color_attachments=[out])
    linear = gl_ctx.texture((W, H), 4, src.tobytes(), dtype="f4")
    linear.filter = (moderngl.LINEAR, moderngl.LINEAR)
    linear.repeat_x = linear.repeat_y = False
    sampler = nearest_sampler(gl_ctx)
    made = [prog, vao, out, fbo, linear, sampler]
    yy, xx = np.mgrid[:H, :W]

    def check(tex, what):
        tex.use(0)
        prog["uSource"] = 0
        for off in ((0, 0), (-5, 3), (4, -7), (W + 2, H + 1), (-W - 3, -H)):
            prog["uOffset"] = off
            fbo.use()
            fbo.viewport = (0, 0, W, H)
            vao.render(moderngl.TRIANGLES, vertices=3)
            got = np.frombuffer(out.read(), np.float32).reshape(H, W, 4)
            ref = src[np.clip(yy + off[1], 0, H - 1), np.clip(xx + off[0], 0, W - 1)]
            assert np.array_equal(got.view(np.uint32), ref.view(np.uint32)), (what, off)

    try:
        sampler.use(0)
        check(linear, "nearest_sampler")
        sampler.clear(0)
        with Renderer(quad_scene(10.0, 10.0), (16, 16), irradiance_size=64, ctx=gl_ctx, samples=0) as r:
            ssss = r.technique("ssss")
            ssss._ensure_targets((W, H), 1, False)
            scattered = ssss.tex["scattered"]  # float32 like irradiance; view_normal float16 (same state)
            scattered.write(src.tobytes())
            check(scattered, "ssss target")
        # LevelChain: a 16^2 raster reduced to the gather's level (SOURCE_FINER_LEVELS coarser), every
        # reduced texel the exact mean of its block
        chain = LevelChain(gl_ctx)
        made.append(chain)
        levels = chain.levels(16, SOURCE_FINER_LEVELS)
        assert len(levels) == SOURCE_FINER_LEVELS + 1 >= 2
        top = src[:16, :16]
        levels[0][0].write(top.tobytes())
        n = 16 >> SOURCE_FINER_LEVELS
        got = np.frombuffer(chain.reduce(levels).read(), np.float32).reshape(n, n, 4)
        ref = top
        for _ in range(len(levels) - 1):
            ref = 0.25 * (ref[0::2, 0::2] + ref[0::2, 1::2] + ref[1::2, 0::2] + ref[1::2, 1::2])
        np.testing.assert_array_equal(got, ref)  # the same four terms in the same order: exact
    finally:
        for o in reversed(made):
            o.release()
