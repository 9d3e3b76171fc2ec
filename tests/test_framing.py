"""Framing: [camera] fit = true fits the mesh (a bust: its head) in view."""

from __future__ import annotations

from pathlib import Path

import numpy as np

import dermis
from dermis.camera import camera_matrices
from dermis.framing import fit_camera, head_vertices
from dermis.renderer import Renderer
from dermis.scene.model import Camera

REPO = Path(__file__).resolve().parent.parent


def _ndc(camera, points, aspect):
    lo, hi = points.min(axis=0), points.max(axis=0)
    view, proj, *_ = camera_matrices(camera, aspect, lo, hi)
    q = np.c_[points, np.ones(len(points))] @ (proj @ view).T
    return q[:, :2] / q[:, 3:4]


def test_fit_camera_puts_every_vertex_in_view_touching_the_margin():
    rng = np.random.default_rng(1)
    pts = rng.normal(size=(2000, 3)) * [3.0, 1.0, 0.5] + [5.0, -2.0, 1.0]
    for aspect in (0.5, 1.0, 2.0):
        cam = Camera(position=(1.0, 3.0, 20.0), target=(0.0, 0.0, 0.0), fov_deg=30.0, fit=True)
        fitted = fit_camera(cam, pts, aspect, margin=0.04)
        # direction kept
        d0 = np.subtract(cam.target, cam.position)
        d1 = np.subtract(fitted.target, fitted.position)
        assert np.allclose(d0 / np.linalg.norm(d0), d1 / np.linalg.norm(d1))
        ndc = _ndc(fitted, pts, aspect)
        assert np.abs(ndc).max() <= 0.96 + 1e-6
        assert np.abs(ndc).max() > 0.95  # tight on the limiting axis


def test_example_head_is_framed_uncropped(example_head_toml, gl_ctx):
    """examples/lee-perry-smith.toml (fit = true): no head pixel on the image's top row or side
    columns, and the head fills the height (top of the skull within 6% of the top edge)."""
    sc = dermis.load_scene(example_head_toml)
    assert sc.camera.fit
    with Renderer(sc, (96, 96), ctx=gl_ctx, samples=0) as r:
        a = r.render("lambert", with_alpha=True)[:, :, 3] > 0.5
    assert not a[0].any() and not a[:, 0].any() and not a[:, -1].any()
    first = np.argmax(a.any(axis=1))
    assert first <= 0.06 * 96


def test_head_vertices_cuts_a_bust_at_the_neck():
    """A sphere (head) on a thin cylinder (neck) on a wide box (shoulders): the head's vertices."""
    rng = np.random.default_rng(0)
    head = rng.normal(size=(3000, 3))
    head = head / np.linalg.norm(head, axis=1, keepdims=True) * 1.0 + [0, 3.0, 0]
    t = rng.uniform(0, 2 * np.pi, 600)
    neck = np.c_[0.4 * np.cos(t), rng.uniform(1.2, 2.2, 600), 0.4 * np.sin(t)]
    shoulders = rng.uniform([-3, 0, -1], [3, 1.2, 1], size=(3000, 3))
    pts = np.r_[head, neck, shoulders]
    kept = head_vertices(pts)
    assert kept[:, 1].min() > 1.2 and kept[:, 1].max() == pts[:, 1].max()
    assert len(head_vertices(head)) == len(head)  # no neck: all vertices
