"""A finished run's folder read back: the typed record, the trajectories, the plots."""

from __future__ import annotations

import json
import shutil
from pathlib import Path
from typing import TYPE_CHECKING, Any, Dict, List, Optional

from syncroad._errors import RecordError

if TYPE_CHECKING:
    import pyarrow


class Record(Dict[str, Any]):
    """A JSON record of the CLI (``metrics.json``, a ``check``/``stability`` report) as a
    dict whose keys also read as attributes: ``record.sync.verdict`` is
    ``record["sync"]["verdict"]``. Its fields are those of ``docs/metrics.schema.json``."""

    def __getattr__(self, name: str) -> Any:
        try:
            value = self[name]
        except KeyError:
            raise AttributeError(name) from None
        return _wrap(value)

    def __getitem__(self, key: str) -> Any:
        return _wrap(dict.__getitem__(self, key))

    def __dir__(self) -> List[str]:
        return [*super().__dir__(), *self.keys()]


def _wrap(value: Any) -> Any:
    if isinstance(value, dict) and not isinstance(value, Record):
        return Record(value)
    return value


#: The files of a run's folder (as the CLI names them).
METRICS_FILE = "metrics.json"
#: Where the CLI keeps a record it could not write as metrics.json.
UNSAVED_GLOB = "metrics.unsaved-*.json"
TRAJECTORY_FILE = "trajectories.csv"
PLOT_NAMES = ("time_space", "speeds", "spread")


class Run:
    """One run's results: the folder the CLI wrote (``metrics.json``, ``trajectories.csv``,
    plots). ``Run(folder)`` opens any run folder, a compare run's or a kept sweep run's."""

    out: Path
    #: The record file read: ``out/metrics.json``, or the ``metrics.unsaved-*.json`` kept there.
    record_file: Path
    exit_code: Optional[int]
    summary: str

    def __init__(self, out: "str | Path", exit_code: Optional[int] = None, summary: str = ""):
        path = Path(out)
        if path.is_file() and path.name.startswith("metrics") and path.suffix == ".json":
            # A record file itself: metrics.json, or one kept as metrics.unsaved-*.json when
            # metrics.json could not be written.
            self.out, self.record_file = path.parent, path
        else:
            self.out, self.record_file = path, path / METRICS_FILE
            kept = sorted(path.glob(UNSAVED_GLOB)) if path.is_dir() else []
            if not self.record_file.is_file() and len(kept) == 1:
                self.record_file = kept[0]
        self.exit_code = exit_code
        self.summary = summary
        self._metrics: Optional[Record] = None
        self._trajectories: Optional["pyarrow.Table"] = None
        if not self.record_file.is_file():
            raise FileNotFoundError(f"{self.out / METRICS_FILE}: not a run folder (no {METRICS_FILE})")

    @property
    def metrics(self) -> Record:
        """The typed run record (``metrics.json``, or the ``metrics.unsaved-*.json`` kept in
        its place; schema: ``syncroad schema``). :class:`RecordError` when it cannot be read."""
        if self._metrics is None:
            try:
                data = json.loads(self.record_file.read_text())
            except (UnicodeDecodeError, json.JSONDecodeError) as e:
                raise RecordError(f"{self.record_file}: not a readable run record ({e})", self.record_file) from None
            if not isinstance(data, dict) or "sync" not in data:
                raise RecordError(
                    f"{self.record_file}: not a syncroad run record (a JSON object with a 'sync' block)",
                    self.record_file,
                )
            self._metrics = Record(data)
        return self._metrics

    @property
    def verdict(self) -> str:
        """``"synchronized"``, ``"not_synchronized"`` or ``"inconclusive"`` (a run that did
        not complete is never more confident than the rows it has)."""
        return str(self.metrics["sync"]["verdict"])

    @property
    def complete(self) -> bool:
        """True when the run reached its horizon."""
        return bool(self.metrics["complete"])

    @property
    def trajectories(self) -> "pyarrow.Table":
        """Every recorded sample: ``time_s, vehicle, speed_mps, position_m, gap_m`` (and the
        command where the CLI records one), as a pyarrow Table (``.to_pandas()``)."""
        if self._trajectories is None:
            from pyarrow import csv

            self._trajectories = csv.read_csv(str(self.out / TRAJECTORY_FILE))
        return self._trajectories

    @property
    def vehicle_ids(self) -> Optional[List[str]]:
        """The SUMO ids of the trajectory's vehicles, by its ``vehicle`` index, when the law
        drove vehicles of your own (``sumo.controlled``; ``record.controlled.vehicles``):
        ``df["id"] = df["vehicle"].map(dict(enumerate(run.vehicle_ids)))``. ``None`` for a
        run of syncroad's own vehicles."""
        c = self.metrics.get("controlled")
        return None if c is None else [str(v) for v in c["vehicles"]]

    def plots(self, out: "Optional[str | Path]" = None) -> Dict[str, Path]:
        """The run's plots (time-space diagram, speeds, spread; PNG and SVG, and PDF when run
        with ``pdf=True``), drawn by the CLI when the run was written, keyed
        ``"time_space.png"`` etc.; with ``out``, copied
        into that folder (created if missing) and the copies returned."""
        found = {
            f"{name}.{ext}": self.out / f"{name}.{ext}"
            for name in PLOT_NAMES
            for ext in ("png", "svg", "pdf")
            if (self.out / f"{name}.{ext}").is_file()
        }
        if not found:
            raise FileNotFoundError(
                f"{self.out}: no plots (the run was written with plots=False, or did not complete)"
            )
        if out is None:
            return found
        dest = Path(out)
        dest.mkdir(parents=True, exist_ok=True)
        copies = {}
        for name, src in found.items():
            target = dest / name
            if target.exists() and not target.samefile(src):
                raise FileExistsError(f"{target}: exists; syncroad never overwrites a file it did not write")
            if not target.exists():
                shutil.copyfile(src, target)
            copies[name] = target
        return copies

    def _repr_html_(self) -> str:
        return f"<pre>{self.summary or repr(self)}</pre>"

    def __repr__(self) -> str:
        m = self.metrics
        return f"Run({m.get('scenario')!r}, run={m.get('run')!r}, backend={m.get('backend')!r}, verdict={self.verdict!r}, out={str(self.out)!r})"
