"""gelrig for Python: GelSight marker tracking, a calibrated force reader, a simulated bench
and tactile-force runs — the same code as the ``gelrig`` command, called from Python.

    >>> import gelrig
    >>> p = gelrig.Protocol.load("box-normal-flat")
    >>> run = gelrig.run(p, out="runs", seed=1)
    >>> run.force.head()          # a pandas DataFrame
    >>> tracker = gelrig.Tracker(reference_frame)      # numpy uint8, H×W×3
    >>> result = tracker.track(frame)                  # result.xy, result.dxy, result.state

Tables come back as pandas DataFrames read by pyarrow (integer ``t_ns``, floats in the
SI-named columns of the CSVs); frames as numpy ``uint8`` arrays of shape (H, W, 3). Errors are
:class:`GelrigError` (or :class:`ProtocolError`) with the command's message: the place and
the fix.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any, Callable, Mapping, Optional, Sequence, Union

import numpy as np
import pandas as pd
import pyarrow as pa
import pyarrow.csv as pacsv

from . import _gelrig
from ._gelrig import ForceSensor, GelrigError, ProtocolError, Shape, Tracker, TrackResult
from . import sim

# The shipped protocols travel in the wheel (`gelrig/protocols`, the repository's
# `protocols/`): found by name from any folder, as the command finds them beside its binary.
# Registered in the native module for this process only (the environment is left alone: a
# `gelrig` binary this process starts finds its own); a `GELRIG_PROTOCOLS` the user set wins.
_SHIPPED = Path(__file__).with_name("protocols")
if (_SHIPPED / "rigs" / "sim.yaml").is_file():
    _gelrig.use_packaged_protocols(_SHIPPED)

__version__ = _gelrig.__version__
__all__ = [
    "ForceSensor",
    "GelrigError",
    "Protocol",
    "ProtocolError",
    "Run",
    "Shape",
    "Tracker",
    "TrackResult",
    "read_image",
    "run",
    "runs",
    "sim",
]

PathLike = Union[str, Path]


class Plan(pd.DataFrame):
    """The steps of a plan, one row each, with the run's ``duration_s`` (min, max) and its
    ``frames`` and ``bytes`` (min, max) as attributes."""

    _metadata = ["duration_s", "frames", "bytes"]

    @property
    def _constructor(self):
        return Plan


class Protocol:
    """A protocol loaded with its rig, checked and planned once, as the command does.

    ``Protocol.load(path_or_name, rig=None, set=None, name=None)``: a file, or a shipped
    protocol's name (``"box-normal-flat"``); ``set`` changes values without editing the
    file, as ``--set`` does (``{"indenter.diameter": "10 mm"}``).
    """

    def __init__(self, native: "_gelrig.Protocol"):
        self._native = native

    @classmethod
    def load(
        cls,
        path: PathLike,
        rig: Optional[PathLike] = None,
        set: Optional[Mapping[str, str]] = None,
        name: Optional[str] = None,
    ) -> "Protocol":
        values = {str(k): str(v) for k, v in (set or {}).items()}
        return cls(_gelrig.Protocol.load(str(path), None if rig is None else str(rig), values, name))

    @property
    def path(self) -> Path:
        return Path(self._native.path)

    @property
    def name(self) -> str:
        return self._native.name

    @property
    def valid(self) -> bool:
        return self._native.valid

    @property
    def diagnostics(self) -> list[dict]:
        return self._native.diagnostics

    def validate(self) -> list[str]:
        """Raises :class:`ProtocolError` unless the protocol checks; returns its warnings."""
        return self._native.validate()

    def plan(self) -> Plan:
        """The expanded steps as a DataFrame (``ends_min_s``, ``ends_max_s`` per step), with
        the run's ``duration_s``, ``frames`` and ``bytes`` as (min, max)."""
        raw = json.loads(self._native.plan_json())
        rows = []
        for s in raw["steps"]:
            row = {k: v for k, v in s.items() if k != "ends_s"}
            row["ends_min_s"] = s["ends_s"]["min"]
            row["ends_max_s"] = s["ends_s"]["max"]
            rows.append(row)
        df = Plan(pd.DataFrame(rows))
        df.duration_s = (raw["duration_s"]["min"], raw["duration_s"]["max"])
        df.frames = (raw["frames"]["min"], raw["frames"]["max"])
        df.bytes = (raw["bytes"]["min"], raw["bytes"]["max"])
        return df

    def __repr__(self) -> str:
        return repr(self._native)


def run(
    protocol: Union[Protocol, PathLike],
    out: PathLike = "runs",
    seed: int = 0,
    time_scale: Optional[float] = None,
    on_event: Optional[Callable[[dict], Any]] = None,
) -> "Run":
    """Runs ``protocol`` as ``gelrig run`` does (the same run directory, seed for seed) and
    returns the :class:`Run`. On a simulated rig the run goes in virtual time unless
    ``time_scale`` (a speed-up over the wall clock) is given. ``on_event(dict)`` receives
    each step, force reading, frame, tactile state and the end as they happen. Ctrl-C stops
    the run cleanly (retract, status ``aborted``), then raises ``KeyboardInterrupt``."""
    if not isinstance(protocol, Protocol):
        protocol = Protocol.load(protocol)
    callback = None
    if on_event is not None:
        callback = lambda text: on_event(json.loads(text))  # noqa: E731
    Path(out).mkdir(parents=True, exist_ok=True)
    directory, _status, _message = _gelrig.run(
        protocol._native, str(out), int(seed), time_scale, callback
    )
    return Run(directory)


# A column named with a unit (`fz_n`, `depth_mm`, `settle_s`) is a float in that unit, even
# when every value in a file happens to be whole; times in ns, counters and ids are integers.
_UNITS = ("_n", "_nmm", "_mm", "_mm2", "_deg", "_rad", "_s", "_px", "_px2", "_hz", "_mpa", "_pct")


def _is_integer(column: str) -> bool:
    return column.endswith("_ns") or not column.endswith(_UNITS)


def _read_table(path: Path) -> pd.DataFrame:
    # The column types from the first block only (a streaming reader infers them there).
    with pacsv.open_csv(path, read_options=pacsv.ReadOptions(block_size=1 << 16)) as reader:
        header = reader.schema
    types = {}
    for field in header:
        if pa.types.is_integer(field.type):
            types[field.name] = pa.int64() if _is_integer(field.name) else pa.float64()
        elif pa.types.is_floating(field.type) or pa.types.is_null(field.type):
            types[field.name] = pa.float64()
    table = pacsv.read_csv(path, convert_options=pacsv.ConvertOptions(column_types=types))
    return table.to_pandas()


class Run:
    """A run directory: its status, manifest, tables (pandas), frames (numpy), report and
    exports."""

    _TABLES = {
        "steps": "steps.csv",
        "force": "force.csv",
        "axes": "axes.csv",
        "frames": "frames.csv",
        "markers": "markers.csv",
        "contact": "contact.csv",
        "tactile": "tactile.csv",
        "wrench": "wrench.csv",
        "sim_steps": "sim_steps.csv",
    }

    def __init__(self, path: PathLike):
        self.path = Path(path)
        if not (self.path / "run.yaml").is_file():
            raise GelrigError(f"{self.path}: not a run directory (no run.yaml); give a folder `gelrig run` made")
        self._cache: dict[str, pd.DataFrame] = {}

    @property
    def status(self) -> str:
        """completed, aborted, failed, running, or interrupted (killed)."""
        return _gelrig.run_status(str(self.path))

    @property
    def manifest(self) -> dict:
        """``run.yaml`` as a dict."""
        return json.loads(_gelrig.read_manifest(str(self.path)))

    def table(self, name: str) -> pd.DataFrame:
        """The table ``name`` (``force``, ``steps``, ``frames``, ``markers``, ``contact``,
        ``tactile``, ``axes``, ``wrench``, ``sim_steps``) as a DataFrame."""
        if name not in self._TABLES:
            raise GelrigError(f"no table `{name}`; the tables are {', '.join(self._TABLES)}")
        if name not in self._cache:
            path = self.path / self._TABLES[name]
            if not path.is_file():
                hint = " (track the run first: `gelrig track RUN_DIR`)" if name in ("markers", "contact") else ""
                raise GelrigError(f"{path}: this run has no {name} table{hint}")
            self._cache[name] = _read_table(path)
        return self._cache[name]

    force = property(lambda self: self.table("force"))
    steps = property(lambda self: self.table("steps"))
    frames = property(lambda self: self.table("frames"))
    markers = property(lambda self: self.table("markers"))
    contact = property(lambda self: self.table("contact"))
    tactile = property(lambda self: self.table("tactile"))

    @property
    def trials(self) -> pd.DataFrame:
        """A grasp run's trials, one row each (held or slipped, when slip was felt, the
        lead of the warning, …), as its report finds them; the report is made first if the
        run has none."""
        summary_path = self.path / "report" / "summary.json"
        if summary_path.is_file():
            summary = json.loads(summary_path.read_text())
        else:
            summary = self.report()[1]
        rows = summary.get("trials")
        if not isinstance(rows, list):
            raise GelrigError(f"{self.path}: this run has no trials (it repeats no grasp)")
        return pd.DataFrame(rows)
    axes = property(lambda self: self.table("axes"))

    def frame(self, index: int) -> np.ndarray:
        """Frame ``index`` (as in ``frames.frame``) as ``uint8`` (H, W, 3)."""
        return _gelrig.read_frame(str(self.path), int(index))

    def report(self, out: Optional[PathLike] = None, sensor: Optional[PathLike] = None) -> tuple[Path, dict]:
        """Writes the report (into ``RUN/report`` or ``out``); returns its folder and its
        ``summary.json`` as a dict."""
        folder, summary = _gelrig.report(
            str(self.path), None if out is None else str(out), None if sensor is None else str(sensor)
        )
        return Path(folder), json.loads(summary)

    def export(self, format: str, out: PathLike) -> list[Path]:
        """Writes the run as ``parquet`` (a folder of tables) or ``mcap`` (one file)."""
        return [Path(p) for p in _gelrig.export(str(self.path), format, str(out))]

    def __repr__(self) -> str:
        return f"Run({str(self.path)!r}, status={self.status!r})"


def read_image(path: PathLike) -> np.ndarray:
    """The image at ``path`` as ``uint8`` (H, W, 3), decoded as ``gelrig track`` decodes it."""
    return _gelrig.read_image(str(path))


def runs(folder: PathLike = "runs") -> pd.DataFrame:
    """The runs in ``folder``, one row each, as ``gelrig runs`` lists them."""
    return pd.DataFrame(json.loads(_gelrig.list_runs(str(folder))))
