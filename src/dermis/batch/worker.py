"""One batch worker: a GL context and a Renderer kept across renders (shaders compile once per
technique), base scenes loaded once, environment maps cached.

A worker never writes into the dataset: it returns each render's metadata row and its encoded
files as bytes, and the driver writes them (one writer, atomic files, works on a cluster without
a shared file system). Any error in a render becomes a row with status "failed" and its one-line
error; the worker goes on with the next.
"""

from __future__ import annotations

import hashlib
import os
import socket
import tempfile
import time
from pathlib import Path

import numpy as np

from dermis.errors import DermisError
from dermis.framing import framed_camera

DEFAULT_SIZE = "512x512"


def one_line(exc: BaseException) -> str:
    """An exception as one line: DermisError's own message, else 'Type: first line'."""
    if isinstance(exc, DermisError):
        return str(exc)
    text = str(exc).strip().splitlines()
    return f"{type(exc).__name__}: {text[0]}" if text else type(exc).__name__


def file_stem(index: int, render_id: str) -> str:
    return f"{index:06d}_{render_id}"


def output_paths(index: int, render_id: str, outputs) -> dict:
    """Dataset-relative paths of a render's files, by output kind."""
    stem = file_stem(index, render_id)
    where = {"png": f"images/{stem}.png", "exr": f"linear/{stem}.exr", "mask": f"mask/{stem}.png",
             "depth": f"depth/{stem}.exr"}
    return {k: where[k] for k in outputs}


def depth_map(scene, camera, size, bvh) -> np.ndarray:
    """Distance along the camera's view axis to the first surface through each pixel centre, in
    mm (scene units x mm_per_unit); 0 where the ray misses the mesh. Ray cast on the CPU through
    dermis.geometry.raycast's Embree ray caster with the renderer's own camera matrices (dermis.camera)."""
    from dermis.camera import camera_matrices

    w, h = size
    lo, hi = scene.bounds()
    view, proj, eye, _, _ = camera_matrices(camera, w / h, lo, hi)
    x = (np.arange(w) + 0.5) / w * 2.0 - 1.0
    y = 1.0 - (np.arange(h) + 0.5) / h * 2.0  # row 0 = top of the image
    xx, yy = np.meshgrid(x / proj[0, 0], y / proj[1, 1])
    d_view = np.stack([xx, yy, -np.ones_like(xx)], -1).reshape(-1, 3)  # view space, z = -1
    rot = view[:3, :3]  # world -> view rotation; its transpose takes view directions to world
    d_world = d_view @ rot
    t, tri, _ = bvh.closest_hit(np.broadcast_to(eye, d_world.shape), d_world)
    # with the view-space direction's z = -1, the ray parameter t IS the depth along the view axis
    depth = np.where(tri >= 0, t, 0.0) * scene.mm_per_unit
    return depth.reshape(h, w).astype(np.float32)


class RenderWorker:
    """Renders RenderSpecs of one sweep. ``config``: see :func:`worker_config`."""

    def __init__(self, config: dict):
        t0 = time.perf_counter()
        if config.get("lp_num_threads") and "LP_NUM_THREADS" not in os.environ:
            # llvmpipe's rasteriser threads per worker (read when the context is made): N workers
            # on N cores each get one instead of all fighting over every core
            os.environ["LP_NUM_THREADS"] = str(config["lp_num_threads"])
        from dermis.renderer import Renderer

        self.config = config
        self.folder = Path(config["folder"])
        self.outputs = tuple(config["outputs"])
        self.renderer = Renderer(None, (64, 64), device=config.get("device"), samples=config["samples"],
                                 shadow_size=config["shadow_size"], irradiance_size=config["irradiance_size"])
        self.gl_renderer = self.renderer.info["renderer"]
        self.name = f"{socket.gethostname()}:{os.getpid()}"
        self._scenes = {}
        self._bvh = {}
        self._env = {}
        self._tmp = tempfile.TemporaryDirectory(prefix="dermis-batch-")
        import dermis

        self.version = dermis.__version__
        self.startup_s = time.perf_counter() - t0

    def info(self) -> dict:
        return {"worker": self.name, "gl_renderer": self.gl_renderer, "startup_s": self.startup_s, "pid": os.getpid()}

    # ---------------------------------------------------------------- cached inputs
    def _state(self, name: str):
        from dermis.batch.apply import SceneState
        from dermis.batch.sweep import DEFAULT_SCENE

        if name not in self._scenes:
            import dermis

            scene = dermis.default_scene() if name == DEFAULT_SCENE else dermis.load_scene(self.folder / name)
            self._scenes[name] = SceneState(scene)
        return self._scenes[name]

    def _environment(self, source):
        """The equirect Texture of a sweep path (read once, then the same object) or a scene's own
        Texture. The sweep's rotation is set on the scene's environment (``rotation_deg``), not
        baked into a copy of the image."""
        from dermis.images import as_rgb, read_image
        from dermis.scene.model import Texture

        if not isinstance(source, str):
            return source
        if source not in self._env:
            path = self.folder / source
            self._env[source] = Texture(as_rgb(read_image(path, srgb=True)), str(path))
        return self._env[source]

    def _encode(self, name: str, write) -> bytes:
        path = Path(self._tmp.name) / name
        write(path)
        data = path.read_bytes()
        path.unlink()
        return data

    # ---------------------------------------------------------------- one render
    def render(self, spec) -> tuple[dict, dict]:
        """(metadata row, {dataset-relative path: file bytes}) of one render."""
        from dermis.batch.apply import apply_parameters
        from dermis.cli import parse_size
        from dermis.images import write_exr, write_png
        from dermis.output import output_transform

        t0, c0 = time.perf_counter(), time.process_time()
        params = spec.params
        row = {"render_id": spec.render_id, "index": spec.index, "status": "failed", "error": None,
               **{k: v for k, v in params.items()}, "worker": self.name, "gl_renderer": self.gl_renderer,
               "dermis_version": self.version}
        files = {}
        try:
            size = parse_size(params.get("size") or DEFAULT_SIZE, "size")
            row["width"], row["height"] = size
            state = self._state(params["scene"])
            scene = state.scene
            if self.renderer.scene is not scene:
                self.renderer.set_scene(scene)
            derived = apply_parameters(state, params, light_indices=self.config["lights"], folder=self.folder,
                                       source=f"{self.config['source']}: render {spec.index}",
                                       environment_image=self._environment)
            row.update(derived)
            row["technique"] = scene.technique
            rgba = self.renderer.render(None, size, with_alpha=True)
            row["render_ms"] = float(self.renderer.stats["frame_ms"])
            img = np.ascontiguousarray(rgba[:, :, :3])
            if not np.isfinite(img).all():
                raise DermisError("the render produced NaN or infinite values")
            o = scene.output
            paths = output_paths(spec.index, spec.render_id, self.outputs)
            display = output_transform(img, o.exposure, o.tonemap, o.bloom, o.bloom_radius)
            files[paths["png"]] = self._encode("image.png", lambda p: write_png(p, display))
            if "exr" in paths:
                files[paths["exr"]] = self._encode("linear.exr", lambda p: write_exr(p, img))
            if "mask" in paths:
                # coverage of the mesh (the resolved MSAA alpha), as 8-bit grey
                mask = np.repeat(np.clip(rgba[:, :, 3:4], 0.0, 1.0), 3, axis=2)
                files[paths["mask"]] = self._encode("mask.png", lambda p: write_png(p, mask))
            if "depth" in paths:
                depth = depth_map(scene, framed_camera(scene.camera, scene.mesh, size[0] / size[1]), size,
                                  self._mesh_bvh(scene))
                files[paths["depth"]] = self._encode("depth.exr", lambda p: write_exr(p, np.repeat(depth[:, :, None], 3, axis=2)))
            row.update({k: v for k, v in paths.items()})
            row["png_sha256"] = hashlib.sha256(files[paths["png"]]).hexdigest()
            row["status"] = "ok"
        except Exception as exc:  # recorded in the table; the batch goes on
            files = {}
            row["error"] = one_line(exc)
        row["total_ms"] = (time.perf_counter() - t0) * 1e3
        # CPU time of the whole worker process (llvmpipe's rasteriser threads included): what a
        # render costs in core-seconds, whatever else the machine is running
        row["cpu_ms"] = (time.process_time() - c0) * 1e3
        row["finished_utc"] = time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime())
        return row, files

    def _mesh_bvh(self, scene):
        from dermis.geometry.raycast import RayCaster

        key = id(scene.mesh)
        if key not in self._bvh:
            self._bvh[key] = (scene.mesh, RayCaster(scene.mesh.positions, scene.mesh.indices))
        return self._bvh[key][1]

    def close(self):
        self.renderer.release()
        self._tmp.cleanup()


def worker_config(sweep, device=None, lp_num_threads=None) -> dict:
    """What a worker needs of a sweep (plain data: it crosses process and machine boundaries)."""
    return {"folder": str(sweep.folder), "outputs": list(sweep.outputs), "lights": sweep.lights,
            "source": str(sweep.path), "device": device, "lp_num_threads": lp_num_threads, **sweep.renderer_options()}
