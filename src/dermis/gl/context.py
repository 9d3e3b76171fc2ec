"""Headless OpenGL 4.5 core contexts through EGL (moderngl + glcontext).

On a machine without a GPU, EGL gives Mesa's llvmpipe (slow, exact); on NVIDIA machines the
vendor EGL. The user never creates a context: :func:`create_context` is called by the renderer.
"""

from __future__ import annotations

import os
import time

from dermis.errors import GLUnavailableError

_INSTALL_HINT = (
    "install the headless GL packages (Debian/Ubuntu: apt-get install libegl1 libgl1 libegl-mesa0 "
    "libgl1-mesa-dri) or run on a machine with a GPU driver"
)


def create_context(device_index: int | None = None):
    """Create a standalone OpenGL 4.5 core context through EGL.

    ``device_index`` picks the EGL device (GPU) on machines with several; None takes the default.
    The DERMIS_GL_DEVICE environment variable sets it too. Raises GLUnavailableError (one line).
    """
    try:
        import moderngl
    except Exception as exc:  # pragma: no cover - import failure is an install problem
        raise GLUnavailableError(f"cannot import moderngl ({exc}); reinstall dermis") from None
    if device_index is None and os.environ.get("DERMIS_GL_DEVICE", "").strip():
        try:
            device_index = int(os.environ["DERMIS_GL_DEVICE"])
        except ValueError:
            raise GLUnavailableError("DERMIS_GL_DEVICE must be an integer device index") from None
    kwargs = {"standalone": True, "backend": "egl", "require": 450}
    if device_index is not None:
        if device_index < 0:
            raise GLUnavailableError(f"GL device index must be >= 0, got {device_index}")
        kwargs["device_index"] = int(device_index)
    try:
        ctx = moderngl.create_context(**kwargs)
    except Exception as exc:
        first = str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__
        if device_index is not None and "device" in first.lower():
            raise GLUnavailableError(f"no OpenGL context on EGL device {device_index} ({first}); "
                                     "choose another --device / DERMIS_GL_DEVICE") from None
        raise GLUnavailableError(f"no OpenGL 4.5 context through EGL ({first}); {_INSTALL_HINT}") from None
    if ctx.version_code < 450:
        ctx.release()
        raise GLUnavailableError(f"OpenGL 4.5 core is required, the driver offers {ctx.version_code}; {_INSTALL_HINT}")
    return ctx


def is_software(ctx) -> bool:
    """True on Mesa's CPU rasterisers (llvmpipe, softpipe), where MSAA is capped at 4x."""
    r = ctx.info.get("GL_RENDERER", "").lower()
    return "llvmpipe" in r or "softpipe" in r or "swrast" in r


def rasteriser_ns() -> tuple[int, int]:
    """(summed run time in ns, thread count) of Mesa llvmpipe's rasteriser threads in this process
    (/proc/self/task/*/schedstat: CPU time actually run, not time waited for a core)."""
    from pathlib import Path

    total, n = 0, 0
    tasks = Path("/proc/self/task")
    if not tasks.is_dir():  # not Linux: no per-thread run times; cpu_busy_ns is then the calling thread's alone
        return 0, 0
    for task in tasks.iterdir():
        try:
            if not (task / "comm").read_text().startswith("llvmpipe"):
                continue
            total += int((task / "schedstat").read_text().split()[0])
            n += 1
        except (OSError, ValueError, IndexError):
            continue
    return total, n


def cpu_busy_ns() -> int:
    """A CPU-time clock for a pass on llvmpipe, in ns: the rasteriser threads' run time divided by
    their number (their busy time if evenly loaded) plus the calling thread's CPU time (vertex
    processing and setup run there). Unlike the wall clock it does not grow while another process
    holds a core: on the shared 2-core machine (round 15, perf15) tsd's lights-moving frame took
    500 or 940 ms of wall time by the machine's state, and 462-504 ms of this clock throughout."""
    total, n = rasteriser_ns()
    return total // max(n, 1) + time.thread_time_ns()


def gl_info(ctx) -> dict:
    """Renderer, version and the limits dermis cares about."""
    info = ctx.info
    return {
        "renderer": info.get("GL_RENDERER", "?"),
        "vendor": info.get("GL_VENDOR", "?"),
        "version": info.get("GL_VERSION", "?"),
        "glsl": "4.50 core (shaders are #version 450 core)",
        "version_code": ctx.version_code,
        "max_texture_size": info.get("GL_MAX_TEXTURE_SIZE"),
        "max_samples": ctx.max_samples,
        "max_texture_units": ctx.max_texture_units,
        "max_viewport_dims": info.get("GL_MAX_VIEWPORT_DIMS"),
        "software": is_software(ctx),
    }
