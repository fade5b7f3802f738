"""Every per-point quantity, declared once: the column table (:data:`COLUMNS`).

A measured point travels capture -> run store -> export -> measurement CSV -> Dataset.
Each quantity it carries is one :class:`Column`: its name, unit and meaning; its
column(s) in the measurement CSV (docs/formats.md §1) and how they are read and
written; its column(s) and SQL type in the run store (the ``samples`` table, and the
``readings`` table when a rejected reading keeps it too) and how a value is encoded
there; and the field it fills in :class:`calibration.data.dataset.Dataset` and in the
store's record of a point (``daq.store.Sample``, named like the column). The CSV reader
and writer, the store's writer and readers (rows read by column name), the export and
``Dataset.subset``/``concat`` all go through this table, and
``tests/calibration/test_columns.py`` and ``tests/daq/test_column_table.py`` check that
it covers every Dataset field, every store column (with its SQL type and schema version)
and every CSV column: a new quantity is one entry here.

One name per quantity
    :attr:`Column.name` is the name in code: the Dataset's field and the store record's.
    Where the CSV or the store spells it otherwise, :attr:`Column.reason` says why. The
    CSV is a contract (docs/formats.md §1) and a released store column is never renamed
    (old stores must open and upgrade in place: ``daq.store.schema``), so a name that
    differs there stays and is explained.

Kinds
    How a value is stored and stacked over points is its :class:`Kind`: a scalar (REAL,
    INTEGER or TEXT), a fixed-width vector spread over several store columns (``x, y,
    z``), a per-joint list stored as JSON, a JSON document, a covariance's upper triangle.
    A record (one point) holds None where a value was not measured; a run's columns
    (``daq.store.Samples``) hold NaN, 0 or None there, as the kind says; a Dataset
    column is all or nothing (:meth:`Kind.gather`).

Reading the CSV
    Each readable entry has a reader ``read(table, ctx, got) -> {field: values}`` over
    the strict table of :mod:`calibration.data.dataset` (``CsvTable``); every refusal is a
    :class:`DataError` naming the file, the line and the column. The required columns are
    read first, then the others in table order (``got``: what was read so far, e.g. the
    orientation's uncertainty needs the quaternions).

Units in code: joints rad, lengths mm, angles of orientation as unit quaternions and
their uncertainty deg, times epoch s, temperatures °C; the CSV writes joints in deg.
"""

from __future__ import annotations

import json
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np

from ..errors import DataError
from .orientation_columns import QUAT_COLUMNS, read_quaternions, read_sigma_deg, read_tool_ids

if TYPE_CHECKING:
    from .dataset import CsvTable, Dataset

#: lengths beyond 1 km are no measurement of a robot cell
MAX_LENGTH_MM = 1e6
PLAUSIBLE_LENGTH = "a plausible length (|value| <= 1e6 mm)"
#: plausible ranges of the optional columns: (low, high, expected form)
OPTIONAL_RANGES = {
    "temp_c": (-100.0, 200.0, "a plausible temperature (-100 to 200 °C)"),
    "payload_kg": (0.0, 10000.0, "a payload mass (0 to 10000 kg)"),
    "sigma_mm": (0.0, 1000.0, "a plausible tracker uncertainty (0 to 1000 mm)"),
}


# ---------------------------------------------------------------------------- kinds
class Kind:
    """How a quantity's value is stored, stacked over a run's points and gathered into a
    Dataset column. ``encode``/``decode``: one record's value to/from its store columns
    (``decode`` gets the row as a mapping of column name to value); ``stack``/``unstack``:
    the records' values to/from a run's column (``daq.store.Samples``); ``gather``: the
    Dataset's column, or None unless every record has a value."""

    #: the SQL type of each store column (SQLite's spelling)
    sql = "REAL"

    def encode(self, value: Any) -> tuple:
        return (None if value is None else float(value),)

    def decode(self, row: Mapping, columns: tuple[str, ...]) -> Any:
        v = row[columns[0]]
        return None if v is None else float(v)

    def stack(self, values: list) -> Any:
        return np.array([np.nan if v is None else v for v in values], float)

    def column(self, rows: Sequence[Mapping[str, Any]], columns: tuple[str, ...]) -> Any:
        """A run's column straight from its rows (read by name): what ``stack`` makes of
        the decoded values, without a record per row."""
        return self.stack([self.decode(r, columns) for r in rows])

    def unstack(self, column: Any, i: int) -> Any:
        v = float(column[i])
        return None if np.isnan(v) else v

    def gather(self, values: list) -> Any:
        return None if any(v is None for v in values) else np.array(values, float)


class Real(Kind):
    """A float, NULL where not measured (NaN in a run's column)."""

    def column(self, rows: Sequence[Mapping[str, Any]], columns: tuple[str, ...]) -> Any:
        return np.array([r[columns[0]] for r in rows], float)  # NULL -> NaN by numpy


@dataclass(frozen=True)
class Int(Kind):
    """An integer. ``missing``: the record's value where the store holds NULL;
    ``column_missing``: a run's column's value there; ``zero_is_none``: 0 means "not
    said" (a tracker face), stored as NULL and read back as None."""

    missing: int | None = 0
    column_missing: int = 0
    zero_is_none: bool = False
    sql = "INTEGER"

    def encode(self, value: Any) -> tuple[Any, ...]:
        if value is None or (self.zero_is_none and not value):
            return (None,)
        return (int(value),)

    def decode(self, row: Mapping[str, Any], columns: tuple[str, ...]) -> Any:
        v = row[columns[0]]
        if v is None or (self.zero_is_none and not v):
            return self.missing
        return int(v)

    def stack(self, values: list[Any]) -> Any:
        return np.array([self.column_missing if v is None else v for v in values], int)

    def unstack(self, column: Any, i: int) -> Any:
        v = int(column[i])
        return None if self.zero_is_none and not v else v

    def gather(self, values: list[Any]) -> Any:
        return None if any(v is None for v in values) else np.array(values, int)


@dataclass(frozen=True)
class Text(Kind):
    """A string, NULL when empty or not said. ``default``: the record's value where the
    store holds none (a function of the row, or a constant)."""

    default: Callable[[Mapping], str] | str | None = None
    sql = "TEXT"

    def encode(self, value: Any) -> tuple[Any, ...]:
        return (value or None,)

    def decode(self, row: Mapping[str, Any], columns: tuple[str, ...]) -> Any:
        v = row[columns[0]]
        if v:
            return v
        return self.default(row) if callable(self.default) else self.default

    def stack(self, values: list[Any]) -> Any:
        return list(values)

    def unstack(self, column: Any, i: int) -> Any:
        return column[i]

    def gather(self, values: list[Any]) -> Any:
        return None if any(v is None for v in values) else list(values)


@dataclass(frozen=True)
class Vector(Kind):
    """A fixed-width float vector spread over ``width`` store columns (``x, y, z``).
    ``nullable`` False: always present (NaN where a column is NULL)."""

    width: int = 3
    nullable: bool = True

    def encode(self, value: Any) -> tuple[Any, ...]:
        if value is None:
            return (None,) * self.width
        return tuple(float(v) for v in np.asarray(value, float))

    def decode(self, row: Mapping[str, Any], columns: tuple[str, ...]) -> Any:
        values = [row[c] for c in columns]
        if self.nullable and values[0] is None:
            return None
        return np.array(values, float)

    def stack(self, values: list[Any]) -> Any:
        if not values:
            return np.zeros((0, self.width))
        return np.array([np.full(self.width, np.nan) if v is None else v for v in values],
                        float)

    def column(self, rows: Sequence[Mapping[str, Any]], columns: tuple[str, ...]) -> Any:
        return np.array([[r[c] for c in columns] for r in rows], float).reshape(-1, self.width)

    def unstack(self, column: Any, i: int) -> Any:
        if self.nullable and np.isnan(column[i]).any():
            return None
        return column[i].copy()

    def gather(self, values: list[Any]) -> Any:
        return None if any(v is None for v in values) else np.array(values, float)


@dataclass(frozen=True)
class JointList(Kind):
    """One value per joint, stored as a JSON list in one TEXT column. ``nullable`` False:
    every record has it (the joints); otherwise a run's column is None unless every
    point has it."""

    dtype: type = float
    nullable: bool = True
    sql = "TEXT"

    def encode(self, value: Any) -> tuple[Any, ...]:
        if value is None:
            return (None,)
        return (json.dumps([self.dtype(v) for v in np.asarray(value, self.dtype)]),)

    def decode(self, row: Mapping[str, Any], columns: tuple[str, ...]) -> Any:
        v = row[columns[0]]
        return None if v is None else np.array(json.loads(v), self.dtype)

    def stack(self, values: list[Any]) -> Any:
        if not self.nullable:
            return (np.array(values, self.dtype).reshape(len(values), -1) if values
                    else np.zeros((0, 0)))
        if not values or any(v is None for v in values):
            return None
        return np.array(values, self.dtype)

    def unstack(self, column: Any, i: int) -> Any:
        return None if column is None else column[i].copy()

    def gather(self, values: list[Any]) -> Any:
        return None if any(v is None for v in values) else np.array(values, self.dtype)


class JsonDoc(Kind):
    """A JSON document (a dict) in one TEXT column, None where there is none."""

    sql = "TEXT"

    def encode(self, value: Any) -> tuple[Any, ...]:
        return (None if value is None else json.dumps(value),)

    def decode(self, row: Mapping[str, Any], columns: tuple[str, ...]) -> Any:
        v = row[columns[0]]
        return json.loads(v) if v else None

    def stack(self, values: list[Any]) -> Any:
        return list(values)

    def unstack(self, column: Any, i: int) -> Any:
        return column[i]

    def gather(self, values: list[Any]) -> Any:
        return list(values)


#: the covariance's upper triangle as stored (``cov_xx`` … ``cov_zz``): (row, column)
_COV = ((0, 0), (0, 1), (0, 2), (1, 1), (1, 2), (2, 2))


class Covariance(Kind):
    """A symmetric (3, 3) matrix stored as its upper triangle in six REAL columns; None
    where the first is NULL (NaN where another is)."""

    def encode(self, value: Any) -> tuple[Any, ...]:
        if value is None:
            return (None,) * len(_COV)
        c = np.asarray(value, float)
        return tuple(float(c[i, j]) for i, j in _COV)

    def decode(self, row: Mapping[str, Any], columns: tuple[str, ...]) -> Any:
        if row[columns[0]] is None:
            return None
        out = np.full((3, 3), np.nan)
        for (i, j), c in zip(_COV, columns, strict=True):
            v = row[c]
            out[i, j] = out[j, i] = np.nan if v is None else v
        return out

    def stack(self, values: list[Any]) -> Any:
        return np.array([np.full((3, 3), np.nan) if v is None else v for v in values],
                        float).reshape(len(values), 3, 3)

    def column(self, rows: Sequence[Mapping[str, Any]], columns: tuple[str, ...]) -> Any:
        upper = np.array([[r[c] for c in columns] for r in rows], float).reshape(-1, len(_COV))
        out = np.full((len(rows), 3, 3), np.nan)
        for m, (i, j) in enumerate(_COV):
            out[:, i, j] = out[:, j, i] = upper[:, m]
        return out

    def unstack(self, column: Any, i: int) -> Any:
        return None if np.isnan(column[i]).all() else column[i].copy()

    def gather(self, values: list[Any]) -> Any:
        return None if any(v is None for v in values) else np.array(values, float)


# --------------------------------------------------------------------------- readers
@dataclass(frozen=True)
class CsvContext:
    """What a column's reader needs besides the table: the joint count and, to check the
    joints' limits, the model (``check_limits``)."""

    n_joints: int
    model: Any = None
    check_limits: bool = True


def _line_error(t: CsvTable, r: int, column: str, message: str) -> DataError:
    return DataError(f"{t.source}: line {t.lines[r]}, column {column}: {message}")


def _read_pose_id(t: CsvTable, ctx: CsvContext, got: dict[str, Any]) -> dict[str, Any]:
    return {"pose_id": t.ids("pose_id")}


def _read_q(t: CsvTable, ctx: CsvContext, got: dict[str, Any]) -> dict[str, Any]:
    model = ctx.n_joints if ctx.model is None else ctx.model
    return {"q": np.radians(t.joints_deg(model, ctx.check_limits))}


def _lengths(t: CsvTable, names: list[str]) -> np.ndarray:
    """Columns ``names`` as an (n, len(names)) array of plausible lengths (mm)."""
    v = np.column_stack([t.numeric(c) for c in names])
    for k, c in enumerate(names):
        t.within(c, v[:, k], -MAX_LENGTH_MM, MAX_LENGTH_MM, PLAUSIBLE_LENGTH)
    return v


def _read_xyz(t: CsvTable, ctx: CsvContext, got: dict[str, Any]) -> dict[str, Any]:
    return {"tracker_p_smr": _lengths(t, ["x", "y", "z"])}


def _read_cmd(t: CsvTable, ctx: CsvContext, got: dict[str, Any]) -> dict[str, Any]:
    names = ["cmd_x", "cmd_y", "cmd_z"]
    if any(c in t for c in names) and not all(c in t for c in names):
        raise t.error("cmd_x, cmd_y, cmd_z must come together")
    return {"cmd": _lengths(t, names) if "cmd_x" in t else None}


def _read_float(name: str, *, rule: tuple[Callable, str] | None = None,
                ranged: bool = False) -> Callable:
    """A reader of the optional float column ``name``: numeric, then ``rule`` (a test of
    bad values and what they must be), then its plausible range (:data:`OPTIONAL_RANGES`)."""

    def read(t: CsvTable, ctx: CsvContext, got: dict[str, Any]) -> dict[str, Any]:
        if name not in t:
            return {name: None}
        v = t.numeric(name)
        if rule is not None and rule[0](v).any():
            r = int(np.argmax(rule[0](v)))
            raise _line_error(t, r, name, rule[1])
        if ranged:
            lo, hi, what = OPTIONAL_RANGES[name]
            t.within(name, v, lo, hi, what)
        return {name: v}

    return read


def _read_reflector(t: CsvTable, ctx: CsvContext, got: dict[str, Any]) -> dict[str, Any]:
    if "reflector" not in t:
        return {"reflector": None}
    reflector = np.array(t.text("reflector"), dtype=object)
    if (reflector == "").any():
        raise _line_error(t, int(np.argmax(reflector == "")), "reflector", "empty value")
    return {"reflector": reflector}


def _read_face(t: CsvTable, ctx: CsvContext, got: dict[str, Any]) -> dict[str, Any]:
    if "face" not in t:
        return {"face": None}
    face = t.numeric("face")
    bad = ~np.isin(face, (1.0, 2.0))
    if bad.any():
        r = int(np.argmax(bad))
        raise _line_error(t, r, "face", f"{face[r]:g} is neither 1 nor 2")
    return {"face": face.astype(int)}


def read_dirs(t: CsvTable, ctx: CsvContext, got: dict[str, Any]) -> dict[str, Any]:
    """``dir1..dirN`` (all or none), each -1, 0 or +1, as an (n, N) int array."""
    names = [f"dir{j + 1}" for j in range(ctx.n_joints)]
    if not t.all_or_none(names, "direction columns"):
        return {"dirs": None}
    dirs = np.column_stack([t.numeric(c) for c in names])
    bad = ~np.isin(dirs, (-1.0, 0.0, 1.0))
    if bad.any():
        r, j = map(int, np.argwhere(bad)[0])
        raise _line_error(t, r, f"dir{j + 1}", f"{dirs[r, j]:g} is not -1, 0 or +1")
    return {"dirs": dirs.astype(int)}


def read_joint_temp(t: CsvTable, ctx: CsvContext, got: dict[str, Any]) -> dict[str, Any]:
    """``joint_temp1..N`` (°C, all or none), shape (n, N); refuses a part, a column beyond
    the model's joints and an implausible temperature."""
    n_joints = ctx.n_joints
    extra = [h for h in t.header if h.startswith("joint_temp") and h[10:].isdigit()
             and not 1 <= int(h[10:]) <= n_joints]
    if extra:
        raise t.error(f"column(s) {', '.join(extra)} but the model has {n_joints} joints")
    names = [f"joint_temp{j + 1}" for j in range(n_joints)]
    if not t.all_or_none(names, "joint temperatures"):
        return {"joint_temp": None}
    lo, hi, what = OPTIONAL_RANGES["temp_c"]
    for c in names:
        t.within(c, t.numeric(c), lo, hi, what)
    return {"joint_temp": np.column_stack([t.numeric(c) for c in names])}


def _read_quat(t: CsvTable, ctx: CsvContext, got: dict[str, Any]) -> dict[str, Any]:
    return {"quat": read_quaternions(t)}


def _read_sigma_deg(t: CsvTable, ctx: CsvContext, got: dict[str, Any]) -> dict[str, Any]:
    return {"sigma_deg": read_sigma_deg(t, got.get("quat") is not None)}


def _read_tool_id(t: CsvTable, ctx: CsvContext, got: dict[str, Any]) -> dict[str, Any]:
    return {"tool_id": read_tool_ids(t)}


def _read_set(t: CsvTable, ctx: CsvContext, got: dict[str, Any]) -> dict[str, Any]:
    is_valid, is_drift = np.zeros(len(t), bool), np.zeros(len(t), bool)
    if "set" in t:
        for r, v in enumerate(t.text("set")):
            if v not in ("calib", "valid", "drift", ""):
                raise _line_error(t, r, "set", f"{v!r} is not 'calib', 'valid' or 'drift'")
            is_valid[r], is_drift[r] = v == "valid", v == "drift"
    return {"is_valid": is_valid, "is_drift": is_drift}


# --------------------------------------------------------------------------- writers
def _write_q(data: Dataset) -> dict[str, Any]:
    return {f"q{j + 1}": np.degrees(data.q[:, j]) for j in range(data.n_joints)}


def _write_set(data: Dataset) -> dict[str, Any]:
    if not (data.is_valid.any() or data.is_drift is not None):
        return {}
    return {"set": np.where(data.is_valid, "valid",
                            np.where(data.drift_rows(), "drift", "calib"))}


def _sets_to_dataset(values: list[Any]) -> dict[str, Any]:
    sets = ["calib" if v is None else v for v in values]
    return {"is_valid": np.array([v == "valid" for v in sets], bool),
            "is_drift": np.array([v == "drift" for v in sets], bool)}


# ---------------------------------------------------------------------------- table
@dataclass(frozen=True)
class Column:
    """One per-point quantity (see the module docstring).

    Attributes
    ----------
    name : the name in code: the Dataset's field (when in ``dataset``) and the store
        record's (``daq.store.Sample``, when ``record``)
    unit, doc : the unit in code ("" when none) and what it is, in one line
    kind : how it is stored and stacked (:class:`Kind`)
    csv : its CSV column(s); ``{j}`` in a name spreads it over the joints (1-based)
    store : its store column(s) in the ``samples`` table (SQL type ``kind.sql``)
    since : the store schema version that added ``store``
    reading : a rejected reading keeps it too (the ``readings`` table)
    dataset : the Dataset field(s) it fills (two for ``set``: ``is_valid``, ``is_drift``)
    record : a field of the store's record of a point (and of a run's ``Samples``)
    required : the CSV must have it
    read, write : the CSV reader (``read(table, ctx, got) -> {field: values}``) and
        writer (``write(dataset) -> {csv column: values}``; the default writes the
        Dataset field over ``csv``)
    to_dataset : the Dataset's field(s) from the records' values (default: all or none,
        :meth:`Kind.gather`)
    reason : why the CSV's or the store's name differs from ``name``, or why a place
        does not hold it
    """

    name: str
    unit: str
    doc: str
    kind: Kind = field(default_factory=Real)
    csv: tuple[str, ...] = ()
    store: tuple[str, ...] = ()
    since: int = 0
    reading: bool = False
    dataset: tuple[str, ...] = ()
    record: bool = True
    required: bool = False
    read: Callable | None = None
    write: Callable | None = None
    to_dataset: Callable | None = None
    reason: str = ""

    def csv_names(self, n_joints: int) -> list[str]:
        """The CSV columns for a robot of ``n_joints`` joints."""
        out = []
        for name in self.csv:
            if "{j}" in name:
                out += [name.format(j=j + 1) for j in range(n_joints)]
            else:
                out.append(name)
        return out

    # ---- the store
    def encode(self, value: Any) -> tuple:
        """A record's value as the values of :attr:`store` (in that order)."""
        return self.kind.encode(value)

    def decode(self, row: Mapping) -> Any:
        """The record's value from a row read by name (a mapping of column to value)."""
        return self.kind.decode(row, self.store)

    # ---- the CSV
    def write_csv(self, data: Dataset) -> dict:
        """The CSV columns of ``data`` (a Dataset) for this quantity ({} when absent)."""
        if self.write is not None:
            return self.write(data)
        if not self.csv or not self.dataset:
            return {}
        v = getattr(data, self.dataset[0])
        if v is None:
            return {}
        if len(self.csv) == 1 and "{j}" not in self.csv[0]:  # one value per point
            return {self.csv[0]: v}
        if isinstance(self.kind, JointList) and self.kind.dtype is int:
            v = np.asarray(v).astype(int)
        return {c: v[:, k] for k, c in enumerate(self.csv_names(data.n_joints))}

    def read_csv(self, table: CsvTable, ctx: CsvContext, got: dict) -> dict:
        """This quantity's Dataset field(s) from a CSV table ({} when it has no reader)."""
        return {} if self.read is None else self.read(table, ctx, got)

    # ---- the records
    def gather(self, values: list) -> dict:
        """The Dataset's field(s) from the records' values (one per point)."""
        if self.to_dataset is not None:
            return self.to_dataset(values)
        return {self.dataset[0]: self.kind.gather(values)}


#: every per-point quantity; CSV columns are written in this order (docs/formats.md §1)
COLUMNS: tuple[Column, ...] = (
    Column("point_index", "", "the point's index in the capture's plan", Int(),
           store=("point_index",), since=1, reading=True,
           reason="the store's key of a point; not a Dataset field (pose_id names a row)"),
    Column("pose_id", "", "a label, unique within a file", Text(
        default=lambda row: str(int(row["point_index"]) + 1)),
        csv=("pose_id",), store=("pose_id",), since=1, dataset=("pose_id",),
        read=_read_pose_id),
    Column("q", "rad", "the joints as the controller reported them",
           JointList(float, nullable=False), csv=("q{j}",), store=("q_json",), since=1,
           reading=True, dataset=("q",), required=True, read=_read_q, write=_write_q,
           reason="the CSV has one column per joint, in deg (q1..qN); the store one JSON "
                  "list in rad (q_json, released at schema 1)"),
    Column("tracker_p_smr", "mm", "the measured target (SMR) centre in the tracker frame",
           Vector(3, nullable=False), csv=("x", "y", "z"), store=("x", "y", "z"), since=1,
           reading=True, dataset=("tracker_p_smr",), required=True, read=_read_xyz,
           reason="named by the frames convention in code (ARCHITECTURE.md, Frames); the "
                  "CSV and the store give its three axes (x, y, z), the contract's names"),
    Column("cmd", "mm", "the controller's own (nominal) TCP position, base frame", Vector(3),
           csv=("cmd_x", "cmd_y", "cmd_z"), store=("cmd_x", "cmd_y", "cmd_z"), since=2,
           reading=True, dataset=("cmd",), read=_read_cmd,
           reason="a vector: its three axes are the CSV's and the store's columns"),
    Column("temp_c", "°C", "temperature (ambient or robot)", Real(), csv=("temp_c",),
           store=("temp_c",), since=1, reading=True, dataset=("temp_c",),
           read=_read_float("temp_c", ranged=True)),
    Column("t_s", "s", "time of the measurement (epoch)", Real(), csv=("t_s",), store=("t",),
           since=1, reading=True, dataset=("t_s",), read=_read_float("t_s"),
           reason="the store's column t was released at schema 1: never renamed"),
    Column("payload_kg", "kg", "payload mass for that pose, overrides the model's",
           csv=("payload_kg",), dataset=("payload_kg",), record=False,
           read=_read_float("payload_kg", ranged=True),
           reason="given in a file only: a capture does not record it"),
    Column("sigma_mm", "mm", "the tracker's standard uncertainty of the point, per axis",
           csv=("sigma_mm",), dataset=("sigma_mm",), record=False,
           read=_read_float("sigma_mm", rule=(lambda v: v <= 0, "must be positive"),
                            ranged=True),
           reason="not stored: the export derives it from std_mm (and n_averaged), as "
                  "--sigma-mode says (daq.run_data)"),
    Column("pressure_hpa", "hPa", "air pressure at the measurement", csv=("pressure_hpa",),
           store=("pressure_hpa",), since=2, reading=True, dataset=("pressure_hpa",),
           read=_read_float("pressure_hpa", rule=(lambda v: v <= 0, "must be positive"))),
    Column("humidity_pct", "%", "relative humidity at the measurement",
           csv=("humidity_pct",), store=("humidity_pct",), since=2, reading=True,
           dataset=("humidity_pct",),
           read=_read_float("humidity_pct", rule=(lambda v: (v < 0) | (v > 100),
                                                  "must be within 0..100"))),
    Column("reflector", "", "the reflector type measured (e.g. RRR1.5)", Text(),
           csv=("reflector",), store=("reflector",), since=4, reading=True,
           dataset=("reflector",), read=_read_reflector),
    Column("face", "", "the tracker face of the measurement: 1 or 2",
           Int(missing=None, zero_is_none=True), csv=("face",), store=("face",), since=4,
           reading=True, dataset=("face",), read=_read_face),
    Column("dirs", "", "the direction each joint approached the pose from: -1, 0 or +1",
           JointList(int), csv=("dir{j}",), store=("dir_json",), since=2, reading=True,
           dataset=("dirs",), read=read_dirs,
           reason="one value per joint: dir1..dirN in the CSV, one JSON list in the store "
                  "(dir_json, released at schema 2)"),
    Column("joint_temp", "°C", "each joint's temperature as the controller reports it",
           JointList(float), csv=("joint_temp{j}",), store=("joint_temp_json",), since=9,
           reading=True, dataset=("joint_temp",), read=read_joint_temp,
           reason="one value per joint: joint_temp1..N in the CSV, one JSON list in the "
                  "store (joint_temp_json, released at schema 9)"),
    Column("quat", "", "a 6-DoF target's orientation: unit quaternion (w, x, y, z) of the "
           "target frame in the tracker frame", Vector(4), csv=QUAT_COLUMNS,
           store=QUAT_COLUMNS, since=9, reading=True, dataset=("quat",), read=_read_quat,
           reason="a vector: its four parts, scalar first, are the CSV's and the store's "
                  "columns"),
    Column("sigma_deg", "deg", "the tracker's standard uncertainty of the orientation",
           csv=("sigma_deg",), store=("sigma_deg",), since=9, reading=True,
           dataset=("sigma_deg",), read=_read_sigma_deg),
    Column("tool_id", "", "which target on the tool was measured, when a pose measures "
           "several", Text(), csv=("tool_id",), store=("tool_id",), since=9, reading=True,
           dataset=("tool_id",), read=_read_tool_id),
    Column("set_name", "", "calib, valid or drift (a capture's drift checks)",
           Text(default="calib"), csv=("set",), store=("set_name",), since=1,
           dataset=("is_valid", "is_drift"), read=_read_set, write=_write_set,
           to_dataset=_sets_to_dataset,
           reason="the CSV's set (the contract) is an SQL keyword, so the store says "
                  "set_name; the Dataset keeps it as two masks (is_valid, is_drift) for "
                  "selecting rows"),
    Column("target", "", "the plan's target of the point (JSON)", JsonDoc(),
           store=("target_json",), since=1,
           reason="the capture's own record: not in a measurement file; stored as JSON"),
    Column("std_mm", "mm", "the tracker's per-axis standard deviation of the reading",
           Vector(3, nullable=False), store=("sx", "sy", "sz"), since=1, reading=True,
           reason="the store's own: the export turns it into sigma_mm; sx, sy, sz are "
                  "its axes, released at schema 1"),
    Column("n_averaged", "", "how many tracker samples the reading averaged", Int(),
           store=("n",), since=1, reading=True,
           reason="the store's column n was released at schema 1: never renamed"),
    Column("attempts", "", "tries the point took (faults retried)", Int(missing=1),
           store=("attempts",), since=2, reason="the capture's own record"),
    Column("joints_t", "s", "when the joints were read (epoch)", store=("joints_t",),
           since=2, reason="the capture's own record"),
    Column("cov_mm2", "mm²", "the covariance of tracker_p_smr", Covariance(),
           store=("cov_xx", "cov_xy", "cov_xz", "cov_yy", "cov_yz", "cov_zz"), since=4,
           reading=True, reason="a symmetric matrix: its upper triangle's six columns"),
    Column("verdict", "", "how the reading was judged (daq.remeasure.VERDICTS)", Text(),
           store=("verdict",), since=6, reason="the capture's own record"),
    Column("remeasures", "", "re-measurements made at the point", Int(), store=("remeasures",),
           since=6, reason="the capture's own record"),
    Column("model_residual_mm", "mm", "distance from the running model's prediction",
           store=("model_residual_mm",), since=6, reading=True,
           reason="the capture's own record"),
    Column("model_threshold_mm", "mm", "the re-measure threshold at the point",
           store=("model_threshold_mm",), since=6, reading=True,
           reason="the capture's own record"),
    Column("lines", "", "the file line of each row (0: not from a file)", dataset=("lines",),
           record=False, reason="where a row came from, not a measured quantity"),
    Column("reading", "", "accepted or rejected: one of every reading of a capture",
           csv=("reading",), record=False,
           reason="written by cellcal export --all-readings (from verdict and the readings "
                  "table); the reader leaves rejected rows out, so no Dataset field"),
    Column("reason", "", "why a reading was rejected (or how the accepted one was judged)",
           csv=("reason",), record=False,
           reason="written by cellcal export --all-readings (the readings table's reason, "
                  "the verdict's note); informative, not read back"),
)

#: the table by name
BY_NAME: dict[str, Column] = {c.name: c for c in COLUMNS}
#: the quantities of the store's record of a point (``daq.store.Sample``)
RECORD: tuple[Column, ...] = tuple(c for c in COLUMNS if c.record)
#: the store columns of a point (``samples``) and of a rejected reading (``readings``)
SAMPLE_COLUMNS: tuple[Column, ...] = tuple(c for c in RECORD if c.store)
READING_COLUMNS: tuple[Column, ...] = tuple(c for c in SAMPLE_COLUMNS if c.reading)
#: what the measurement CSV's reader reads, required ones first
CSV_READ: tuple[Column, ...] = (tuple(c for c in COLUMNS if c.required and c.read)
                                + tuple(c for c in COLUMNS if not c.required and c.read))


def column(name: str) -> Column:
    """The table's entry ``name`` (``KeyError`` naming the known ones)."""
    try:
        return BY_NAME[name]
    except KeyError:
        raise KeyError(f"no per-point column {name!r}; known: {', '.join(BY_NAME)}") from None


def store_columns(columns: tuple[Column, ...]) -> list[str]:
    """The store columns of ``columns``, in order."""
    return [s for c in columns for s in c.store]


def encode_row(record: Any, columns: tuple[Column, ...]) -> list:
    """A record's values for the store columns of ``columns`` (:func:`store_columns`)."""
    return [v for c in columns for v in c.encode(getattr(record, c.name))]


def decode_row(row: Mapping) -> dict:
    """The record's fields from a row read by name: every quantity whose store columns
    the row has (a rejected reading's row lacks the point's own record)."""
    return {c.name: c.decode(row) for c in SAMPLE_COLUMNS if all(s in row for s in c.store)}
