"""``dermis bench``: frame times of every technique on the real head, as ratios to ``lambert``
measured in one run (absolute times depend on the machine and its load; ratios much less).

Two workloads per technique, the same for all:
- lights moving: the key light turns a little every frame, so shadow maps and every
  view-independent (texture-space) pass re-run;
- camera moving: the camera orbits, lights fixed: texture-space results are reused.
"""

from __future__ import annotations

import json
import math
import platform
import statistics
import time
from pathlib import Path

import click
import numpy as np

from dermis.errors import DermisError
from dermis.gl.context import rasteriser_ns

HEAD_TOML = Path(__file__).resolve().parents[2] / "examples" / "lee-perry-smith.toml"


def _rotate(v, angle):
    c, s = math.cos(angle), math.sin(angle)
    x, y, z = v
    return (c * x + s * z, y, -s * x + c * z)


class GpuBusyClock:
    """GPU time of a run of frames submitted back to back, read only after all were submitted.

    On a GPU: one GL_TIME_ELAPSED query around each whole frame (nothing else queried meanwhile:
    the pass timer is off), read after the last frame. A query counts from the moment the GPU
    reaches the frame's first command to its last, so where the CPU submits slower than the GPU
    draws, the GPU's waits inside the frame are counted too: then it is the CPU's submit time.
    On Mesa's CPU rasteriser (timer queries unreliable there, see PassTimer) the "GPU" is
    llvmpipe's rasteriser threads: their run time (/proc/self/task/*/schedstat, ns) over the run,
    divided by their number, i.e. how long they were busy per frame if evenly loaded (a lower
    bound: llvmpipe's vertex processing and setup run in the calling thread, not counted)."""

    def __init__(self, ctx, frames: int):
        from dermis.gl.context import is_software

        self.ctx = ctx
        self.software = is_software(ctx)
        self.queries = [] if self.software else [ctx.query(time=True) for _ in range(frames)]
        self._start = None

    def start(self):
        if self.software:
            self._start = rasteriser_ns()[0]

    def frame(self, i: int):
        """Context manager around frame i's submission (a query on a GPU; nothing on llvmpipe)."""
        if self.software:
            from contextlib import nullcontext

            return nullcontext()
        return self.queries[i]

    def ms_per_frame(self, frames: int) -> float:
        """After ctx.finish(): the GPU ms per frame (mean)."""
        if self.software:
            total, n = rasteriser_ns()
            return (total - self._start) / 1e6 / max(n, 1) / frames
        ms = [q.elapsed / 1e6 for q in self.queries[:frames]]
        return sum(ms) / len(ms)

    def release(self):
        self.queries = []  # moderngl's Query has no release(); the context frees them with itself


def pipelined(renderer, technique: str, step, frames: int) -> dict:
    """``frames`` frames of ``technique`` back to back, as a viewer draws them: ``step(f)`` moves
    the scene before frame f, the pass timer is off (no per-pass queries or finishes), nothing is
    read back between frames and the GPU is waited for once, after the last. Returns ms per frame:
    ``gpu_ms`` (GpuBusyClock), ``throughput_ms`` (wall time of all frames and the one finish /
    frames: CPU and GPU together, overlapped as far as the driver lets them) and ``readback_ms``
    (one extra frame's read back alone: the GPU->CPU copy, the row flip and the finite check)."""
    r, ctx = renderer, renderer.ctx
    timing = r.timer.enabled
    r.timer.enabled = False
    clock = GpuBusyClock(ctx, frames)
    try:
        step(-1)
        r.render(technique, readback=False)  # the first frame after a change of workload: warm
        ctx.finish()
        clock.start()
        t0 = time.perf_counter()
        for f in range(frames):
            step(f)
            with clock.frame(f):
                r.render(technique, readback=False)
        ctx.finish()
        wall = (time.perf_counter() - t0) * 1e3 / frames
        gpu = clock.ms_per_frame(frames)
        t1 = time.perf_counter()
        r.read_frame()
        readback = (time.perf_counter() - t1) * 1e3
    finally:
        r.timer.enabled = timing
        clock.release()
    return {"frames": frames, "gpu_ms": gpu, "throughput_ms": wall, "readback_ms": readback,
            "gpu_clock": "llvmpipe rasteriser threads" if clock.software else "GL_TIME_ELAPSED per frame"}


# floor samples per sampling point (before the first technique, after every workload's frames)
FLOOR_REPEATS = 2


def run_bench(scene, techniques, size=(1024, 1024), irradiance_size=1024, frames=5, progress=None, device=None,
              floors: bool = True, pipelined_frames: int = 10):
    """Median frame and pass times per technique and workload; with ``floors``, also the floors of
    dermis.bench_floors measured on the same renderer, sampled ``FLOOR_REPEATS`` times before the
    first technique and after every workload's frames, and once after every timed frame (so the
    samples span the run's load; a frame's own pass times are taken before its floor sample):
    ``info["floors_ms"]`` is each floor's minimum (the divisor; dermis.bench_floors.floor_summary
    says why), ``info["floors_spread"]`` its min/median/max/n/spread and ``info["floor_samples_ms"]``
    the samples; with ``pipelined_frames``, also each workload's frames back to back
    (:func:`pipelined`: ``results[technique]["pipelined"][workload]``)."""
    from dermis.bench_floors import FloorSampler, floor_summary, stable_floors
    from dermis.renderer import Renderer

    results = {}
    with Renderer(scene, size, irradiance_size=irradiance_size, device=device) as r:
        info = dict(r.info)
        r.timer.cpu = True  # on llvmpipe each pass's CPU-time clock too (passes_cpu_ms); nothing on a GPU
        sampler = FloorSampler(r, irradiance_size) if floors else None
        sample_floors = sampler.sample if sampler else (lambda repeats: None)
        sample_floors(FLOOR_REPEATS)
        base_light = [tuple(L.direction) for L in scene.lights]
        base_cam = tuple(scene.camera.position)
        target = np.asarray(scene.camera.target, float)
        for name in techniques:
            r.render(name)  # compile, first-frame work (stretch map etc.)
            res = {}
            for mode in ("lights", "camera"):
                times, passes, cpu = [], {}, {}

                def step(f, mode=mode):
                    if mode == "lights":
                        for L, d in zip(scene.lights, base_light):
                            L.direction = _rotate(d, 0.02 * (f + 1))
                    else:
                        off = np.asarray(base_cam, float) - target
                        scene.camera.position = tuple(target + np.asarray(_rotate(off, 0.03 * (f + 1))))
                for f in range(frames):
                    step(f)
                    r.render(name)
                    times.append(r.stats["frame_ms"])
                    for k, v in r.stats["passes_ms"].items():
                        passes.setdefault(k, []).append(v)
                    for k, v in r.stats.get("passes_cpu_ms", {}).items():
                        cpu.setdefault(k, []).append(v)
                    sample_floors(1)  # after every frame too: more chances at a quiet moment for the minimum
                    if progress:
                        progress()
                sample_floors(FLOOR_REPEATS)  # after this workload's frames (= before the next's)
                for L, d in zip(scene.lights, base_light):
                    L.direction = d
                scene.camera.position = base_cam
                res[mode] = {"frame_ms": statistics.median(times),
                             "passes_ms": {k: statistics.median(v) for k, v in passes.items()},
                             # each pass's fastest frame: like with like against the floors' minimum
                             "passes_min_ms": {k: min(v) for k, v in passes.items()},
                             **({"passes_cpu_ms": {k: statistics.median(v) for k, v in cpu.items()}} if cpu else {}),
                             "passes_run": list(r.stats["passes_run"])}
                if pipelined_frames > 0:
                    res.setdefault("pipelined", {})[mode] = pipelined(r, name, step, pipelined_frames)
                    for L, d in zip(scene.lights, base_light):
                        L.direction = d
                    scene.camera.position = base_cam
            results[name] = res
        if sampler:
            # the wall clock's samples, and on llvmpipe the same samples on the CPU-time clock ("_cpu")
            clocks = [("", sampler.samples_ms)] + ([("_cpu", sampler.samples_cpu_ms)] if sampler.timer.cpu else [])
            for c, samples in clocks:
                info[f"floors{c}_ms"] = stable_floors(samples)
                info[f"floors{c}_spread"] = floor_summary(samples)
                info[f"floor_samples{c}_ms"] = {k: list(v) for k, v in samples.items()}
            sampler.release()
    return info, results


def markdown_table(info, results, size, irradiance_size, gaussians: int = 6):
    base = results.get("lambert")
    lines = [f"Renderer: {info['renderer']} ({info['version']}); output {size[0]}x{size[1]}, irradiance {irradiance_size}^2; "
             f"machine: {platform.machine()}, {platform.system()}, Python {platform.python_version()}", "",
             "| technique | lights moving (ms) | ratio to lambert | camera moving (ms) | ratio to lambert | passes (lights moving, ms) |",
             "|---|---|---|---|---|---|"]
    for name, res in results.items():
        lm, cm = res["lights"]["frame_ms"], res["camera"]["frame_ms"]
        rl = f"{lm / base['lights']['frame_ms']:.2f}x" if base else "-"
        rc = f"{cm / base['camera']['frame_ms']:.2f}x" if base else "-"
        passes = ", ".join(f"{k} {v:.0f}" for k, v in res["lights"]["passes_ms"].items())
        lines.append(f"| {name} | {lm:.0f} | {rl} | {cm:.0f} | {rc} | {passes} |")
    piped = {name: res["pipelined"] for name, res in results.items() if res.get("pipelined")}
    if piped:
        first = next(iter(piped.values()))
        n, clock = next(iter(first.values()))["frames"], next(iter(first.values()))["gpu_clock"]
        lines += ["", f"Pipelined frames ({n} back to back per workload as a viewer draws them: pass timer off, nothing read "
                  f"back between frames, one finish at the end; GPU ms per frame from {clock}; throughput = wall time / "
                  f"frames, CPU and GPU together; readback = one frame's read back alone):", "",
                  "| technique | lights moving: GPU ms/frame | lights moving: throughput ms/frame | "
                  "camera moving: GPU ms/frame | camera moving: throughput ms/frame | readback (ms) |",
                  "|---|---|---|---|---|---|"]
        for name, p in piped.items():
            lm, cm = p.get("lights", {}), p.get("camera", {})
            cell = lambda d, k: f"{d[k]:.2f}" if k in d else "-"  # noqa: E731
            lines.append(f"| {name} | {cell(lm, 'gpu_ms')} | {cell(lm, 'throughput_ms')} | {cell(cm, 'gpu_ms')} | "
                         f"{cell(cm, 'throughput_ms')} | {cell(lm or cm, 'readback_ms')} |")
    floors = info.get("floors_ms")
    if floors:
        spread = info.get("floors_spread") or {}
        lines += ["", "Floors (ms, same run, dermis.bench_floors; each the minimum of its samples interleaved with the "
                  "techniques [median, max, samples]; the multiples divide by the minimum): " +
                  ", ".join(f"{k} {v:.2f}" + (f" [{spread[k]['median']:.2f}, {spread[k]['max']:.2f}, n={spread[k]['n']}]"
                                              if k in spread else "") for k, v in floors.items()), "",
                  "| technique | pass | ms (lights moving) | floor (ms) | multiple of floor | "
                  "pass minimum (ms) | minimum / floor | CPU ms | CPU floor (ms) | CPU multiple |",
                  "|---|---|---|---|---|---|---|---|---|---|"]
        cpu_floors = info.get("floors_cpu_ms")
        for name, res in results.items():
            fastest = floor_ratios(res["lights"].get("passes_min_ms", {}), floors, gaussians)
            on_cpu = floor_ratios(res["lights"].get("passes_cpu_ms", {}), cpu_floors, gaussians) if cpu_floors else {}
            for k, v in floor_ratios(res["lights"]["passes_ms"], floors, gaussians).items():
                lo = f"{fastest[k][0]:.1f} | {fastest[k][2]:.2f}x" if k in fastest else "- | -"
                c = f"{on_cpu[k][0]:.1f} | {on_cpu[k][1]:.1f} | {on_cpu[k][2]:.2f}x" if k in on_cpu else "- | - | -"
                lines.append(f"| {name} | {k} | {v[0]:.1f} | {v[1]:.1f} | {v[2]:.2f}x | {lo} | {c} |")
        if cpu_floors:
            lines += ["", "CPU ms (llvmpipe): the rasteriser threads' run time / their number + the calling thread's "
                      "CPU time (dermis.gl.context.cpu_busy_ns), which does not grow while another process holds a "
                      "core; CPU floors are the same samples' minima on that clock."]
    return "\n".join(lines)


def floor_ratios(passes_ms: dict, floors: dict, gaussians: int) -> dict:
    """{pass: (ms, floor ms, multiple)} for the passes that have a floor."""
    from dermis.bench_floors import pass_floor

    out = {}
    for k, v in passes_ms.items():
        f = pass_floor(k, floors, gaussians)
        if f:
            out[k] = (v, f, v / f)
    return out


@click.command("bench")
@click.argument("scene", required=False)
@click.option("--techniques", default=None, help="Comma-separated (default: all available).")
@click.option("--size", default="1024x1024", show_default=True)
@click.option("--irradiance-size", type=int, default=None,
              help="Texture-space resolution (default 1024; with --viewer the viewer's own choice from the head's size "
                   "on screen, dermis.adaptive_resolution).")
@click.option("--frames", type=int, default=5, show_default=True, help="Timed frames per workload (median).")
@click.option("--pipelined-frames", type=click.IntRange(0, 10000), default=10, show_default=True,
              help="Also this many frames per workload back to back without per-pass timing or readback "
                   "(GPU ms and throughput per frame; 0: off).")
@click.option("--json", "json_out", default=None, help="Write the results as JSON.")
@click.option("--markdown", default=None, help="Write the table as Markdown.")
@click.option("--accuracy/--no-accuracy", default=True, help="Also measure tsd's impulse error with and without reduced-resolution blurs.")
@click.option("--device", type=int, default=None)
@click.option("--viewer", is_flag=True, help="Measure the interactive viewer instead (a scripted session in a real "
              "window, 960x640 unless --size is given; needs a display: xvfb-run -a dermis bench --viewer).")
def bench_cmd(scene, techniques, size, irradiance_size, frames, pipelined_frames, json_out, markdown, accuracy, device,
              viewer):
    """Time every technique on the real head (default) relative to lambert."""
    import dermis
    import dermis.verification
    from dermis.cli import parse_size, write_json_atomic
    from dermis.techniques import technique_names

    path = scene or HEAD_TOML
    if scene is None and not Path(path).is_file():
        raise DermisError(f"{path}: the benchmark scene is missing")
    if viewer:
        w, h = parse_size(size) if size != "1024x1024" else (960, 640)
        table, data = viewer_table(path, (w, h), irradiance_size)
        click.echo(table)
        if json_out:
            write_json_atomic(json_out, data)
        if markdown:
            from dermis.images import atomic_write

            atomic_write(markdown, lambda tmp: Path(tmp).write_text(table + "\n"))
        return
    w, h = parse_size(size)
    irradiance_size = irradiance_size or 1024
    sc = dermis.load_scene(path)
    names = techniques.split(",") if techniques else technique_names()
    if "lambert" not in names:
        names = ["lambert"] + names
    from tqdm import tqdm

    with tqdm(total=len(names) * 2 * frames, desc="bench", unit="frame") as bar:
        info, results = run_bench(sc, names, (w, h), irradiance_size, frames, progress=bar.update, device=device,
                                  pipelined_frames=pipelined_frames)
    table = markdown_table(info, results, (w, h), irradiance_size, gaussians=sc.profile.k)
    click.echo(table)
    extra = {}
    if accuracy and "tsd" in names:
        full = dermis.verification.impulse_error(multires=False)
        multi = dermis.verification.impulse_error(multires=True)
        extra = {"impulse_error_full_res": full.tolist(), "impulse_error_multires": multi.tolist()}
        click.echo(f"\ntsd impulse response, r-weighted L2 error per channel (RGB): full-resolution blurs "
                   f"{np.round(full * 100, 3).tolist()} %, reduced-resolution wide blurs {np.round(multi * 100, 3).tolist()} %")
    if json_out:
        write_json_atomic(json_out, {"info": info, "size": [w, h], "irradiance_size": irradiance_size,
                                     "results": results, **extra})
    if markdown:
        from dermis.images import atomic_write

        text = table + ("\n\n" + json.dumps(extra) if extra else "") + "\n"
        atomic_write(markdown, lambda tmp: Path(tmp).write_text(text))


def viewer_table(path, size, irradiance_size):
    """The viewer bench with progressive rendering on and off, in one run."""
    import dermis
    from dermis.viewer.bench import viewer_bench

    runs = {}
    for progressive in (True, False):
        runs["progressive" if progressive else "full every frame"] = viewer_bench(
            dermis.load_scene(path), size, irradiance_size=irradiance_size, progressive=progressive)
    first = next(iter(runs.values()))
    irr = irradiance_size or f"{first.get('irradiance_size', '?')} (adaptive)"
    lines = [f"Viewer: {first['renderer']}; window {size[0]}x{size[1]}, irradiance {irr}^2, tsd, panel on", "",
             "| mode | orbit fps | light drag fps | full quality after orbit (ms) | after light drag (ms) "
             "| after a key or slider instead (ms) |",
             "|---|---|---|---|---|---|"]
    for name, r in runs.items():
        wait = r.get("refine_wait_after_keys_ms", 0.0)
        lines.append(f"| {name} | {r['orbit']['fps']:.1f} | {r['light_drag']['fps']:.1f} | "
                     f"{r['full_after_orbit_ms']:.0f} | {r['full_after_light_ms']:.0f} | "
                     f"{r['full_after_light_ms'] + wait:.0f} |")
    lines += ["", "A drag refines when its mouse button is released; keys and panel sliders refine "
              "after no input for dermis.viewer.progressive.REFINE_AFTER_S."]
    return "\n".join(lines), runs
