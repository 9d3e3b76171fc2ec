"""Turntables: the camera circles the scene's target and each frame goes to a video or images.

Two motions: by default the lights stay fixed to the head and the camera circles (the
view-independent texture-space passes of ``tsd`` run once, then only the final pass per frame);
with ``orbit_light`` the lights circle with the camera, as when a head turns on a turntable in
a fixed studio (texture space re-runs every frame). Frames are rendered headless (EGL), tone
mapped with :func:`dermis.output.output_transform` and written through maintained writers:
``.mp4`` by imageio-ffmpeg (H.264, yuv420p; the ffmpeg binary ships inside its wheel), ``.gif``
by imageio's Pillow plugin, or a folder of PNGs. Files are written under a temporary name and
renamed when complete.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from dermis.errors import DermisError
from dermis.fileio import OutputSet
from dermis.viewer.camera_controls import orbit_rig, rotate_about_axis

FORMATS = (".mp4", ".gif", "folder of .png")
MAX_FRAMES = 10_000


def output_kind(out) -> str:
    p = Path(out)
    ext = p.suffix.lower()
    if ext in (".mp4", ".gif"):
        return ext[1:]
    if ext == "" or p.is_dir():
        return "png"
    raise DermisError(f"{out}: unsupported turntable output '{ext}' (use .mp4, .gif or a folder for PNG frames)")


class _AtomicFile:
    """A temporary name beside ``path`` (keeping its extension, which the encoders read), renamed over it
    when the last frame is written (dermis.fileio.OutputSet: also gives the file the usual permissions)."""

    def __init__(self, path: Path):
        self.path = path
        folder = path.parent if str(path.parent) else Path(".")
        if not folder.is_dir():
            raise DermisError(f"{path}: output folder {folder} does not exist")
        self._outputs = OutputSet()
        self.tmp = self._outputs.reserve(path)

    def commit(self):
        self._outputs.commit()

    def discard(self):
        self._outputs.abort()


class Mp4Writer:
    def __init__(self, path: Path, size, fps: float):
        try:
            import imageio_ffmpeg
        except ImportError:
            raise DermisError("writing .mp4 needs imageio-ffmpeg (pip install imageio-ffmpeg); or write a .gif") from None
        self.file = _AtomicFile(path)
        w, h = size
        # H.264 in yuv420p needs even sizes: imageio-ffmpeg scales up to a multiple of 2 if needed
        self.gen = imageio_ffmpeg.write_frames(str(self.file.tmp), (w, h), fps=fps, codec="libx264", quality=8,
                                               pix_fmt_in="rgb24", pix_fmt_out="yuv420p", macro_block_size=2,
                                               ffmpeg_log_level="error")
        self.gen.send(None)

    def write(self, rgb8: np.ndarray):
        self.gen.send(np.ascontiguousarray(rgb8))

    def close(self, ok: bool = True):
        try:
            self.gen.close()
        finally:
            self.file.commit() if ok else self.file.discard()


class GifWriter:
    def __init__(self, path: Path, size, fps: float):
        import imageio.v3 as iio

        self.file = _AtomicFile(path)
        self.writer = iio.imopen(self.file.tmp, "w", plugin="pillow", extension=".gif")
        self.duration_ms = 1000.0 / fps

    def write(self, rgb8: np.ndarray):
        self.writer.write(rgb8, is_batch=False, duration=self.duration_ms, loop=0)

    def close(self, ok: bool = True):
        try:
            self.writer.close()
        finally:
            self.file.commit() if ok else self.file.discard()


class PngFolderWriter:
    def __init__(self, path: Path, size, fps: float):
        if path.exists() and not path.is_dir():
            raise DermisError(f"{path}: exists and is not a folder")
        if not path.parent.is_dir():
            raise DermisError(f"{path}: output folder {path.parent} does not exist")
        path.mkdir(exist_ok=True)
        self.path = path
        self.index = 0

    def write(self, rgb8: np.ndarray):
        from PIL import Image

        from dermis.images import atomic_write

        atomic_write(self.path / f"frame_{self.index:05d}.png", lambda tmp: Image.fromarray(rgb8).save(tmp, format="PNG"))
        self.index += 1

    def close(self, ok: bool = True):
        pass


WRITERS = {"mp4": Mp4Writer, "gif": GifWriter, "png": PngFolderWriter}


def orbit_camera(camera, angle_rad: float):
    """A copy of ``camera`` rotated by ``angle_rad`` about its up axis through its target."""
    import copy

    c = copy.copy(camera)
    t = np.asarray(camera.target, np.float64)
    c.position = tuple(float(x) for x in t + rotate_about_axis(np.asarray(camera.position, np.float64) - t, camera.up, angle_rad))
    return c


def to_rgb8(display: np.ndarray) -> np.ndarray:
    return np.clip(np.asarray(display, np.float32) * 255.0 + 0.5, 0, 255).astype(np.uint8)


def turntable(scene, out, *, frames: int = 60, size=(512, 512), technique: str | None = None, orbit_light: bool = False,
              degrees: float = 360.0, fps: float = 24.0, irradiance_size: int = 1024, samples: int = 4,
              device: int | None = None, exposure: float | None = None, tonemap: str | None = None,
              progress: bool = True) -> dict:
    """Render ``frames`` views around the scene into ``out`` (.mp4, .gif or a folder of PNGs).

    Frame i looks from the camera turned by ``degrees * i / frames`` (a full turn loops without
    a repeated frame). Returns {"path", "frames", "size", "format", "frame_ms" and "passes_run"
    (per frame), "technique", "orbit_light"}.
    """
    from tqdm import tqdm

    from dermis.output import output_transform
    from dermis.renderer import Renderer, check_size

    if isinstance(frames, bool) or not isinstance(frames, (int, np.integer)) or not 1 <= int(frames) <= MAX_FRAMES:
        raise DermisError(f"frames: must be an integer in [1, {MAX_FRAMES}], got {frames!r}")
    if not (math.isfinite(fps) and 0 < fps <= 240):
        raise DermisError(f"fps: must lie in (0, 240], got {fps}")
    if not math.isfinite(degrees):
        raise DermisError(f"degrees: must be a finite number, got {degrees}")
    w, h = check_size(size)
    out = Path(out)
    kind = output_kind(out)
    name = technique or scene.technique
    from dermis.techniques import technique_class

    technique_class(name)
    o = scene.output
    exposure = o.exposure if exposure is None else float(exposure)
    tonemap = tonemap or o.tonemap
    base_camera = scene.camera
    base_lights = list(scene.lights)
    times, passes = [], []
    writer = None
    ok = False
    try:
        with Renderer(scene, (w, h), device=device, samples=samples, irradiance_size=irradiance_size) as r:
            writer = WRITERS[kind](out, (w, h), fps)
            bar = tqdm(total=int(frames), desc=f"turntable {out.name}", unit="frame", disable=not progress,
                       dynamic_ncols=True, leave=False)
            for i in range(int(frames)):
                angle = math.radians(degrees * i / int(frames))
                cam = orbit_camera(base_camera, angle)
                if orbit_light:
                    scene.lights = orbit_rig(scene, angle, axis=base_camera.up, center=base_camera.target)
                img = r.render(name, camera=cam)
                if not np.isfinite(img).all():
                    raise DermisError(f"{scene.source}: frame {i} has NaN or infinite values")
                times.append(float(r.stats["frame_ms"]))
                passes.append(list(r.stats.get("passes_run", [])))
                display = output_transform(img, exposure, tonemap, getattr(o, "bloom", 0.0), getattr(o, "bloom_radius", 0.015))
                writer.write(to_rgb8(display))
                bar.update(1)
            bar.close()
        ok = True
    finally:
        scene.lights = base_lights
        if writer is not None:
            writer.close(ok)
    return {"path": str(out), "frames": int(frames), "size": [w, h], "format": kind, "frame_ms": times, "passes_run": passes,
            "technique": name, "orbit_light": bool(orbit_light)}
