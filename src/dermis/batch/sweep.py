"""The sweep file (docs/batch.md): base scenes and the axes to vary, expanded to a render list.

A sweep is a TOML file with a [sweep] table (mode, seed, outputs, renderer settings) and an
[axes] table whose keys are parameter names (``camera.azimuth_deg``, ``skin.melanin``, ...).
``grid`` takes the Cartesian product of the axes' value lists (the first axis varies slowest);
``random`` makes ``count`` draws, draw i from its own generator seeded with (seed, i), so the
first draws stay the same when ``count`` grows. Every render gets an id: a hash of its
parameters, stable across runs and machines (what resume matches on).

Names and types are checked here, before anything renders; physical ranges (melanin in [0, 1],
a temperature in [1000, 40000] K, ...) are checked by the scene API when a render is set up, so a
bad value fails that render only, and the batch goes on.
"""

from __future__ import annotations

import hashlib
import itertools
import json
import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from dermis.errors import DermisError

DEFAULT_SCENE = "builtin:default"

# parameter name -> type ("float", "int", "str"); the order is the metadata table's column order
PARAMETERS = {
    "scene": "str",
    "technique": "str",
    "size": "str",
    "skin.profile": "str",
    "skin.melanin": "float",
    "skin.melanin_blend": "float",
    "skin.hemoglobin": "float",
    "skin.oxygenation": "float",
    "skin.epidermis_mm": "float",
    "skin.model": "str",
    "skin.gaussians": "int",
    "skin.color": "str",
    "lights.rotation_deg": "float",
    "lights.intensity": "float",
    "lights.temperature_k": "float",
    "environment.image": "str",
    "environment.rotation_deg": "float",
    "environment.intensity": "float",
    "camera.azimuth_deg": "float",
    "camera.elevation_deg": "float",
    "camera.distance": "float",
    "camera.fov_deg": "float",
}
OUTPUTS = ("png", "exr", "mask", "depth")
MODES = ("grid", "random")
DISTRIBUTIONS = {"grid": ("linspace",), "random": ("uniform", "loguniform")}
SWEEP_KEYS = {"name": str, "mode": str, "count": int, "seed": int, "outputs": list, "lights": (str, list),
              "irradiance_size": int, "shadow_size": int, "samples": int}


@dataclass
class Sweep:
    path: Path
    name: str
    mode: str
    axes: dict  # name -> list of values (grid), or a value list / distribution (random)
    seed: int = 0
    count: int = 0
    outputs: tuple = ("png",)
    lights: object = "all"  # "all" or the indices of the lights the lights.* axes change
    irradiance_size: int = 512
    shadow_size: int = 1024
    samples: int = 4
    document: dict = field(default_factory=dict)

    @property
    def folder(self) -> Path:
        return self.path.resolve().parent

    def identity(self) -> str:
        """What the dataset's renders depend on (the parsed sweep, not its comments)."""
        return json.dumps(self.document, sort_keys=True, default=str)

    def renderer_options(self) -> dict:
        return {"irradiance_size": self.irradiance_size, "shadow_size": self.shadow_size, "samples": self.samples}


@dataclass(frozen=True)
class RenderSpec:
    """One render: its place in the list, its id and its parameters (every name in PARAMETERS)."""

    index: int
    render_id: str
    params: dict


def _flatten(table: dict, prefix: str = "") -> dict:
    out = {}
    for key, value in table.items():
        name = f"{prefix}{key}"
        if isinstance(value, dict) and name not in PARAMETERS:
            out.update(_flatten(value, name + "."))
        else:
            out[name] = value
    return out


def _scalar(name: str, value, where: str):
    kind = PARAMETERS[name]
    if kind == "float":
        if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
            raise DermisError(f"{where}: {name} values must be finite numbers, got {value!r}")
        return float(value)
    if kind == "int":
        if isinstance(value, bool) or not isinstance(value, int):
            raise DermisError(f"{where}: {name} values must be integers, got {value!r}")
        return int(value)
    if name == "size" and isinstance(value, list):  # [w, h] is accepted as well as "WxH"
        if len(value) == 2 and all(isinstance(v, int) and not isinstance(v, bool) for v in value):
            value = f"{value[0]}x{value[1]}"
    if not isinstance(value, str) or not value.strip():
        raise DermisError(f"{where}: {name} values must be non-empty strings, got {value!r}")
    return value.strip()


def _axis(name: str, spec, mode: str, where: str):
    """An axis as a list of values (grid; random: drawn uniformly among them) or a distribution."""
    if isinstance(spec, dict):
        if len(spec) != 1:
            raise DermisError(f"{where}: {name} must be a list of values or one of "
                              f"{{{', '.join(k + ' = [...]' for k in DISTRIBUTIONS[mode])}}}, got {spec!r}")
        (kind, args), = spec.items()
        if kind not in DISTRIBUTIONS[mode]:
            raise DermisError(f"{where}: {name} = {{{kind} = ...}} is not available in mode = \"{mode}\" "
                              f"(use {', '.join(DISTRIBUTIONS[mode])} or a list of values)")
        if PARAMETERS[name] != "float":
            raise DermisError(f"{where}: {name} takes a list of values, not {kind}")
        if not isinstance(args, list) or not all(isinstance(a, (int, float)) and not isinstance(a, bool) for a in args):
            raise DermisError(f"{where}: {name} {kind} needs a list of numbers, got {args!r}")
        if kind == "linspace":
            if len(args) != 3 or not float(args[2]).is_integer() or args[2] < 1:
                raise DermisError(f"{where}: {name} linspace = [start, stop, count] with an integer count >= 1, got {args}")
            return [float(v) for v in np.linspace(args[0], args[1], int(args[2]))]
        if len(args) != 2 or not args[0] <= args[1] or not all(math.isfinite(a) for a in args):
            raise DermisError(f"{where}: {name} {kind} = [low, high] with low <= high, got {args}")
        if kind == "loguniform" and args[0] <= 0:
            raise DermisError(f"{where}: {name} loguniform needs low > 0, got {args}")
        return (kind, float(args[0]), float(args[1]))
    values = spec if isinstance(spec, list) and not (name == "size" and _is_size_pair(spec)) else [spec]
    if not values:
        raise DermisError(f"{where}: {name} has no values")
    return [_scalar(name, v, where) for v in values]


def _is_size_pair(v) -> bool:
    return len(v) == 2 and all(isinstance(x, int) and not isinstance(x, bool) for x in v)


def load_sweep(path) -> Sweep:
    """Parse and check a sweep file (names, types, distributions; not physical ranges)."""
    from dermis.scene.toml_scene import read_toml

    path = Path(path)
    doc = read_toml(path, "sweep")
    for key in doc:
        if key not in ("sweep", "axes"):
            raise DermisError(f"{path}: unknown table '{key}' (a sweep has [sweep] and [axes])")
        if not isinstance(doc[key], dict):
            raise DermisError(f"{path}: '{key}' must be a table [{key}]")
    head = doc.get("sweep", {})
    for key, value in head.items():
        if key not in SWEEP_KEYS:
            raise DermisError(f"{path}: unknown key '{key}' in [sweep] (known: {', '.join(SWEEP_KEYS)})")
        if isinstance(value, bool) or not isinstance(value, SWEEP_KEYS[key]):
            raise DermisError(f"{path}: [sweep] {key} has the wrong type ({value!r})")
    mode = head.get("mode", "grid")
    if mode not in MODES:
        raise DermisError(f"{path}: [sweep] mode must be grid or random, got '{mode}'")
    count = head.get("count", 0)
    if mode == "random" and count < 1:
        raise DermisError(f"{path}: [sweep] mode = \"random\" needs count >= 1")
    if mode == "grid" and "count" in head:
        raise DermisError(f"{path}: [sweep] count applies to mode = \"random\" only")
    outputs = head.get("outputs", ["png"])
    bad = [o for o in outputs if o not in OUTPUTS]
    if bad or "png" not in outputs:
        raise DermisError(f"{path}: [sweep] outputs must include \"png\" and be among {', '.join(OUTPUTS)}, got {outputs}")
    lights = head.get("lights", "all")
    if lights != "all" and not (isinstance(lights, list) and lights and all(isinstance(i, int) and not isinstance(i, bool)
                                                                            and i >= 0 for i in lights)):
        raise DermisError(f"{path}: [sweep] lights must be \"all\" or a list of light indices (0 = the first), got {lights!r}")
    settings = {k: head.get(k, d) for k, d in (("irradiance_size", 512), ("shadow_size", 1024), ("samples", 4))}
    for key, lo, hi in (("irradiance_size", 64, 8192), ("shadow_size", 128, 8192), ("samples", 0, 16)):
        if not lo <= settings[key] <= hi:
            raise DermisError(f"{path}: [sweep] {key} must be in [{lo}, {hi}], got {settings[key]}")

    axes = {}
    for name, spec in _flatten(doc.get("axes", {})).items():
        if name not in PARAMETERS:
            near = [p for p in PARAMETERS if p.split(".")[-1] == name.split(".")[-1]]
            hint = f" (did you mean '{near[0]}'?)" if near else ""
            raise DermisError(f"{path}: unknown axis '{name}' in [axes]{hint}")
        axes[name] = _axis(name, spec, mode, str(path))
    axes.setdefault("scene", [DEFAULT_SCENE])
    _check_values(axes, path)
    document = {"sweep": {**head, "mode": mode, "outputs": list(outputs)}, "axes": axes}
    return Sweep(path=path, name=head.get("name", path.stem), mode=mode, axes=axes, seed=int(head.get("seed", 0)),
                 count=int(count), outputs=tuple(outputs), lights=lights, document=document, **settings)


def _check_values(axes: dict, path: Path):
    """What is cheap to check before rendering: scene and environment files exist, technique
    names and sizes parse. (Each render's physical values are checked when it is set up.)"""
    from dermis.cli import parse_size
    from dermis.techniques import technique_names

    folder = path.resolve().parent
    names = technique_names()
    for value in _listed(axes.get("technique")):
        if value not in names:
            raise DermisError(f"{path}: technique '{value}' is unknown (available: {', '.join(names)})")
    for value in _listed(axes.get("size")):
        parse_size(value, f"{path}: size")
    for value in _listed(axes.get("scene")):
        if value != DEFAULT_SCENE and not (folder / value).is_file():
            raise DermisError(f"{path}: scene '{value}' not found (looked for {folder / value}; "
                              f"paths are relative to the sweep file, or use \"{DEFAULT_SCENE}\")")
    for value in _listed(axes.get("environment.image")):
        if value != "none" and not (folder / value).is_file():
            raise DermisError(f"{path}: environment.image '{value}' not found (looked for {folder / value})")


def _listed(axis) -> list:
    return axis if isinstance(axis, list) else []


def render_id(params: dict) -> str:
    """A render's identity: a hash of its parameters (JSON, keys sorted; floats as repr)."""
    text = json.dumps({k: v for k, v in params.items() if v is not None}, sort_keys=True)
    return hashlib.sha256(text.encode()).hexdigest()[:16]


def _draw(rng: np.random.Generator, axis):
    if isinstance(axis, list):
        return axis[int(rng.integers(len(axis)))]
    kind, lo, hi = axis
    if kind == "uniform":
        return float(rng.uniform(lo, hi))
    return float(math.exp(rng.uniform(math.log(lo), math.log(hi))))  # loguniform


def expand(sweep: Sweep) -> list[RenderSpec]:
    """The sweep's render list, in a deterministic order (grid: the axes in the file's order,
    the first varying slowest; random: draw 0, 1, ...)."""
    names = list(sweep.axes)
    combos = []
    if sweep.mode == "grid":
        for values in itertools.product(*(sweep.axes[n] for n in names)):
            combos.append(dict(zip(names, values)))
    else:
        for i in range(sweep.count):
            # one generator per draw, seeded by (seed, draw): draw i does not depend on count
            rng = np.random.default_rng([sweep.seed, i])
            combos.append({n: _draw(rng, sweep.axes[n]) for n in sorted(names)})
    specs = []
    seen = {}
    for i, combo in enumerate(combos):
        params = {name: combo.get(name) for name in PARAMETERS}
        rid = render_id(params)
        if rid in seen:  # a grid axis listing a value twice, or a random draw repeating a choice
            rid = render_id({**params, "_repeat": i})
        seen[rid] = i
        specs.append(RenderSpec(i, rid, params))
    return specs
