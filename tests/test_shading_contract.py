"""The shading contract (dermis.techniques.shared): one definition of every constant Python and
GLSL share, no technique importing another, the specular tables uploaded once per Renderer, and
the samplers of every program within what GL guarantees per stage."""

from __future__ import annotations

import ast
import math
import re
from pathlib import Path

import numpy as np
import pytest

import dermis.specular as specular
from dermis.errors import DermisError
from dermis.gl.shaders import SHADER_DIR, check_samplers, load_shader_source, program, sampler_count
from dermis.techniques import TECHNIQUE_MODULES, shared

TECHNIQUES_DIR = Path(shared.__file__).parent


def _defines(source: str) -> dict:
    """The first #define of each name (a later one sits under #ifndef and is skipped)."""
    out = {}
    for name, value in re.findall(r"^#define (\w+) (\S+)$", source, flags=re.M):
        out.setdefault(name, value)
    return out


def test_generated_constants_are_the_python_constants():
    src = load_shader_source("common/lights.glsl")
    d = _defines(src)
    assert int(d["MAX_LIGHTS"]) == shared.MAX_LIGHTS
    assert int(d["MAX_GAUSSIANS"]) == shared.MAX_GAUSSIANS
    assert float(d["DERMIS_SPECULAR_M_MIN"]) == specular.M_MIN and float(d["DERMIS_SPECULAR_M_MAX"]) == specular.M_MAX
    assert float(d["DERMIS_SKIN_F0"]) == specular.SKIN_F0
    for kind, value in shared.LIGHT_TYPES.items():
        assert int(d[f"LIGHT_{kind.upper()}"]) == value
    for mode in shared.OutputMode:
        assert int(d[f"OUTPUT_{mode.name}"]) == int(mode)
    inv_pi = float(re.search(r"const float INV_PI = (\S+);", src).group(1))
    assert inv_pi == pytest.approx(1.0 / math.pi, rel=1e-15)
    # a program's own #define wins over the generated default (ssss compiles for exactly K)
    src3 = load_shader_source("common/profile.glsl", {"MAX_GAUSSIANS": 3})
    assert _defines(src3)["MAX_GAUSSIANS"] == "3" and "#ifndef MAX_GAUSSIANS" in src3
    # included once per program, however many files include it
    assert load_shader_source("tsd/final.frag").count("const float INV_PI") == 1


def test_no_shader_repeats_a_shared_constant():
    for path in SHADER_DIR.rglob("*"):
        if path.suffix not in (".glsl", ".frag", ".vert"):
            continue
        text = path.read_text()
        rel = path.relative_to(SHADER_DIR)
        assert "must equal" not in text, rel
        assert not re.search(r"0\.3183|3\.14159", text), f"{rel}: write INV_PI (common/constants.glsl)"
        assert not re.search(r"#define (MAX_LIGHTS|MAX_GAUSSIANS|DERMIS_SPECULAR_M_M..|LIGHT_\w+|OUTPUT_\w+) ", text), rel
        assert not re.search(r"uOutputMode\s*==\s*\d", text), f"{rel}: compare with OUTPUT_* names"
        assert "clamp(m, 0.05" not in text, rel


def test_no_technique_imports_another():
    for mod in TECHNIQUE_MODULES:
        tree = ast.parse((TECHNIQUES_DIR / f"{mod}.py").read_text())
        imported = set()
        for node in ast.walk(tree):
            if isinstance(node, ast.ImportFrom) and node.module:
                imported.add(node.module)
            elif isinstance(node, ast.Import):
                imported.update(a.name for a in node.names)
        others = {f"dermis.techniques.{m}" for m in TECHNIQUE_MODULES if m != mod}
        assert not imported & others, (mod, imported & others)


def test_skin_techniques_share_one_directional_albedo():
    """tsd, ssss and preintegrated weight the light by the skin's directional albedo through the one
    common/directional_albedo.glsl (its table, directional_c, directional_factor: no copy) and set
    its switch through the one helper, shared.directional_albedo_uniforms (scene.directional_albedo)."""
    own = "common/directional_albedo.glsl"
    for path in SHADER_DIR.rglob("*"):
        if path.suffix in (".glsl", ".frag", ".vert") and path.relative_to(SHADER_DIR).as_posix() != own:
            text = path.read_text()
            assert not re.search(r"DA_C\[|vec3 directional_factor\(|float directional_c\(", text), path
    for shader in ("tsd/irradiance.frag", "tsd/final.frag", "ssss/irradiance.frag", "preintegrated/skin.frag"):
        src = load_shader_source(shader)
        assert src.count("vec3 directional_factor(vec3 c, float mu)") == 1, shader
        assert re.search(r"uDirectionalAlbedo \* directional_c\(", src), shader
    for mod in ("tsd", "ssss", "preintegrated"):
        text = (TECHNIQUES_DIR / f"{mod}.py").read_text()
        assert "directional_albedo_uniforms(" in text and '"uDirectionalAlbedo"' not in text, mod


def test_set_profile_uniforms_pads_with_unit_variances(gl_ctx):
    from dermis.profiles import deon_skin

    prog = program(gl_ctx, "tsd/uv_space.vert", "tsd/translucency.frag", {"MAX_GAUSSIANS": 8})
    try:
        p = deon_skin()
        shared.set_profile_uniforms(prog, p, 8)
        assert prog["uGaussianCount"].value == p.k
        var = np.frombuffer(prog["uVariances"].read(), np.float32)
        w = np.frombuffer(prog["uWeights"].read(), np.float32).reshape(-1, 3)
        np.testing.assert_allclose(var[: p.k], p.variances_mm2, rtol=1e-6)
        assert np.all(var[p.k:] == 1.0) and np.all(w[p.k:] == 0.0)
        np.testing.assert_allclose(w[: p.k].sum(axis=0), 1.0, rtol=1e-5)  # normalised per channel
        with pytest.raises(DermisError, match="at most 4"):
            shared.set_profile_uniforms(prog, p, 4)
    finally:
        prog.release()


def test_specular_tables_are_uploaded_once_per_renderer(gl_ctx, monkeypatch):
    import dermis.gl.tables as tables
    from dermis.renderer import Renderer
    from dermis.verification import backlit_slab_scene

    calls = []
    real = tables.upload_specular_tables
    monkeypatch.setattr(tables, "upload_specular_tables", lambda ctx: calls.append(1) or real(ctx))
    with Renderer(backlit_slab_scene(2.0, n=4), (16, 16), ctx=gl_ctx, samples=0, irradiance_size=64,
                  shadow_size=128) as r:
        for name in ("tsd", "ssss", "preintegrated"):
            r.render(name)
    assert len(calls) == 1


def test_every_technique_program_fits_the_guaranteed_sampler_units(gl_ctx):
    import moderngl

    from dermis.renderer import Renderer
    from dermis.verification import backlit_slab_scene

    with Renderer(backlit_slab_scene(2.0, n=4), (16, 16), ctx=gl_ctx, samples=0, irradiance_size=64,
                  shadow_size=128) as r:
        progs = [r.shadows.prog]
        for name in TECHNIQUE_MODULES:
            r.render(name)
            t = r.technique(name)
            own = list(vars(t).values()) + [p for ps in getattr(t, "_programs", {}).values() for p in ps]
            for v in own:  # programs, and the ones compiled per light count (LightCountPrograms)
                progs += v.values() if isinstance(v, shared.LightCountPrograms) else [v] if isinstance(v, moderngl.Program) else []
        counts = [sampler_count(p) for p in progs]
    assert len(progs) >= 12 and max(counts) <= shared.GUARANTEED_TEXTURE_UNITS, counts
    assert max(counts) == 16  # tsd's final pass: 8 shared samplers, its translucency and 8 blurs


def test_too_many_samplers_is_refused_at_link(gl_ctx):
    prog = program(gl_ctx, "common/mesh.vert", "tsd/final.frag", {"MAX_GAUSSIANS": 8})
    try:
        n = sampler_count(prog)

        class Tight:  # a context that offers fewer units than the program uses
            info = {"GL_MAX_TEXTURE_IMAGE_UNITS": n - 1}

        with pytest.raises(DermisError, match=rf"uses {n} texture samplers; this GPU allows {n - 1} per stage"):
            check_samplers(Tight(), prog, "tsd/final")
        check_samplers(gl_ctx, prog, "tsd/final")  # llvmpipe: 32
    finally:
        prog.release()
