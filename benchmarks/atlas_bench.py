"""Time to generate (and then to read back from the disk cache) the texture-space atlas of the
Lee Perry-Smith head and of a ~500k-triangle sphere (trimesh). Not part of the test suite: run
    PYTHONPATH=src python benchmarks/atlas_bench.py [--skip-large]
Results go to benchmarks/RESULTS.md by hand."""

from __future__ import annotations

import os
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]


def run(name, mesh, mm_per_unit):
    from dermis.geometry.texture_space import with_texture_space_uvs

    t0 = time.perf_counter()
    g = with_texture_space_uvs(mesh, "generate", resolution=1024, mm_per_unit=mm_per_unit, widest_variance_mm2=2.0062)
    t1 = time.perf_counter()
    with_texture_space_uvs(mesh, "generate", resolution=1024, mm_per_unit=mm_per_unit, widest_variance_mm2=2.0062)
    t2 = time.perf_counter()
    print(f"{name}: {len(mesh.indices)} triangles, {len(mesh.positions)} -> {len(g.positions)} vertices; "
          f"generate + cache {t1 - t0:.2f} s, cached {t2 - t1:.3f} s", flush=True)


def main():
    os.environ["DERMIS_CACHE_DIR"] = tempfile.mkdtemp(prefix="dermis-atlas-bench-")
    from dermis.scene.loaders import load_mesh_file

    head, _ = load_mesh_file(REPO / "examples/assets/lee-perry-smith/LeePerrySmith.glb", "v-up")
    run("Lee Perry-Smith head", head, 48.0)
    if "--skip-large" in sys.argv:
        return
    import trimesh

    from dermis.scene.loaders import finish_mesh

    s = trimesh.creation.icosphere(subdivisions=7, radius=100.0)  # 327,680 triangles
    # one more midpoint subdivision of 57,344 of them (each becomes 4): 499,712 triangles
    s = s.subdivide(face_index=np.arange(57_344))
    m = finish_mesh(s.vertices, None, np.zeros((len(s.vertices), 2)), s.faces, "icosphere", "v-up")
    run("subdivided icosphere", m, 1.0)


if __name__ == "__main__":
    main()
