"""Re-key the stored Cycles renders after an edit to dermis.blender's sources that does not change
what the stored scenes render.

`dermis validate --against cycles` (dermis.blender.validate._accumulator_key), the 768 px crops
(benchmarks/cycles_crops.py crop_key) and the built-in scene's windows (benchmarks/cycles_builtin.py)
key what they store on, among the scene, the whole source text of dermis.blender's convert, export,
render and sss modules, so that any change to the bridge makes them stale rather than silently wrong.
An edit that provably leaves a stored scene's Blender scene as it was (round 21: export.py loads an
HDR or in-memory albedo as linear; every stored scene's albedo is an 8-bit JPEG or PNG file, which
takes the unchanged path) would otherwise throw away hours of samples. This script recomputes each
stored file's key with the four modules' text at REV and with the current text, and rewrites the
key only where the stored key is REV's (a file stale for another reason is reported and left).
Saying that the edit does not change the stored scenes is the caller's job; write why in RESULTS.

    PYTHONPATH=src python benchmarks/rekey_cycles_stores.py --from REV [--dry-run]
"""

from __future__ import annotations

import argparse
import contextlib
import inspect
import json
import subprocess
import sys
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(REPO / "benchmarks"))
CYCLES = REPO / "benchmarks" / "cycles"
BRIDGE_MODULES = ("convert", "export", "render", "sss")  # what _accumulator_key hashes, in its order


@contextlib.contextmanager
def bridge_sources_at(rev: str):
    """inspect.getsource answers REV's text for the four hashed modules while inside."""
    import importlib

    old = {}
    for name in BRIDGE_MODULES:
        mod = importlib.import_module(f"dermis.blender.{name}")
        text = subprocess.run(["git", "show", f"{rev}:src/dermis/blender/{name}.py"], cwd=REPO, check=True,
                              capture_output=True, text=True).stdout
        old[id(mod)] = text
    real = inspect.getsource

    def patched(obj):
        return old[id(obj)] if id(obj) in old else real(obj)

    inspect.getsource = patched
    try:
        yield
    finally:
        inspect.getsource = real


def _stores():
    """(path, key function) of validate's accumulations: stores/<scene>/cycles_<mode>[_nosss]_<W>x<H>.npz."""
    import dermis
    from dermis.blender.validate import _accumulator_key

    for path in sorted((CYCLES / "stores").glob("*/cycles_*.npz")):
        scene_file = REPO / "examples" / "reference" / f"{path.parent.name}.toml"
        parts = path.stem.split("_")  # cycles, spec|nospec, [nosss], WxH
        w, h = (int(v) for v in parts[-1].split("x"))
        specular, sss = parts[1] == "spec", "nosss" not in parts

        def key(scene_file=scene_file, w=w, h=h, sss=sss, specular=specular):
            sc = dermis.load_scene(scene_file)  # as dermis.blender.validate.validate_cycles sets it up
            sc.material.pore_strength = 0.0
            if not specular:
                sc.material.rho_s = 0.0
            return _accumulator_key(sc, (w, h), sss, specular)

        yield path, key


def _crops():
    """(path, key function) of the 768 px crops and the built-in scene's windows."""
    import dermis
    import cycles_builtin
    import cycles_crops

    for folder, scene_of in ((CYCLES / "crops", lambda m: dermis.load_scene(cycles_crops.SCENES[m["scene"]])),
                             (CYCLES / "builtin", lambda m: cycles_builtin.builtin_scene())):
        for path in sorted(folder.glob("*.npz")):
            with np.load(path) as z:
                meta = json.loads(str(z["meta"]))
            specular = meta.get("specular", not path.stem.endswith("-nospec"))

            def key(meta=meta, specular=specular, scene_of=scene_of):
                sc = scene_of(meta)
                if not specular:
                    sc.material.rho_s = 0.0
                return cycles_crops.crop_key(sc, meta["size"], meta["box"], meta["spp"], meta["seeds"], specular)

            yield path, key


def _stored_key(path: Path) -> str:
    with np.load(path) as z:
        return str(z["key"]) if "key" in z.files else json.loads(str(z["meta"]))["key"]


def _rewrite(path: Path, new_key: str) -> None:
    from dermis.fileio import atomic_write

    with np.load(path) as z:
        data = {k: z[k] for k in z.files}
    if "key" in data:  # validate's accumulation (np.savez, as CyclesAccumulation writes it)
        data["key"] = np.asarray(new_key)
        save = np.savez
    else:  # a crop (np.savez_compressed, as cycles_crops.save_crop writes it)
        meta = json.loads(str(data["meta"]))
        meta["key"] = new_key
        data["meta"] = np.asarray(json.dumps(meta))
        save = np.savez_compressed

    def write(tmp):
        with open(tmp, "wb") as f:
            save(f, **data)

    atomic_write(path, write)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--from", dest="rev", required=True, help="the revision whose bridge sources keyed the stores")
    ap.add_argument("--dry-run", action="store_true")
    a = ap.parse_args()
    entries = list(_stores()) + list(_crops())
    with bridge_sources_at(a.rev):
        old = {p: key() for p, key in entries}
    counts = {"rekeyed": 0, "current": 0, "stale": 0}
    for path, key in entries:
        new, stored = key(), _stored_key(path)
        rel = path.relative_to(REPO)
        if stored == new:
            counts["current"] += 1
        elif stored == old[path]:
            counts["rekeyed"] += 1
            print(f"{rel}: {stored[:12]} -> {new[:12]}")
            if not a.dry_run:
                _rewrite(path, new)
        else:
            counts["stale"] += 1
            print(f"{rel}: stale before {a.rev} too (left as is)")
    print(counts, "(dry run)" if a.dry_run else "")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
