"""The texel thickness bake (dermis.geometry.thickness): distance through the tissue behind each
texel of the texture-space layout along -N, and where the ray leaves it."""

from __future__ import annotations

import numpy as np
import pytest

from dermis.geometry.thickness import texel_thickness
from dermis.verification import backlit_slab_scene, quad_scene, texel_positions


@pytest.mark.parametrize("d", [0.5, 2.0, 5.0])
def test_slab_thickness_and_exit_point(d):
    """Front-face texels of a closed slab of thickness d (mm_per_unit 1): thickness d within
    1e-4 mm, and the exit (u, v) is the back-face point opposite (same x, y; z = -d/2) within a
    texel of the layout."""
    sc = backlit_slab_scene(d, size_mm=30.0)
    S = 256
    bake = texel_thickness(sc.mesh, S, sc.mm_per_unit)
    pos, cov = texel_positions(sc.mesh, S)
    front = cov & (np.abs(pos[..., 2] - d / 2) < 1e-6) & (np.abs(pos[..., 0]) < 12) & (np.abs(pos[..., 1]) < 12)
    assert front.sum() > 500
    assert np.all(bake[..., 3][front] == 1.0)
    np.testing.assert_allclose(bake[..., 2][front], d, atol=1e-4)
    # the exit point's position: the texel of the layout at the exit (u, v)
    u, v = bake[..., 0][front], bake[..., 1][front]
    rows = np.clip(((1.0 - v) * S).astype(int), 0, S - 1)
    cols = np.clip((u * S).astype(int), 0, S - 1)
    exit_pos = pos[rows, cols]
    texel_mm = 30.0 / (S / 3)  # the slab's faces each fill a third of the layout
    assert np.all(np.isfinite(exit_pos))
    np.testing.assert_allclose(exit_pos[:, 2], -d / 2, atol=1e-6)
    assert np.abs(exit_pos[:, :2] - pos[front][:, :2]).max() <= 1.5 * texel_mm


def test_thickness_in_mm_follows_the_scale():
    """The same slab at 2.5 mm per unit is 2.5 times as thick in mm (where both bakes hold: the
    slab's 30 mm width across its sides is past MAX_THICKNESS_MM at 2.5 mm per unit)."""
    sc = backlit_slab_scene(1.0)
    a = texel_thickness(sc.mesh, 128, 1.0)
    b = texel_thickness(sc.mesh, 128, 2.5)
    ok = (a[..., 3] > 0) & (b[..., 3] > 0)
    assert ok.sum() > 2500  # the front and back faces
    np.testing.assert_allclose(b[..., 2][ok], 2.5 * a[..., 2][ok], rtol=1e-6)


def test_open_surface_has_no_thickness():
    """A single quad has no far side: no texel holds a thickness (no light is transmitted)."""
    sc = quad_scene(20.0, 20.0)
    bake = texel_thickness(sc.mesh, 64, 1.0)
    assert not bake[..., 3].any()


def test_bake_is_kept_on_disk_and_read_back_as_made(gl_ctx, tmp_path, monkeypatch):
    """Every process that renders a mesh needs its thickness bake (0.55-0.8 s for the head at 512^2): it is
    kept in the disk cache and read back as made (tsd's image the same bits, the ray cast not run again),
    made again for another texture-space layout of the same mesh arrays, and not written with the cache off."""
    import dataclasses

    from dermis.geometry import thickness as T
    from dermis.gl import thickness as gl_thickness
    from dermis.renderer import Renderer

    monkeypatch.setenv("DERMIS_CACHE_DIR", str(tmp_path))
    monkeypatch.setattr(gl_thickness, "_BAKES", gl_thickness.OrderedDict())
    sc = backlit_slab_scene(1.0, fov_deg=30.0)

    def render(scene):
        gl_thickness._BAKES.clear()
        with Renderer(scene, (48, 48), ctx=gl_ctx, samples=0, irradiance_size=64) as r:
            img = r.render("tsd")
            assert "thickness" in r.stats["passes_run"]
            return img

    made = render(sc)
    files = list((tmp_path / "thickness").glob("*.npz"))
    assert len(files) == 1
    with monkeypatch.context() as m:
        m.setattr(T, "texel_thickness", lambda *a, **k: pytest.fail("baked again"))
        assert np.array_equal(render(sc), made) and made[..., 0].max() > 0.01
        # the same arrays with another texture-space layout (half the UV square): a bake of its own
        moved = dataclasses.replace(sc, mesh=dataclasses.replace(sc.mesh, texture_space_uvs=0.5 * np.asarray(sc.mesh.uvs)))
        with pytest.raises(pytest.fail.Exception, match="baked again"):
            render(moved)
    monkeypatch.setenv("DERMIS_CACHE_DIR", "off")
    render(moved)
    assert len(list((tmp_path / "thickness").glob("*.npz"))) == 1  # nothing more written with the cache off
