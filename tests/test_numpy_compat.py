"""dermis runs on numpy 1.26 and 2.x (the ``cycles`` extra brings bpy, which pins numpy<2).

Under numpy 2 nothing would notice a numpy-2-only name creeping in, so the sources are scanned for
them; dermis.numpy_compat holds the ones dermis needs.
"""

from __future__ import annotations

import re
import tomllib
from pathlib import Path

import numpy as np
import pytest

from dermis.numpy_compat import trapezoid

REPO = Path(__file__).resolve().parent.parent

# Names that numpy 2.0-2.2 added (release notes: the array-API aliases, np.trapezoid, np.astype,
# ndarray.mT/device, the linalg array-API functions, np.strings, copy= on asarray/reshape) and that
# numpy 1.26 lacks. np.bool and np.long exist in 2.x again but not in 1.24-1.26.
NUMPY2_ONLY = re.compile(
    r"\bnp\.(trapezoid|astype|isdtype|concat|permute_dims|pow|acos|acosh|asin|asinh|atan|atanh|atan2|"
    r"bitwise_(count|invert|left_shift|right_shift)|unstack|cumulative_(sum|prod)|matvec|vecmat|vecdot|"
    r"matrix_transpose|unique_(all|counts|inverse|values)|strings|bool|long|ulong)\b(?!_)"
    r"|\bnp\.linalg\.(vecdot|matrix_norm|vector_norm|svdvals|matrix_transpose|diagonal|trace|outer|cross|"
    r"tensordot|matmul)\b"
    r"|\.mT\b|\bStringDType\b|np\.(asarray|reshape)\([^)\n]*\bcopy="
)


def test_trapezoid_matches_the_closed_form():
    """Composite trapezoid rule of x^2 on n equal intervals of [0, 1]: 1/3 + 1/(6 n^2) exactly."""
    for n in (1, 4, 37):
        x = np.linspace(0.0, 1.0, n + 1)
        assert trapezoid(x * x, x) == pytest.approx(1 / 3 + 1 / (6 * n * n), rel=1e-12)
    x = np.linspace(0.0, 2.0, 9)
    y = np.stack([x, 3 * x], -1)  # linear: exact, along axis 0
    assert np.allclose(trapezoid(y, x, axis=0), [2.0, 6.0], rtol=1e-12)


def test_no_numpy2_only_names_in_the_sources():
    """Every numpy-2-only spelling goes through dermis.numpy_compat (bpy pins numpy<2)."""
    hits = []
    for top in ("src", "tests", "benchmarks", "scripts", "examples"):
        for f in sorted((REPO / top).rglob("*.py")):
            if f.name in ("numpy_compat.py", Path(__file__).name):
                continue
            for i, line in enumerate(f.read_text(encoding="utf-8").splitlines(), 1):
                code = line.split("#", 1)[0]
                if NUMPY2_ONLY.search(code):
                    hits.append(f"{f.relative_to(REPO)}:{i}: {line.strip()}")
    assert not hits, "numpy-2-only names (use dermis.numpy_compat):\n" + "\n".join(hits)


def test_the_scan_sees_numpy2_names():
    for bad in ("np.trapezoid(y, x)", "a = np.astype(b, int)", "np.linalg.vecdot(a, b)", "v.mT",
                "np.asarray(a, copy=False)", "np.bool(1)", "np.concat([a, b])"):
        assert NUMPY2_ONLY.search(bad), bad
    for ok in ("np.trapz(y, x)", "a.astype(int)", "np.bool_(1)", "np.concatenate([a])", "np.array(a, copy=False)",
               "np.atan2x", "np.longdouble"):
        assert not NUMPY2_ONLY.search(ok), ok


def test_numpy_requirement_admits_the_cycles_extra():
    """dermis's numpy range overlaps bpy's numpy pin (so pip can resolve .[cycles])."""
    from packaging.requirements import Requirement

    deps = tomllib.loads((REPO / "pyproject.toml").read_text())["project"]["dependencies"]
    numpy_req = next(Requirement(d) for d in deps if Requirement(d).name == "numpy")
    try:  # the installed bpy's own pin when it is there, else bpy 4.2-5.0.1's
        from importlib.metadata import requires

        pin = next(Requirement(r) for r in requires("bpy") or () if Requirement(r).name == "numpy").specifier
    except Exception:
        from packaging.specifiers import SpecifierSet

        pin = SpecifierSet(">=1.26,<2.0")
    both = numpy_req.specifier & pin
    assert any(both.contains(v) for v in ("1.26.0", "1.26.4")), (str(numpy_req), str(pin))
    assert numpy_req.specifier.contains(np.__version__), np.__version__
