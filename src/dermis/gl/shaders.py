"""GLSL 450 sources kept in ``dermis/shaders`` with a small ``#include "path"`` mechanism.

Paths in #include are relative to the shaders folder (``#include "common/brdf.glsl"``); each file
is included once per program (include guards are implicit). ``#version`` is added here so that
includes never carry one. Compile errors name the file.
"""

from __future__ import annotations

import re
from pathlib import Path

SHADER_DIR = Path(__file__).resolve().parent.parent / "shaders"
_INCLUDE = re.compile(r'^\s*#include\s+"([^"]+)"\s*$')


def load_shader_source(name: str, defines: dict | None = None) -> str:
    """Expand a shader file's includes; prepend #version 450 core and the given #defines."""
    seen: set[Path] = set()

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
            if m:
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
        return ctx.program(
            vertex_shader=load_shader_source(vertex, defines),
            fragment_shader=load_shader_source(fragment, defines) if fragment else None,
            geometry_shader=load_shader_source(geometry, defines) if geometry else None,
        )
    except Exception as exc:
        raise RuntimeError(f"compiling {vertex} + {fragment}: {exc}") from exc


def compute(ctx, name: str, defines: dict | None = None):
    """Compile a compute shader from a file."""
    try:
        return ctx.compute_shader(load_shader_source(name, defines))
    except Exception as exc:
        raise RuntimeError(f"compiling {name}: {exc}") from exc
