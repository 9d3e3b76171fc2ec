"""Blender Cycles as ground truth: export any dermis scene to a .blend, render it in Cycles through
``bpy`` (Blender as a Python module, the ``cycles`` extra), and score the real-time techniques
against the path-traced render (``dermis export``, ``dermis cycles``, ``dermis validate --against
cycles``).

Only this package imports ``bpy``; everything else of dermis works without it.
"""

from __future__ import annotations

import os
import tempfile

from dermis.errors import DermisError

INSTALL_HINT = ("Blender's Python module (bpy) is not installed: run pip install -e \".[cycles]\" "
                "(or `make cycles`; CPython 3.11 only, about 370 MB)")

_bpy = None


def bpy_available() -> bool:
    """True when ``import bpy`` can work (without importing it: the import costs about a second)."""
    import importlib.util

    return importlib.util.find_spec("bpy") is not None


class quiet_fds:
    """Silence fds 1 and 2 (Blender's C code prints status and the numpy-1.x audio warning)."""

    def __enter__(self):
        self._null = os.open(os.devnull, os.O_WRONLY)
        self._saved = [os.dup(1), os.dup(2)]
        os.dup2(self._null, 1)
        os.dup2(self._null, 2)
        return self

    def __exit__(self, *exc):
        for fd, saved in zip((1, 2), self._saved):
            os.dup2(saved, fd)
            os.close(saved)
        os.close(self._null)
        return False


def require_bpy():
    """The ``bpy`` module, imported once; DermisError with the install line when it is absent.

    bpy's audio module is built against numpy 1.x (the extra resolves numpy 1.26); where bpy was
    put beside numpy 2 by hand (pip --no-deps) it prints a long warning and runs without audio,
    which rendering does not use: the import's stderr is captured and shown only when it fails.
    """
    global _bpy
    if _bpy is not None:
        return _bpy
    if not bpy_available():
        raise DermisError(INSTALL_HINT)
    with tempfile.TemporaryFile() as cap:
        saved = os.dup(2)
        os.dup2(cap.fileno(), 2)
        try:
            import bpy  # noqa: F401
        except Exception as exc:
            os.dup2(saved, 2)
            cap.seek(0)
            detail = cap.read().decode(errors="replace").strip().splitlines()
            raise DermisError(f"bpy failed to import ({exc}){': ' + detail[-1] if detail else ''}") from None
        finally:
            os.dup2(saved, 2)
            os.close(saved)
    import bpy

    _bpy = bpy
    return bpy
