"""Shared fixtures. Tests render small (256-512 px) so they stay fast on Mesa llvmpipe."""

from __future__ import annotations

from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parent.parent
HEAD_ASSETS = REPO / "examples" / "assets" / "lee-perry-smith"


@pytest.fixture(scope="session")
def lee_perry_smith() -> Path:
    """The real head scan, shipped in examples/assets/lee-perry-smith (CC BY 3.0)."""
    assert (HEAD_ASSETS / "LeePerrySmith.glb").is_file(), f"{HEAD_ASSETS} is part of the repository"
    return HEAD_ASSETS


@pytest.fixture(scope="session")
def gl_ctx():
    """One EGL context for the session (creating one costs ~50 ms, compiling programs more)."""
    from dermis.gl.context import create_context

    ctx = create_context()
    yield ctx
    ctx.release()


@pytest.fixture(scope="session")
def example_head_toml(lee_perry_smith) -> Path:
    return REPO / "examples" / "lee-perry-smith.toml"


# an asymmetric scene (a box over a plane): turning it changes the image even when the light
# turns with the camera (viewer and turntable tests)
BOX_SCENE_TOML = """
[scene]
name = "box-over-plane"
mm_per_unit = 20.0

[mesh]
builtin = "box_over_plane"

[[lights]]
type = "directional"
direction = [0.5, -0.6, -0.6]
color = [1.0, 0.95, 0.9]
intensity = 3.0
"""


@pytest.fixture(scope="session")
def box_toml(tmp_path_factory) -> Path:
    p = tmp_path_factory.mktemp("box_scene") / "box.toml"
    p.write_text(BOX_SCENE_TOML)
    return p
