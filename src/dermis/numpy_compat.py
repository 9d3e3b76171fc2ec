"""numpy 1.26 - 2.x: the numpy-2-only names dermis uses, under names that work on both.

dermis supports numpy >= 1.26 because Blender's Python module (bpy 4.2 - 5.0.1, the ``cycles``
extra, CPython 3.11) pins ``numpy>=1.26,<2`` in its metadata. Code and tests import these instead
of the numpy-2 spellings; tests/test_numpy_compat.py fails on any numpy-2-only name elsewhere.
"""

from __future__ import annotations

import numpy as np

# numpy 2.0 renamed np.trapz (composite trapezoid rule, same signature and result) to np.trapezoid and
# deprecated the old name; numpy 1.26 has only np.trapz.
trapezoid = getattr(np, "trapezoid", None) or np.trapz

__all__ = ["trapezoid"]
