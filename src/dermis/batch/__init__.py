"""Batch rendering: parameter sweeps rendered into a dataset (images + a Parquet table), on
local worker processes or on Ray (``dermis batch``; the sweep format is in docs/batch.md).

>>> from dermis.batch import run_batch
>>> result = run_batch("examples/batch-skin-tones.toml", "out/skin-tones", workers=2)
>>> result.ok, result.failed, result.renders_per_minute

- ``sweep``: the sweep file and its expansion to a deterministic render list.
- ``apply``: a render's parameters set on a loaded Scene.
- ``colour_temperature``: a light's colour temperature as linear RGB (blackbody, CIE 1931).
- ``worker``: a GL context and Renderer kept across renders; one render -> row + file bytes.
- ``executors``: local worker processes and Ray actors.
- ``dataset``: the dataset folder, its journal and the metadata table; resume.
- ``run``: the driver.
"""

from dermis.batch.run import BatchResult, run_batch
from dermis.batch.sweep import RenderSpec, Sweep, expand, load_sweep

__all__ = ["run_batch", "BatchResult", "load_sweep", "expand", "Sweep", "RenderSpec"]
