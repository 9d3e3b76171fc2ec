"""Tabulated Monte Carlo profiles of the shipped skin presets: the shape the physical presets render with.

The layered diffusion models get skin's total reflectance right but not its shape: photon beam
diffusion combined across a 0.25 mm epidermis (thinner than a transport mean free path) is 7-13 %
(light presets) to 17-28 % (dark) off the Monte Carlo of the same layers, r-weighted over
0.1-10 mm, its red tail at 2 mm 15-40 % low (benchmarks/RESULTS.md, issue 13). So the presets'
profiles come from the MCML Monte Carlo (monte_carlo.py) itself, tabulated once and shipped in
``dermis/data/monte_carlo_skin_tables.json``:

    per preset   its SkinParameters, the coefficients of its layers (1/mm, mm) at every tabulated
                 wavelength, the photons per wavelength and the seed (wavelength i runs with
                 seed + 7919 i), and per wavelength (400-700 nm every 20 nm) and radial bin
                 (models.MONTE_CARLO_BIN_EDGES_MM) the mean reflectance (1/mm^2, per unit power
                 entering) with its standard error, and R_d with its standard error.

Regenerate (about 1-3 minutes a preset on 2 cores, 10-15 minutes in all; ``make mc-tables``):

    PYTHONPATH=src nice -n 10 python -m dermis.profiles.monte_carlo_tables [PRESET ...]

A table is used only while its preset's parameters and coefficients are exactly those the code
computes now (``shipped_table``); anything else (other parameters, a medium) runs the Monte Carlo
on demand (scene_skin.py: model = "mc", about 1-2 minutes once, then cached on disk).
"""

from __future__ import annotations

import hashlib
import json
import sys
import time
from dataclasses import dataclass, field
from functools import lru_cache
from importlib import resources

import numpy as np

from dermis.errors import DermisError
from dermis.profiles.spectral import SkinParameters

TABLE_FILE = "monte_carlo_skin_tables.json"
TABLE_VERSION = 1
#: Wavelengths of the tables (the CIE matching functions are smooth on 20 nm; models.py integrates)
TABLE_WAVELENGTHS_NM = np.arange(400.0, 701.0, 20.0)
#: Photons per wavelength: enough that the red/green/blue profile's own standard error, as an
#: r-weighted norm over 0.1-10 mm, stays within about 2 % (recorded per table; tests/test_profiles_mc_tables.py)
DEFAULT_PHOTONS = 100_000
PHOTONS = {"dark": 500_000, "brown": 150_000}
SEED = 20_261_127


@dataclass(frozen=True, eq=False)
class MonteCarloTable:
    """The spectral Monte Carlo of one skin (see the module docstring); arrays are (bins, wavelengths)."""

    name: str
    parameters: SkinParameters
    wavelength_nm: np.ndarray
    bin_edges_mm: np.ndarray
    reflectance_per_mm2: np.ndarray
    standard_error_per_mm2: np.ndarray
    total_reflectance: np.ndarray
    total_standard_error: np.ndarray
    photons: int
    seed: int
    medium: dict = field(default_factory=dict)
    seconds: float = float("nan")

    def profile(self, illuminant: str = "D65", name: str | None = None):
        """The table as a linear-sRGB RadialProfile (model "mc", with its standard error)."""
        from dermis.profiles.models import monte_carlo_table_profile

        return monte_carlo_table_profile(self.reflectance_per_mm2, self.standard_error_per_mm2,
                                         self.total_reflectance, self.wavelength_nm, illuminant, name or self.name)

    def to_dict(self) -> dict:
        def rows(a):
            return [[float(f"{v:.5e}") for v in row] for row in np.asarray(a)]

        return {"name": self.name, "parameters": self.parameters.to_dict(), "photons_per_wavelength": self.photons,
                "seed": self.seed, "seed_of_wavelength_i": "seed + 7919 i", "seconds": round(self.seconds, 1),
                "wavelength_nm": self.wavelength_nm.tolist(), "bin_edges_mm": self.bin_edges_mm.tolist(),
                "reflectance_per_mm2": rows(self.reflectance_per_mm2),
                "standard_error_per_mm2": rows(self.standard_error_per_mm2),
                "total_reflectance": [float(f"{v:.6f}") for v in self.total_reflectance],
                "total_standard_error": [float(f"{v:.3e}") for v in self.total_standard_error],
                "medium": self.medium}

    @classmethod
    def from_dict(cls, entry: dict) -> "MonteCarloTable":
        return cls(entry["name"], SkinParameters(**entry["parameters"]), np.array(entry["wavelength_nm"], float),
                   np.array(entry["bin_edges_mm"], float), np.array(entry["reflectance_per_mm2"], float),
                   np.array(entry["standard_error_per_mm2"], float), np.array(entry["total_reflectance"], float),
                   np.array(entry["total_standard_error"], float), int(entry["photons_per_wavelength"]),
                   int(entry["seed"]), entry.get("medium", {}), float(entry.get("seconds", float("nan"))))

    def digest(self) -> str:
        """A short hash of the table's numbers (for cache keys of fits to it)."""
        text = json.dumps([self.name, self.parameters.to_dict(), self.photons, self.seed,
                           self.reflectance_per_mm2.tolist(), self.total_reflectance.tolist()])
        return hashlib.sha256(text.encode()).hexdigest()[:16]


def _medium_of(parameters: SkinParameters, wavelength_nm) -> dict:
    from dermis.profiles.medium_file import medium_document
    from dermis.profiles.spectral import skin_layers

    return medium_document(skin_layers(parameters, wavelength_nm), wavelength_nm)


def tabulate(name: str, parameters: SkinParameters, photons: int = DEFAULT_PHOTONS, seed: int = SEED,
             wavelength_nm=TABLE_WAVELENGTHS_NM, progress=False) -> MonteCarloTable:
    """Run the Monte Carlo of ``parameters`` at ``wavelength_nm`` (costly: see the module docstring)."""
    from dermis.profiles.models import MONTE_CARLO_BIN_EDGES_MM, monte_carlo_spectral
    from dermis.profiles.spectral import skin_layers

    wavelength = np.asarray(wavelength_nm, dtype=np.float64)
    started = time.perf_counter()
    values, errors, totals, total_errors = monte_carlo_spectral(skin_layers(parameters, wavelength), photons, seed,
                                                                progress)
    return MonteCarloTable(name, parameters, wavelength, MONTE_CARLO_BIN_EDGES_MM.copy(), values, errors, totals,
                           total_errors, int(photons), int(seed), _medium_of(parameters, wavelength),
                           time.perf_counter() - started)


@lru_cache(maxsize=1)
def shipped_tables() -> dict[str, MonteCarloTable]:
    """Every table in dermis/data/monte_carlo_skin_tables.json, by preset name ({} if none ships)."""
    source = resources.files("dermis.data").joinpath(TABLE_FILE)
    if not source.is_file():
        return {}
    document = json.loads(source.read_text())
    if document.get("version") != TABLE_VERSION:
        return {}
    return {entry["name"]: MonteCarloTable.from_dict(entry) for entry in document["tables"]}


def is_current(table: MonteCarloTable) -> bool:
    """The table was computed for the coefficients and bins the code gives its parameters now."""
    from dermis.profiles.models import MONTE_CARLO_BIN_EDGES_MM

    if table.bin_edges_mm.shape != MONTE_CARLO_BIN_EDGES_MM.shape or not np.allclose(
            table.bin_edges_mm, MONTE_CARLO_BIN_EDGES_MM, rtol=1e-12, atol=0):
        return False
    now = _medium_of(table.parameters, table.wavelength_nm)
    stored = table.medium.get("layer", [])
    if len(stored) != len(now["layer"]):
        return False
    for a, b in zip(stored, now["layer"]):
        for key in ("sigma_a", "sigma_s"):
            if not np.allclose(a[key], b[key], rtol=1e-9, atol=0):
                return False
        if (a["g"], a["eta"], a["thickness_mm"]) != (b["g"], b["eta"], b["thickness_mm"]):
            return False
    return True


def shipped_table(parameters: SkinParameters) -> MonteCarloTable | None:
    """The shipped table of exactly these skin parameters, if one ships and is current."""
    for table in shipped_tables().values():
        if table.parameters == parameters and is_current(table):
            return table
    return None


#: Radii over which shapes are compared with a table (mm): below 0.1 mm single scattering dominates
#: and no renderer resolves it; beyond 10 mm less than 1e-3 of the energy is left.
COMPARISON_RANGE_MM = (0.1, 10.0)


def shape_difference(profile, table: MonteCarloTable, illuminant: str = "D65"):
    """(difference, noise) per linear-sRGB channel of ``profile`` against the table over COMPARISON_RANGE_MM.

    ``profile``: callable radius_mm (any shape) -> (..., 3) in 1/mm^2 (a RadialProfile's or a
    SumOfGaussians' ``evaluate``), averaged over each of the table's annuli (Gauss-Legendre);
    difference = sqrt(sum w (model - MC)^2 / sum w MC^2) with w = r dr of each bin, the r-weighted
    relative L2 error of fit.py on the table's bins; noise = the same norm of the table's own
    standard error (what a perfect model would still show).
    """
    from dermis.profiles.monte_carlo import annulus_average

    reference = table.profile(illuminant)
    edges = table.bin_edges_mm
    centre = reference.radius_mm
    keep = (centre >= COMPARISON_RANGE_MM[0]) & (centre <= COMPARISON_RANGE_MM[1])
    weight = (centre * np.diff(edges))[keep, None]
    target = reference.rgb_per_mm2[keep]
    model = annulus_average(profile, edges)[keep]
    norm = np.sqrt(np.sum(weight * target**2, axis=0))
    difference = np.sqrt(np.sum(weight * (model - target) ** 2, axis=0)) / norm
    noise = np.sqrt(np.sum(weight * reference.standard_error_rgb_per_mm2[keep] ** 2, axis=0)) / norm
    return difference, noise


def write_tables(path, tables: list[MonteCarloTable]) -> None:
    from dermis.profiles.profile_json import write_atomic

    document = {"version": TABLE_VERSION, "generator": "python -m dermis.profiles.monte_carlo_tables",
                "units": {"reflectance_per_mm2": "1/mm^2 per unit power entering, mean over each annulus",
                          "bin_edges_mm": "mm", "medium": "1/mm and mm"},
                "tables": [t.to_dict() for t in tables]}
    text = json.dumps(document, separators=(",", ":")).encode()
    write_atomic(path, lambda stream: stream.write(text))


def main(argv=None) -> int:
    """Regenerate the tables of the named presets (default all) into dermis/data, keeping the others."""
    from pathlib import Path

    from dermis.profiles.presets import SKIN_PRESETS

    names = list(argv if argv is not None else sys.argv[1:]) or list(SKIN_PRESETS)
    unknown = [n for n in names if n not in SKIN_PRESETS]
    if unknown:
        print(f"dermis: error: unknown preset '{unknown[0]}' (known: {', '.join(SKIN_PRESETS)})", file=sys.stderr)
        return 2
    path = Path(__file__).resolve().parent.parent / "data" / TABLE_FILE
    tables = dict(shipped_tables())
    done: dict[SkinParameters, MonteCarloTable] = {}
    for name in names:
        parameters = SKIN_PRESETS[name]
        same = done.get(parameters)
        if same is not None:  # presets with the same parameters share one Monte Carlo
            tables[name] = MonteCarloTable(name, *[getattr(same, f) for f in (
                "parameters", "wavelength_nm", "bin_edges_mm", "reflectance_per_mm2", "standard_error_per_mm2",
                "total_reflectance", "total_standard_error", "photons", "seed", "medium", "seconds")])
        else:
            photons = PHOTONS.get(name, DEFAULT_PHOTONS)
            tables[name] = done[parameters] = tabulate(name, parameters, photons, SEED, progress=True)
        print(f"{name}: {tables[name].photons} photons per wavelength, {tables[name].seconds:.0f} s, R_d "
              + " ".join(f"{v:.3f}" for v in tables[name].total_reflectance), flush=True)
        ordered = [tables[n] for n in SKIN_PRESETS if n in tables]
        write_tables(path, ordered)  # after every preset: an interrupted run keeps what it finished
    shipped_tables.cache_clear()
    return 0


if __name__ == "__main__":
    sys.exit(main())
