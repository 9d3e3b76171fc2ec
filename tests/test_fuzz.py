"""Fuzz the loaders, the API and the CLI: hypothesis cases from tests/fuzzing.py, each
strictly classified; anything but a finite image or a clean one-line error fails the test.

The normal run is bounded (FUZZ_EXAMPLES cases per family, a fixed derandomised seed, 16x16
frames on one shared GL context, CLI cases in-process); ``make fuzz`` (scripts/fuzz.py) runs
>= 10,000 cases with a random seed and records the counts in benchmarks/RESULTS.md.
"""

from __future__ import annotations

import os
import sys
import tempfile
from pathlib import Path

import pytest

pytest.importorskip("hypothesis")
from hypothesis import HealthCheck, given, settings  # noqa: E402
from hypothesis import strategies as st  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parent))
import fuzzing as fz  # noqa: E402

EXAMPLES = int(os.environ.get("FUZZ_EXAMPLES", "25"))
_FOLDERS: dict[str, Path] = {}
RECORD = None  # scripts/fuzz.py sets a callback(family, outcome, case) and turns STRICT off
STRICT = True


def folder(family: str) -> Path:
    """One prepared folder per family for the whole run (cases overwrite their own files)."""
    if family not in _FOLDERS:
        root = Path(tempfile.mkdtemp(prefix=f"dermis-fuzz-{family}-"))
        d = root / "case"
        d.mkdir()
        (fz.prepare_cli_folder if family == "cli" else fz.prepare_folder)(d)
        _FOLDERS[family] = d
    return _FOLDERS[family]


def _run_toml(text):
    d = folder("toml")
    (d / "scene.toml").write_text(text)
    return fz.classify(lambda: fz.render_loaded(d / "scene.toml"))


def _run_gltf(case, technique):
    d = folder("gltf")
    path = fz.write_gltf_case(d, case)
    return fz.classify(lambda: fz.render_loaded(path, technique))


def _run_obj(case, technique):
    d = folder("obj")
    text, mtl = case
    (d / "case.obj").write_text(text)
    if mtl is not None:
        (d / "m.mtl").write_text(mtl)
    elif (d / "m.mtl").exists():
        (d / "m.mtl").unlink()
    return fz.classify(lambda: fz.render_loaded(d / "case.obj", technique))


def _run_image(case, technique):
    d = folder("image")
    name, data, role = case
    (d / name).write_bytes(data)
    (d / "scene.toml").write_text(fz.image_scene(name, role))
    return fz.classify(lambda: fz.render_loaded(d / "scene.toml", technique))


def _run_api(case):
    return fz.run_api_case(case)


def _run_cli(argv):
    return fz.run_cli_case(argv, folder("cli"))


TECH = st.sampled_from(fz.TECHNIQUES)
FAMILIES = {  # name -> (strategy of the arguments, runner)
    "toml": (st.tuples(fz.scene_tomls()), _run_toml),
    "gltf": (st.tuples(fz.gltf_cases(), TECH), _run_gltf),
    "obj": (st.tuples(fz.obj_cases(), TECH), _run_obj),
    "image": (st.tuples(fz.image_cases(), TECH), _run_image),
    "api": (st.tuples(fz.api_cases()), _run_api),
    "cli": (st.tuples(fz.cli_cases()), _run_cli),
}


def family_test(name, examples, seed=None):
    """A hypothesis test running family ``name``: returns a zero-argument callable."""
    strategy, runner = FAMILIES[name]

    @settings(max_examples=examples, deadline=None, database=None, derandomize=seed is None, print_blob=True,
              suppress_health_check=list(HealthCheck))
    @given(strategy)
    def run(args):
        outcome = runner(*args)
        if RECORD is not None:
            RECORD(name, outcome, args)
        if STRICT:
            assert outcome.kind != fz.OTHER, f"{name}: {outcome.detail} for {args!r}"[:2000]

    if seed is not None:
        from hypothesis import seed as with_seed

        run = with_seed(seed)(run)
    return run


@pytest.mark.parametrize("family", list(FAMILIES))
def test_fuzz_family(family):
    family_test(family, EXAMPLES)()


@settings(max_examples=4, deadline=None, database=None, derandomize=True, suppress_health_check=list(HealthCheck))
@given(fz.cli_cases())
def test_fuzz_cli_as_real_processes(argv):
    """A handful of CLI cases as real processes: stderr there includes what C libraries print."""
    import subprocess

    d = folder("cli")
    argv = [a.replace("OUT", str(d)).replace("SCENE", str(d / "s.toml")) for a in argv]
    before = set(d.rglob("*"))
    res = subprocess.run([sys.executable, "-m", "dermis.cli", *argv], capture_output=True, text=True, timeout=300,
                         cwd=d)
    lines = [ln for ln in res.stderr.splitlines() if ln.strip()]
    new = sorted(set(d.rglob("*")) - before)
    try:
        if res.returncode == 0:
            assert not lines and not [p for p in new if ".part" in p.name], res.stderr
        else:
            assert res.returncode == 2 and len(lines) == 1 and lines[0].startswith("dermis: error: "), res.stderr
            assert not new, new
    finally:
        for p in sorted(new, reverse=True):
            if p.is_dir() and not p.is_symlink():
                import shutil

                shutil.rmtree(p, ignore_errors=True)
            elif os.path.lexists(p):
                p.unlink()
