"""The dataset folder: images, a journal of finished renders, and the Parquet metadata table.

    DIR/sweep.toml         the sweep file, as given (provenance)
    DIR/sweep.json         the parsed sweep: a re-run must match it (resume)
    DIR/images/*.png       display-encoded images; linear/*.exr, mask/*.png, depth/*.exr optional
    DIR/journal.jsonl      one JSON row per finished render (ok or failed), appended and flushed
    DIR/metadata.parquet   the table: the journal's last row per render, in render-list order

Consistency: every file is written to a temporary name and renamed (dermis.images.atomic_write);
a render's row is appended to the journal only after its files are in place, with SIGINT held
off meanwhile, so a row always means its files are complete. The Parquet table is rewritten
(atomically) from the journal at the end of a run, after Ctrl-C and when a run starts, so it
holds exactly what finished; a run killed outright (SIGKILL, power loss) leaves the journal,
and the next run rebuilds the table from it. A journal line cut short by such a kill is ignored.
"""

from __future__ import annotations

import contextlib
import json
import os
import shutil
import signal
import threading
from pathlib import Path

from dermis.errors import DermisError

JOURNAL = "journal.jsonl"
TABLE = "metadata.parquet"
FOLDERS = ("images", "linear", "mask", "depth")
INSTALL_PYARROW = "the metadata table needs pyarrow: pip install 'dermis[batch]' (or pip install 'pyarrow>=14')"


def _schema():
    try:
        import pyarrow as pa
    except ModuleNotFoundError:
        raise DermisError(INSTALL_PYARROW) from None
    from dermis.batch.sweep import PARAMETERS

    kinds = {"float": pa.float64(), "int": pa.int64(), "str": pa.string()}
    fields = [("render_id", pa.string()), ("index", pa.int64()), ("status", pa.string()), ("error", pa.string())]
    fields += [(name, kinds[kind]) for name, kind in PARAMETERS.items()]
    fields += [("width", pa.int32()), ("height", pa.int32()),
               ("camera_position", pa.list_(pa.float64())), ("light_colors", pa.list_(pa.list_(pa.float64()))),
               ("light_intensities", pa.list_(pa.float64())),
               ("png", pa.string()), ("exr", pa.string()), ("mask", pa.string()), ("depth", pa.string()),
               ("png_sha256", pa.string()), ("render_ms", pa.float64()), ("total_ms", pa.float64()), ("cpu_ms", pa.float64()),
               ("dermis_version", pa.string()), ("gl_renderer", pa.string()), ("worker", pa.string()),
               ("finished_utc", pa.string()), ("sweep", pa.string()), ("seed", pa.int64())]
    return pa.schema(fields)


def metadata_schema():
    """The pyarrow schema of metadata.parquet (one row per render)."""
    return _schema()


@contextlib.contextmanager
def interrupts_deferred():
    """Hold SIGINT off for the block (main thread only); a Ctrl-C meanwhile is raised after it."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    caught = []
    previous = signal.signal(signal.SIGINT, lambda *a: caught.append(a))
    try:
        yield
    finally:
        signal.signal(signal.SIGINT, previous)
        if caught:
            raise KeyboardInterrupt


class Dataset:
    """The dataset folder of one sweep; :meth:`commit` records a finished render."""

    def __init__(self, out, sweep):
        self.root = Path(out)
        self.sweep = sweep
        if self.root.exists() and not self.root.is_dir():
            raise DermisError(f"out: {self.root}: exists and is not a folder")
        if not self.root.parent.is_dir():
            raise DermisError(f"out: {self.root}: its parent folder {self.root.parent} does not exist")
        _schema()  # pyarrow present: fail before rendering anything
        stored = self.root / "sweep.json"
        if stored.is_file():
            if stored.read_text() != sweep.identity():
                raise DermisError(f"out: {self.root}: holds a dataset of a different sweep (its sweep.json differs "
                                  f"from {sweep.path}); use another --out folder")
        elif self.root.is_dir() and any(self.root.iterdir()):
            raise DermisError(f"out: {self.root}: folder is not empty and holds no dermis batch dataset")
        self.root.mkdir(exist_ok=True)
        for name in FOLDERS:
            (self.root / name).mkdir(exist_ok=True)
        self._remove_partial_files()
        if not stored.is_file():
            from dermis.images import atomic_write

            atomic_write(self.root / "sweep.toml", lambda tmp: shutil.copyfile(sweep.path, tmp))
            atomic_write(stored, lambda tmp: Path(tmp).write_text(sweep.identity()))
        self.rows = self._read_journal()
        self._journal = open(self.root / JOURNAL, "a", encoding="utf-8")

    def _remove_partial_files(self):
        """Temporary files of atomic writes that a killed run left behind."""
        for name in FOLDERS:
            for p in (self.root / name).glob(".*.part*"):
                p.unlink(missing_ok=True)

    def _read_journal(self) -> dict:
        rows = {}
        path = self.root / JOURNAL
        if not path.is_file():
            return rows
        with open(path, encoding="utf-8") as f:
            for line in f:
                try:
                    row = json.loads(line)
                    rows[row["render_id"]] = row
                except (ValueError, KeyError, TypeError):
                    continue  # a line cut short by a killed run
        return rows

    def finished(self, spec) -> bool:
        """True when the render is in the dataset: an ok row whose files are all there."""
        row = self.rows.get(spec.render_id)
        if row is None or row.get("status") != "ok":
            return False
        from dermis.batch.sweep import OUTPUTS

        return all(row.get(k) and (self.root / row[k]).is_file() for k in OUTPUTS if k in self.sweep.outputs)

    def commit(self, row: dict, files: dict):
        """Write a render's files (atomically), then its journal row."""
        from dermis.images import atomic_write

        row = {**row, "sweep": self.sweep.name, "seed": self.sweep.seed}
        line = json.dumps(row, default=float) + "\n"
        with interrupts_deferred():
            for rel, data in files.items():
                atomic_write(self.root / rel, lambda tmp, data=data: Path(tmp).write_bytes(data))
            self._journal.write(line)
            self._journal.flush()
            os.fsync(self._journal.fileno())
            self.rows[row["render_id"]] = row

    def write_table(self, specs) -> Path:
        """metadata.parquet from the journal: one row per render of ``specs`` that finished."""
        import pyarrow as pa
        import pyarrow.parquet as pq

        from dermis.images import atomic_write

        schema = _schema()
        rows = [self.rows[s.render_id] for s in specs if s.render_id in self.rows]
        table = pa.Table.from_pylist([{f.name: r.get(f.name) for f in schema} for r in rows], schema=schema)
        with interrupts_deferred():
            return atomic_write(self.root / TABLE, lambda tmp: pq.write_table(table, tmp))

    def close(self):
        self._journal.close()


def read_table(out):
    """The metadata table of a dataset folder as a pyarrow Table."""
    import pyarrow.parquet as pq

    return pq.read_table(Path(out) / TABLE)
