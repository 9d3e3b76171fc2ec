"""Writes studio.exr, the environment of environment.toml: a small procedural equirectangular HDR
(row 0 = up, image centre = -z, dermis.environment's convention) with a warm soft box to the
upper left front, a cool sky above, a dim floor bounce and a faint rim from behind on the right.
Run from anywhere: python examples/reference/make_environment.py"""

from pathlib import Path

import numpy as np

from dermis.environment import equirect_directions
from dermis.images import write_exr


def lobe(d, axis, sharpness):
    a = np.asarray(axis, np.float64)
    a /= np.linalg.norm(a)
    return np.exp(sharpness * (d @ a - 1.0))


def studio(h=64, w=128):
    d, _ = equirect_directions(h, w)
    y = d[..., 1]
    sky = np.clip(y, 0, 1)[..., None] * np.array([0.10, 0.13, 0.18])
    floor = np.clip(-y, 0, 1)[..., None] * np.array([0.05, 0.04, 0.035])
    key = lobe(d, (-0.5, 0.45, 0.75), 12.0)[..., None] * np.array([2.6, 2.2, 1.8])  # from the upper left front
    rim = lobe(d, (0.8, 0.2, -0.6), 20.0)[..., None] * np.array([0.9, 1.0, 1.2])
    return (0.02 + sky + floor + key + rim).astype(np.float32)


if __name__ == "__main__":
    out = Path(__file__).resolve().parent / "studio.exr"
    write_exr(out, studio())
    print(f"wrote {out}")
