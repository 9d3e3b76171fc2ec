"""Where renders run: local worker processes, or Ray actors (one machine or a cluster).

Both keep a :class:`~dermis.batch.worker.RenderWorker` alive per worker (its GL context, its
Renderer with compiled shaders, loaded scenes) and give each worker at most two renders at a
time (one rendering, one waiting), so the driver can stop quickly and knows which renders a
worker that dies was holding: those are recorded as failed, a new worker replaces it, and the
batch goes on. The interface the driver (dermis.batch.run) uses:

    start() -> dict              start-up info (seconds, one entry per worker)
    has_slot() / submit(spec)    hand out a render
    busy() -> bool               renders in flight
    results(timeout) -> list     finished (spec, row, files) triples
    close(abort)                 stop the workers (abort: now, dropping renders in flight)
"""

from __future__ import annotations

import os
import signal
import time

from dermis.errors import DermisError

PER_WORKER = 2
INSTALL_RAY = "--ray: Ray is not installed; install it with pip install 'dermis[ray]' (or pip install 'ray>=2.9')"


def failed_row(spec, error: str) -> dict:
    """The row of a render whose worker never answered (the worker's own failures it writes itself)."""
    return {"render_id": spec.render_id, "index": spec.index, "status": "failed", "error": error, **spec.params,
            "finished_utc": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime())}


def llvmpipe_threads(workers: int) -> int:
    """Rasteriser threads per worker for Mesa's llvmpipe: the cores shared out (>= 1)."""
    return max(1, (os.cpu_count() or 1) // max(1, workers))


# ------------------------------------------------------------------------------------ local
def _local_worker(conn, config):
    """A worker process: Ctrl-C is the driver's to handle (it stops the workers itself)."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    from dermis.batch.worker import RenderWorker, one_line

    try:
        worker = RenderWorker(config)
    except Exception as exc:
        conn.send(("error", one_line(exc)))
        return
    conn.send(("ready", worker.info()))
    while True:
        try:
            spec = conn.recv()
        except EOFError:
            break
        if spec is None:
            break
        row, files = worker.render(spec)
        conn.send(("result", spec.index, row, files))
    worker.close()


class LocalExecutor:
    """Worker processes on this machine (multiprocessing, spawned: each makes its own context)."""

    kind = "local"

    def __init__(self, config: dict, workers: int):
        import multiprocessing

        self.config = dict(config)
        self.workers = int(workers)
        if self.workers < 1:
            raise DermisError(f"workers: must be >= 1, got {workers}")
        if self.config.get("lp_num_threads") is None:
            self.config["lp_num_threads"] = llvmpipe_threads(self.workers)
        self._mp = multiprocessing.get_context("spawn")
        self._slots = []  # per worker: {"process", "conn", "inflight": {index: spec}, "info"}

    def _spawn(self):
        parent, child = self._mp.Pipe()
        p = self._mp.Process(target=_local_worker, args=(child, self.config), daemon=True, name="dermis-batch-worker")
        p.start()
        child.close()
        return {"process": p, "conn": parent, "inflight": {}, "info": None}

    def _await_ready(self, slots):
        from multiprocessing.connection import wait

        waiting = {s["conn"]: s for s in slots}
        while waiting:
            for conn in wait(list(waiting)):
                slot = waiting.pop(conn)
                try:
                    kind, payload = conn.recv()
                except EOFError:
                    kind, payload = "error", f"exit code {slot['process'].exitcode}"
                if kind != "ready":
                    raise DermisError(f"a batch worker could not start: {payload}")
                slot["info"] = payload

    def start(self) -> dict:
        t0 = time.perf_counter()
        self._slots = [self._spawn() for _ in range(self.workers)]
        self._await_ready(self._slots)
        return {"executor": "local", "workers": self.workers, "startup_s": time.perf_counter() - t0,
                "worker_info": [s["info"] for s in self._slots]}

    def has_slot(self) -> bool:
        return any(len(s["inflight"]) < PER_WORKER for s in self._slots)

    def submit(self, spec):
        slot = min(self._slots, key=lambda s: len(s["inflight"]))
        slot["inflight"][spec.index] = spec
        slot["conn"].send(spec)

    def busy(self) -> bool:
        return any(s["inflight"] for s in self._slots)

    def results(self, timeout: float) -> list:
        from multiprocessing.connection import wait

        out = []
        conns = {s["conn"]: s for s in self._slots if s["inflight"]}
        for conn in wait(list(conns), timeout=timeout) if conns else []:
            slot = conns[conn]
            try:
                while conn.poll():
                    _, index, row, files = conn.recv()
                    out.append((slot["inflight"].pop(index), row, files))
            except (EOFError, OSError):
                # the process died (a driver crash, out of memory): its renders fail, a new one takes over
                slot["process"].join(timeout=5)
                code = slot["process"].exitcode
                for spec in slot["inflight"].values():
                    out.append((spec, failed_row(spec, f"the worker process exited (exit code {code}) during this render"), {}))
                i = self._slots.index(slot)
                self._slots[i] = self._spawn()
                self._await_ready([self._slots[i]])
        return out

    def close(self, abort: bool = False):
        for s in self._slots:
            try:
                if abort:
                    s["process"].terminate()
                else:
                    s["conn"].send(None)
            except (OSError, ValueError):
                pass
        for s in self._slots:
            s["process"].join(timeout=10 if not abort else 2)
            if s["process"].is_alive():
                s["process"].kill()
                s["process"].join()
            s["conn"].close()
        self._slots = []


# ------------------------------------------------------------------------------------ Ray
class RayRenderActor:
    """A RenderWorker inside a Ray actor; on a GPU node the actor's GPU is its EGL device."""

    def __init__(self, config: dict):
        import ray

        from dermis.batch.worker import RenderWorker
        from dermis.errors import GLUnavailableError

        config = dict(config)
        gpus = ray.get_gpu_ids()
        if gpus and config.get("device") is None and not os.environ.get("DERMIS_GL_DEVICE"):
            # Ray's GPU index, taken as the EGL device index (both count the node's GPUs)
            config["device"] = int(gpus[0])
        try:
            self.worker = RenderWorker(config)
        except GLUnavailableError:
            if config.get("device") is None or not gpus:
                raise
            config["device"] = None  # the driver may list only the visible GPU: take the default
            self.worker = RenderWorker(config)

    def info(self) -> dict:
        return self.worker.info()

    def render(self, spec):
        return self.worker.render(spec)


class RayExecutor:
    """Ray actors holding a RenderWorker. ``address``: "auto" starts (or joins) a Ray on this
    machine; anything else is a cluster address for ray.init (e.g. "ray://head:10001")."""

    kind = "ray"

    def __init__(self, config: dict, workers: int | None, address: str):
        try:
            import ray  # noqa: F401
        except ModuleNotFoundError:
            raise DermisError(INSTALL_RAY) from None
        self.config = dict(config)
        self.workers = workers
        self.address = address
        self._actors = []
        self._pending = {}  # ObjectRef -> (actor index, spec)
        self._started_ray = False

    def start(self) -> dict:
        import logging

        import ray

        t0 = time.perf_counter()
        if not ray.is_initialized():
            kwargs = {"logging_level": logging.WARNING, "log_to_driver": False}
            if self.address == "auto":
                kwargs["include_dashboard"] = False  # (only for a Ray this call starts)
                kwargs["runtime_env"] = {"env_vars": {"PYTHONPATH": os.environ.get("PYTHONPATH", "")}}
                if self.workers:
                    kwargs["num_cpus"] = max(self.workers, os.cpu_count() or 1)
                ray.init(**kwargs)
            else:
                try:
                    ray.init(address=self.address, **kwargs)
                except Exception as exc:
                    raise DermisError(f"ray: {self.address}: cannot connect ({str(exc).strip().splitlines()[0]})") from None
            self._started_ray = True
        t_init = time.perf_counter() - t0
        resources = ray.cluster_resources()
        gpus = int(resources.get("GPU", 0))
        n = self.workers or gpus or int(resources.get("CPU", 1))
        if n < 1:
            raise DermisError(f"workers: must be >= 1, got {n}")
        if self.address == "auto" and self.config.get("lp_num_threads") is None:
            self.config["lp_num_threads"] = llvmpipe_threads(n)
        options = {"num_gpus": 1, "num_cpus": 1} if gpus else {"num_cpus": 1}
        Actor = ray.remote(max_restarts=-1, max_task_retries=0, **options)(RayRenderActor)
        self._actors = [Actor.remote(self.config) for _ in range(n)]
        self._inflight = [0] * n
        try:
            infos = ray.get([a.info.remote() for a in self._actors])
        except ray.exceptions.RayError as exc:
            raise DermisError(f"a Ray batch worker could not start: {_ray_error(exc)}") from None
        return {"executor": "ray", "address": self.address, "workers": n, "gpus_per_actor": 1 if gpus else 0,
                "ray_init_s": t_init, "startup_s": time.perf_counter() - t0, "worker_info": infos}

    def has_slot(self) -> bool:
        return min(self._inflight) < PER_WORKER

    def submit(self, spec):
        i = min(range(len(self._actors)), key=lambda k: self._inflight[k])
        self._inflight[i] += 1
        self._pending[self._actors[i].render.remote(spec)] = (i, spec)

    def busy(self) -> bool:
        return bool(self._pending)

    def results(self, timeout: float) -> list:
        import ray

        if not self._pending:
            return []
        ready, _ = ray.wait(list(self._pending), num_returns=1, timeout=timeout)
        if ready:
            more, _ = ray.wait([r for r in self._pending if r not in ready], num_returns=len(self._pending) - len(ready),
                               timeout=0) if len(self._pending) > len(ready) else ([], [])
            ready = ready + more
        out = []
        for ref in ready:
            i, spec = self._pending.pop(ref)
            self._inflight[i] -= 1
            try:
                row, files = ray.get(ref)
            except ray.exceptions.RayError as exc:  # the actor died; Ray restarts it
                row, files = failed_row(spec, f"the Ray worker failed during this render: {_ray_error(exc)}"), {}
            out.append((spec, row, files))
        return out

    def close(self, abort: bool = False):
        import ray

        if not abort and self._pending:
            ray.wait(list(self._pending), num_returns=len(self._pending), timeout=30)
        for a in self._actors:
            ray.kill(a)
        self._actors, self._pending = [], {}
        if self._started_ray:
            ray.shutdown()


def _ray_error(exc) -> str:
    text = str(exc).strip().splitlines()
    return f"{type(exc).__name__}: {text[0]}" if text else type(exc).__name__
