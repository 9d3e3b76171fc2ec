"""Image input and output with the safety rules of the project.

- Input: size-limited BEFORE decoding (the header is read first), decoded sRGB -> linear for
  colour maps, kept as-is for data maps (normals, specular masks). One-line errors.
- Output: written to a temporary name in the destination folder and renamed, so no reader ever
  sees a half-written file (dermis.fileio: the policy for special files and symbolic links).
  PNG (8-bit sRGB after the output transform) and EXR (linear half/float).
- Readers: Pillow for 8-bit images, imagecodecs (maintained, on PyPI) for 16-bit PNG (Pillow
  reduces 16-bit RGB to 8 bits) and Radiance RGBE .hdr (Ward, "Real Pixels", Graphics Gems II),
  OpenEXR for .exr.
"""

from __future__ import annotations

import io
from pathlib import Path

import numpy as np

from dermis.errors import DermisError
from dermis.fileio import atomic_write, read_bytes, regular_file  # noqa: F401  (atomic_write: re-exported)

MAX_IMAGE_PIXELS = 8192 * 8192  # refuse larger images before decoding (64 Mpx)


def srgb_to_linear(c):
    """IEC 61966-2-1 sRGB decoding."""
    c = np.asarray(c, dtype=np.float32)
    return np.where(c <= 0.04045, c / 12.92, ((c + 0.055) / 1.055) ** 2.4).astype(np.float32)


def linear_to_srgb(c):
    """IEC 61966-2-1 sRGB encoding (input clamped to [0, 1])."""
    c = np.clip(np.asarray(c, dtype=np.float32), 0.0, 1.0)
    return np.where(c <= 0.0031308, c * 12.92, 1.055 * np.power(c, 1.0 / 2.4) - 0.055).astype(np.float32)


def _decode_bytes(data: bytes, source: str, max_pixels: int) -> np.ndarray:
    from PIL import Image

    try:
        with Image.open(io.BytesIO(data)) as im:  # reads the header only
            w, h = im.size
            if w <= 0 or h <= 0:
                raise DermisError(f"{source}: image has zero size")
            if w * h > max_pixels:
                raise DermisError(f"{source}: image is {w}x{h}, over the limit of {max_pixels} pixels; refused before decoding")
            mode = im.mode
            if _png_bit_depth(data) == 16:
                import imagecodecs

                # Pillow decodes 16-bit RGB(A) PNG to 8 bits; imagecodecs keeps all 16
                arr = np.asarray(imagecodecs.png_decode(data), dtype=np.float32) / 65535.0
            elif mode in ("I;16", "I;16B", "I;16L", "I"):
                arr = np.asarray(im, dtype=np.float32) / 65535.0
            else:
                if mode not in ("L", "RGB", "RGBA", "LA"):
                    im = im.convert("RGBA" if "A" in mode or mode == "P" else "RGB")
                arr = np.asarray(im, dtype=np.float32) / 255.0
    except DermisError:
        raise
    except Exception as exc:
        raise DermisError(f"{source}: cannot decode image ({type(exc).__name__}: {str(exc).splitlines()[0] if str(exc) else ''})") from None
    if arr.ndim == 2:
        arr = arr[:, :, None]
    return arr


def _png_bit_depth(data: bytes) -> int | None:
    """A PNG's bit depth from its IHDR chunk (byte 24), None for other formats."""
    if len(data) >= 25 and data[:8] == b"\x89PNG\r\n\x1a\n" and data[12:16] == b"IHDR":
        return data[24]
    return None


def _read_exr(path: Path, max_pixels: int) -> np.ndarray:
    import OpenEXR

    try:
        with OpenEXR.File(str(path), separate_channels=True) as f:
            hdr = f.header()
            (x0, y0), (x1, y1) = hdr["dataWindow"]
            w, h = x1 - x0 + 1, y1 - y0 + 1
            if w * h > max_pixels:
                raise DermisError(f"{path}: image is {w}x{h}, over the limit of {max_pixels} pixels; refused before decoding")
            ch = f.channels()
            names = [c for c in ("R", "G", "B") if c in ch] or list(ch)[:3]
            arr = np.stack([np.asarray(ch[n].pixels, dtype=np.float32) for n in names], axis=-1)
    except DermisError:
        raise
    except Exception as exc:
        raise DermisError(f"{path}: cannot read EXR ({type(exc).__name__})") from None
    return arr


def read_image(path, *, srgb: bool, max_pixels: int = MAX_IMAGE_PIXELS, data: bytes | None = None, source: str | None = None) -> np.ndarray:
    """Decode an image file (or bytes) to float32 (H, W, C), row 0 = top of the image.

    ``srgb=True`` decodes colour maps to linear; HDR formats (EXR, Radiance .hdr) are linear already.
    """
    src = source or str(path)
    hdr = False
    if data is None:
        p = regular_file(path, "image file")
        if p.suffix.lower() in (".exr", ".hdr"):
            arr = _read_exr(p, max_pixels) if p.suffix.lower() == ".exr" else _read_hdr(p, max_pixels)
            hdr = True
        else:
            data = read_bytes(p, "image file")
    if not hdr:
        arr = _decode_bytes(data, src, max_pixels)
        if srgb:
            c = 1 if arr.shape[2] == 2 else min(arr.shape[2], 3)  # never the alpha of L+A
            arr[:, :, :c] = srgb_to_linear(arr[:, :, :c])
    if not np.all(np.isfinite(arr)):
        raise DermisError(f"{src}: image contains NaN or infinite values")
    return arr


def as_rgb(arr: np.ndarray) -> np.ndarray:
    """(H, W, C) -> (H, W, 3): grey (and grey + alpha) replicated, alpha dropped."""
    arr = np.asarray(arr, np.float32)
    if arr.ndim == 2:
        arr = arr[:, :, None]
    if arr.shape[2] in (1, 2):
        return np.repeat(arr[:, :, :1], 3, axis=2)
    return arr[:, :, :3]


def as_rgba(arr: np.ndarray) -> np.ndarray:
    """(H, W, C) -> (H, W, 4): grey replicated, alpha kept (grey + alpha, RGBA) or 1."""
    arr = np.asarray(arr, np.float32)
    if arr.ndim == 2:
        arr = arr[:, :, None]
    alpha = arr[:, :, -1:] if arr.shape[2] in (2, 4) else np.ones(arr.shape[:2] + (1,), np.float32)
    return np.concatenate([as_rgb(arr), alpha], axis=2)


def _read_hdr(path: Path, max_pixels: int) -> np.ndarray:
    """Radiance RGBE (.hdr) through imagecodecs, with the size read from the header first."""
    data = read_bytes(path, "image file")
    size = None
    end = data.find(b"\n\n")  # the header ends with an empty line; the resolution line follows
    for line in (data[end + 2:end + 2 + 64].split(b"\n")[:1] if end >= 0 else []):
        parts = line.split()
        if len(parts) == 4 and parts[0] in (b"-Y", b"+Y", b"-X", b"+X") and parts[2] in (b"-Y", b"+Y", b"-X", b"+X"):
            try:
                a, b = int(parts[1]), int(parts[3])
            except ValueError:
                break
            if a > 0 and b > 0:
                size, dims = a * b, f"{b}x{a}"
    if size is None:
        raise DermisError(f"{path}: not a Radiance HDR image (no valid resolution line after its header)")
    if size > max_pixels:
        raise DermisError(f"{path}: image is {dims}, over the limit of {max_pixels} pixels; refused before decoding")
    try:
        import imagecodecs

        arr = np.asarray(imagecodecs.rgbe_decode(data), dtype=np.float32)
    except Exception as exc:
        raise DermisError(f"{path}: cannot read HDR image ({type(exc).__name__}: "
                          f"{str(exc).splitlines()[0] if str(exc) else 'corrupt data'})") from None
    if arr.ndim != 3 or arr.shape[0] * arr.shape[1] != size:
        raise DermisError(f"{path}: cannot read HDR image (decoded size does not match its header)")
    return arr[:, :, :3]


def png_writer(rgb_srgb_float: np.ndarray):
    """write_fn(path) writing an (H, W, 3) array of display (sRGB-encoded) [0, 1] values as 8-bit PNG."""
    from PIL import Image

    arr = np.clip(np.nan_to_num(np.asarray(rgb_srgb_float, np.float32)) * 255.0 + 0.5, 0, 255).astype(np.uint8)
    return lambda tmp: Image.fromarray(arr).save(tmp, format="PNG")


def exr_writer(rgb_linear: np.ndarray, half: bool = False):
    """write_fn(path) writing a linear (H, W, 3) image as OpenEXR (float32 by default, or half)."""
    import OpenEXR

    arr = np.ascontiguousarray(np.asarray(rgb_linear, np.float16 if half else np.float32))

    def write(tmp):
        header = {"compression": OpenEXR.ZIP_COMPRESSION, "type": OpenEXR.scanlineimage}
        with OpenEXR.File(header, {"RGB": arr}) as f:
            f.write(str(tmp))

    return write


def write_png(path, rgb_srgb_float: np.ndarray) -> Path:
    """Write an (H, W, 3) array already in display (sRGB-encoded) [0, 1] values as 8-bit PNG."""
    return atomic_write(path, png_writer(rgb_srgb_float))


def write_exr(path, rgb_linear: np.ndarray, half: bool = False) -> Path:
    """Write a linear (H, W, 3) image as OpenEXR (float32 by default, or half)."""
    return atomic_write(path, exr_writer(rgb_linear, half))
