"""GLSL 450 sources kept in ``dermis/shaders`` with a small ``#include "path"`` mechanism.

Paths in #include are relative to the shaders folder (``#include "common/brdf.glsl"``); each file
is included once per program (include guards are implicit). ``#version`` is added here so that
includes never carry one. Compile errors name the file.

``common/constants.glsl`` is not a file: it is generated from dermis.techniques.shared (limits,
INV_PI, the roughness range, light types, output modes) each time a shader includes it, so the
numbers Python and GLSL share are written once. At link, a program's active samplers are counted
against the context's GL_MAX_TEXTURE_IMAGE_UNITS.
"""

from __future__ import annotations

import re
from pathlib import Path

SHADER_DIR = Path(__file__).resolve().parent.parent / "shaders"
_INCLUDE = re.compile(r'^\s*#include\s+"([^"]+)"\s*$')


def _generated_includes() -> dict:
    from dermis.techniques.shared import glsl_constants

    return {"common/constants.glsl": glsl_constants}


# GL_SAMPLER_1D .. GL_SAMPLER_2D_SHADOW, rect, array/cube-shadow/integer, cube-map array, multisample
_SAMPLER_TYPES = set(range(0x8B5D, 0x8B65)) | set(range(0x8DC0, 0x8DD9)) | set(range(0x900C, 0x9010)) \
    | set(range(0x9108, 0x910E))


def sampler_count(prog) -> int:
    """Active sampler uniforms of a linked program, arrays counted per element."""
    import moderngl

    n = 0
    for name in prog:
        m = prog[name]
        if isinstance(m, moderngl.Uniform) and m.gl_type in _SAMPLER_TYPES:
            n += max(int(m.array_length), 1)
    return n


def check_samplers(ctx, prog, what: str) -> None:
    """Refuse a program that uses more samplers than a stage may (GL_MAX_TEXTURE_IMAGE_UNITS):
    the driver would link it and sample garbage or fail at draw time. Every sampler is counted,
    an upper bound on any one stage's (dermis's vertex shaders sample nothing)."""
    from dermis.errors import DermisError

    limit = int(ctx.info.get("GL_MAX_TEXTURE_IMAGE_UNITS") or 16)
    n = sampler_count(prog)
    if n > limit:
        raise DermisError(f"shader program {what} uses {n} texture samplers; this GPU allows {limit} per stage")


def load_shader_source(name: str, defines: dict | None = None) -> str:
    """Expand a shader file's includes; prepend #version 450 core and the given #defines."""
    seen: set[Path] = set()
    generated = _generated_includes()

    def expand(path: Path) -> list[str]:
        path = path.resolve()
        if path in seen:
            return []
        seen.add(path)
        if not path.is_file():
            raise FileNotFoundError(f"shader {path} not found")
        out = []
        for line in path.read_text().splitlines():
            m = _INCLUDE.match(line)
            if m and m.group(1) in generated:
                key = SHADER_DIR / m.group(1)
                if key not in seen:
                    seen.add(key)
                    out.extend(generated[m.group(1)]().splitlines())
            elif m:
                out.extend(expand(SHADER_DIR / m.group(1)))
            else:
                out.append(line)
        return out

    body = expand(SHADER_DIR / name)
    head = ["#version 450 core"]
    for key, value in (defines or {}).items():
        head.append(f"#define {key} {value}" if value is not None else f"#define {key}")
    return "\n".join(head + body) + "\n"


def program(ctx, vertex: str, fragment: str | None = None, defines: dict | None = None, geometry: str | None = None):
    """Compile a program from shader files (relative to dermis/shaders)."""
    try:
        prog = ctx.program(
            vertex_shader=load_shader_source(vertex, defines),
            fragment_shader=load_shader_source(fragment, defines) if fragment else None,
            geometry_shader=load_shader_source(geometry, defines) if geometry else None,
        )
    except Exception as exc:
        raise RuntimeError(f"compiling {vertex} + {fragment}: {exc}") from exc
    # what it was compiled from (moderngl's slot for its user's data): a variant with more defines
    # can be compiled from it (dermis.techniques.shared.shading_program)
    prog.extra = {"sources": (vertex, fragment, dict(defines or {}), geometry)}
    try:
        check_samplers(ctx, prog, f"{vertex} + {fragment}")
    except Exception:
        prog.release()
        raise
    return prog


def compute(ctx, name: str, defines: dict | None = None):
    """Compile a compute shader from a file."""
    try:
        return ctx.compute_shader(load_shader_source(name, defines))
    except Exception as exc:
        raise RuntimeError(f"compiling {name}: {exc}") from exc
