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


# The test files that take longest (tens of seconds each on 2 cores; `make test`'s --durations and
# benchmarks/RESULTS.md round 20), slowest first. `make test` runs the suite on two workers that take one
# whole file at a time (pytest-xdist, --dist loadfile --no-loadscope-reorder: a file's module fixtures are
# built once); starting with these leaves only short files for the end, so neither worker runs a long
# file alone while the other has finished. Only the order changes; a file not listed keeps its place after
# these, and a stale list costs only time.
SLOW_FILES_FIRST = (
    "test_reference.py", "test_subsurface_transfer.py", "test_viewer.py", "test_render_analytic.py",
    "test_artifact_scan.py", "test_environment_occlusion.py", "test_batch.py", "test_procedural_head.py",
    "test_fuzz.py", "test_light_unroll.py", "test_environment_specular.py", "test_ssss.py",
    "test_tsd_pixel_detail.py", "test_texture_space_uvs.py", "test_metallic_roughness.py", "test_tsd_pipeline.py",
    "test_tsd_cached_paths.py", "test_profiles_measured.py", "test_compare.py", "test_cli.py",
    "test_environment_rotation.py", "test_blender_cycles.py",
)


def pytest_collection_modifyitems(config, items):
    rank = {name: i for i, name in enumerate(SLOW_FILES_FIRST)}
    # a stable sort: within a file, and among the files not listed, the collection's own order stays
    items.sort(key=lambda item: rank.get(item.path.name, len(rank)))
