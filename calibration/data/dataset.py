"""Measured poses: :class:`Dataset` and the measurement CSV of docs/formats.md §1.

The reader is strict: a missing required column, a non-numeric value, a NaN, a
duplicated ``pose_id``, a bad ``set``/``dirJ``/``face`` value, an empty
``reflector`` or a joint outside the model's limits is refused with a
:class:`DataError` naming the file, the line and the column. Nothing is guessed.
"""

from __future__ import annotations

import csv
import io
import math
from collections.abc import Sequence
from dataclasses import Field, dataclass, field, fields, replace
from pathlib import Path
from typing import Any

import numpy as np

from ..errors import DataError
from ..files import TextLines, write_atomic
from ..model.robot_model import RobotModel
from .capture_meta import CaptureMeta
from .columns import (
    COLUMNS,
    CSV_READ,
    MAX_LENGTH_MM,
    OPTIONAL_RANGES,
    PLAUSIBLE_LENGTH,
    CsvContext,
)

__all__ = ["MAX_LENGTH_MM", "OPTIONAL_RANGES", "PLAUSIBLE_LENGTH", "CsvTable", "DataError",
           "Dataset", "load_csv", "read_meta"]

#: a field of one value per point (``subset``/``concat`` select and join them); each is a
#: quantity of the column table (:mod:`calibration.data.columns`)
PER_POINT = {"per_point": True}
#: a per-point field whose None means "False on every row" (``is_drift``)
PER_POINT_FALSE = {"per_point": True, "absent": False}


def _per_point(metadata: dict[str, Any] = PER_POINT) -> Any:
    """A per-point field, None by default (typed as its field says: ``is_valid`` and
    ``lines`` are arrays once a Dataset is made, see ``__post_init__``)."""
    return field(default=None, metadata=metadata)


@dataclass
class Dataset:
    """Measured poses, vectorised. Angles in rad, lengths in mm.

    Attributes
    ----------
    q : (n, N) joint positions reported by the controller, rad
    tracker_p_smr : (n, 3) measured target (SMR) centre in the tracker frame, mm
        (the CSV's ``x, y, z``)
    pose_id : list of n labels
    cmd : (n, 3) controller's nominal TCP position (base frame, mm), or None
    temp_c, t_s, payload_kg, sigma_mm : (n,) or None
    pressure_hpa, humidity_pct : (n,) the air at each measurement (hPa, %RH), or None
    reflector : (n,) str (object array), the reflector measured, or None
    face : (n,) int, the tracker face (1 or 2), or None
    dirs : (n, N) approach direction per joint (-1, 0, +1), or None
    joint_temp : (n, N) each joint's temperature as the controller reports it, °C, or None
    quat : (n, 4) unit quaternions (w, x, y, z) of a 6-DoF target's frame in the tracker
        frame (the CSV's ``qw, qx, qy, qz``), or None
    sigma_deg : (n,) the orientation's standard uncertainty, deg, or None
    tool_id : (n,) str (object array), which target on the tool each row measured, or None
    is_valid : (n,) bool, True for validation rows (``set=valid``)
    is_drift : (n,) bool, True for a capture's drift checks (``set=drift``: a reference
        pose measured again during the capture; calibration rows that also show the
        drift over time), or None when there are none
    meta : ``# key: value`` metadata from the file's first comment lines
    source : where the data came from (a path or a description)
    lines : (n,) file line number of each row (0 when not from a file)
    """

    q: np.ndarray = field(metadata=PER_POINT)
    tracker_p_smr: np.ndarray = field(metadata=PER_POINT)
    pose_id: list[str] = field(default_factory=list, metadata=PER_POINT)
    cmd: np.ndarray | None = _per_point()
    temp_c: np.ndarray | None = _per_point()
    t_s: np.ndarray | None = _per_point()
    payload_kg: np.ndarray | None = _per_point()
    sigma_mm: np.ndarray | None = _per_point()
    pressure_hpa: np.ndarray | None = _per_point()
    humidity_pct: np.ndarray | None = _per_point()
    reflector: np.ndarray | None = _per_point()
    face: np.ndarray | None = _per_point()
    dirs: np.ndarray | None = _per_point()
    is_valid: np.ndarray = _per_point()  # None: no validation row
    joint_temp: np.ndarray | None = _per_point()
    is_drift: np.ndarray | None = _per_point(PER_POINT_FALSE)
    quat: np.ndarray | None = _per_point()
    sigma_deg: np.ndarray | None = _per_point()
    tool_id: np.ndarray | None = _per_point()
    meta: dict[str, str] = field(default_factory=dict)
    source: str = "<arrays>"
    lines: np.ndarray = _per_point()  # None: not read from a file (zeros)

    def __post_init__(self) -> None:
        self.q = np.atleast_2d(np.asarray(self.q, float))
        self.tracker_p_smr = np.atleast_2d(np.asarray(self.tracker_p_smr, float))
        n = self.q.shape[0]
        if self.tracker_p_smr.shape != (n, 3):
            raise DataError(f"{self.source}: tracker_p_smr has shape "
                            f"{self.tracker_p_smr.shape}, expected ({n}, 3)")
        if not self.pose_id:
            self.pose_id = [str(i + 1) for i in range(n)]
        if self.is_valid is None:
            self.is_valid = np.zeros(n, bool)
        if self.lines is None:
            self.lines = np.zeros(n, int)
        if self.is_drift is not None:
            self.is_drift = np.asarray(self.is_drift, bool)
            if not self.is_drift.any():
                self.is_drift = None
        if self.reflector is not None:
            self.reflector = np.array([str(r) for r in self.reflector], dtype=object)
        if self.face is not None:
            self.face = np.asarray(self.face, int)
        if self.joint_temp is not None:
            self.joint_temp = np.atleast_2d(np.asarray(self.joint_temp, float))
            if self.joint_temp.shape != self.q.shape:
                raise DataError(f"{self.source}: joint_temp has shape {self.joint_temp.shape}, "
                                f"expected {self.q.shape} (one temperature per joint)")
        if self.quat is not None:
            self.quat = np.atleast_2d(np.asarray(self.quat, float))
            if self.quat.shape != (n, 4):
                raise DataError(f"{self.source}: quat has shape {self.quat.shape}, expected "
                                f"({n}, 4) (qw, qx, qy, qz per row)")
        if self.tool_id is not None:
            self.tool_id = np.array([str(t) for t in self.tool_id], dtype=object)

    # ---- views -----------------------------------------------------------
    @property
    def n(self) -> int:
        return self.q.shape[0]

    @property
    def n_joints(self) -> int:
        return self.q.shape[1]

    @classmethod
    def per_point_fields(cls) -> list[str]:
        """The fields holding one value per point (see :data:`PER_POINT`)."""
        return [f.name for f in fields(cls) if f.metadata.get("per_point")]

    def subset(self, mask_or_index: np.ndarray | Sequence[int] | Sequence[bool]) -> Dataset:
        """Rows selected by a boolean mask or an index array (order kept)."""
        idx = np.arange(self.n)[mask_or_index]

        def pick(a: Any) -> Any:  # a per-point field's value: an array, a list or None
            if a is None:
                return None
            return a[idx] if isinstance(a, np.ndarray) else [a[i] for i in idx.tolist()]

        return replace(self, **{f: pick(getattr(self, f)) for f in self.per_point_fields()})

    def drift_rows(self) -> np.ndarray:
        """(n,) bool: the drift checks (``set=drift``), all False when there are none."""
        return np.zeros(self.n, bool) if self.is_drift is None else self.is_drift

    def calib(self) -> Dataset:
        return self.subset(~self.is_valid)

    def valid(self) -> Dataset:
        return self.subset(self.is_valid)

    def sigma(self) -> float | None:
        """The tracker's standard uncertainty per axis (mm), if known."""
        if self.sigma_mm is not None and self.n:
            return float(np.sqrt(np.mean(self.sigma_mm**2)))
        v = self.meta.get("tracker_sigma_mm")
        return float(v) if v is not None else None

    def with_tracker_sigma(self, sigma_mm: float) -> Dataset:
        """This data set with the tracker's standard uncertainty per axis, mm, set to
        ``sigma_mm`` for every point (a user's ``--sigma`` over the file's): the per-point
        ``sigma_mm`` column is dropped and the capture metadata says it, so :meth:`sigma`,
        the noise floor and :attr:`capture` (kept in params.json) agree. The value is kept
        exactly (shortest round-trip text, as :func:`calibration.fit.simulate.simulate` writes).

        Raises
        ------
        DataError
            ``sigma_mm`` is not a positive finite number.
        """
        sigma_mm = float(sigma_mm)
        if not (sigma_mm > 0 and math.isfinite(sigma_mm)):
            raise DataError(f"{self.source}: tracker sigma {sigma_mm!r} mm is not a positive "
                            "number")
        return replace(self, sigma_mm=None,
                       meta={**self.meta, "tracker_sigma_mm": repr(sigma_mm)})

    @property
    def capture(self) -> CaptureMeta:
        """What the file's metadata says about its capture (tool, frame, run...)."""
        return CaptureMeta.from_meta(self.meta, self.source)

    def noise_floor_mm(self) -> float | None:
        """RMS of the 3-D measurement error the instrument alone causes: sqrt(3) sigma."""
        s = self.sigma()
        return None if s is None else math.sqrt(3.0) * s

    def concat(self, other: Dataset) -> Dataset:
        """This data set followed by ``other`` (columns missing in either become None)."""

        def cat(f: Field[Any], a: Any, b: Any) -> Any:  # as pick in subset
            if a is None and b is None:
                return None
            if a is None or b is None:
                if "absent" not in f.metadata:
                    return None
                a = np.full(self.n, f.metadata["absent"]) if a is None else a
                b = np.full(other.n, f.metadata["absent"]) if b is None else b
            if isinstance(a, np.ndarray):
                return np.concatenate([a, b])
            return [*a, *b]

        return Dataset(**{f.name: cat(f, getattr(self, f.name), getattr(other, f.name))
                          for f in fields(self) if f.metadata.get("per_point")},
                       meta={**other.meta, **self.meta}, source=self.source)

    # ---- writing -----------------------------------------------------------
    def to_csv(self, path: str | Path | None = None, extra: dict | None = None) -> str:
        """Write the measurement CSV (deg, mm); returns the text, writes it when a path is
        given. ``extra``: more columns (name -> n values), written last."""
        cols: dict[str, np.ndarray | list] = {}
        for c in COLUMNS:  # the table's order (docs/formats.md §1)
            cols.update(c.write_csv(self))
        cols.update(extra or {})
        buf = io.StringIO()
        for key, text in self.meta.items():
            buf.write(f"# {key}: {text}\n")
        w = csv.writer(buf, lineterminator="\n")
        w.writerow(cols.keys())
        w.writerows(zip(*(_column_text(c) for c in cols.values()), strict=True))
        text = buf.getvalue()
        if path is not None:
            write_atomic(path, text)
        return text


def _column_text(c: Any) -> list[str]:
    """The CSV text of a column's values: floats at full precision (``repr``), integers
    as integers, anything else as ``str``; a numeric array converted at once."""
    kind = getattr(getattr(c, "dtype", None), "kind", "")
    if kind == "f":
        return list(map(repr, np.asarray(c, float).tolist()))
    if kind in "iu" and kind:
        return list(map(str, np.asarray(c).tolist()))
    out: list[str] = []
    for v in c:
        if isinstance(v, (float, np.floating)):
            out.append(repr(float(v)))
        elif isinstance(v, (np.integer,)):
            out.append(str(int(v)))
        else:
            out.append(str(v))
    return out


# ---- reading ----------------------------------------------------------------
#: the largest CSV file read (bytes) and the longest field (characters)
MAX_CSV_BYTES = 500 << 20
MAX_FIELD_CHARS = 1000
#: the metadata lines read_meta looks at, at most
_META_LINES = 200


def read_meta(path: str | Path) -> dict[str, str]:
    """The ``# key: value`` metadata at the top of a CSV file (before the header), without
    reading the rows: e.g. to find the model a measurement file was captured with.
    An unreadable file gives ``{}`` (reading it for real says why)."""
    meta: dict[str, str] = {}
    try:
        if not Path(path).is_file():  # a folder, /dev/zero, a FIFO: reading it says why
            return {}
        with open(path, encoding="utf-8") as fh:
            for _ in range(_META_LINES):
                line = fh.readline(MAX_FIELD_CHARS * 4)
                if not line:
                    break
                stripped = line.strip()
                if not stripped:
                    continue
                if not stripped.startswith("#"):
                    break
                body = stripped[1:].strip()
                if ":" in body:
                    k, v = body.split(":", 1)
                    meta[k.strip()] = v.strip()
    except (OSError, UnicodeDecodeError):
        return {}
    return meta


_Rows = tuple[dict[str, str], list[str], int, list[tuple[int, list[str]]]]


def _read_rows(path: Path, source: str) -> _Rows:
    """Metadata, header, its line number and the data rows as (line_no, fields); the file
    is read a block at a time (:class:`calibration.files.TextLines`), never held whole."""
    lines = TextLines(path, DataError, "CSV file", MAX_CSV_BYTES)
    try:
        return _parse_rows(lines, source)
    except DataError:
        lines.check_rest()  # an encoding error anywhere in the file is said first
        raise


def _parse_rows(lines: TextLines, source: str) -> _Rows:
    meta: dict[str, str] = {}
    meta_line: dict[str, int] = {}
    header = None
    header_line = 0
    rows: list[tuple[int, list[str]]] = []
    in_preamble = True
    plain = csv.field_size_limit()  # below it, a line without quotes is split on commas
    for line_no, line in lines:
        stripped = line.strip()
        if not stripped:
            continue
        if stripped.startswith("#"):
            body = stripped[1:].strip()
            if in_preamble and ":" in body:
                k, v = body.split(":", 1)
                k = k.strip()
                if k in meta and meta[k] != v.strip():
                    raise DataError(f"{source}: line {line_no}: metadata {k} given twice "
                                    f"(line {meta_line[k]}: {meta[k]!r}, here: {v.strip()!r})")
                meta[k], meta_line[k] = v.strip(), line_no
            continue
        in_preamble = False
        if '"' not in line and len(line) <= plain:
            fields = line.split(",")  # what csv.reader gives a line without quotes
        else:
            try:
                fields = next(csv.reader([line]))
            except csv.Error as e:
                raise DataError(f"{source}: line {line_no}: {e}") from None
        for f in fields:
            if len(f) > MAX_FIELD_CHARS:
                raise DataError(f"{source}: line {line_no}: a field of {len(f)} characters "
                                f"(at most {MAX_FIELD_CHARS}): not a measurement CSV")
        if header is None:
            header = [f.strip() for f in fields]
            header_line = line_no
            _check_separator(header, source, line_no)
            continue
        rows.append((line_no, [f.strip() for f in fields]))
    if header is None:
        raise DataError(f"{source}: empty: no header row (comma-separated values with a "
                        "header, docs/formats.md §1)")
    return meta, header, header_line, rows


def _check_separator(header: list[str], source: str, line_no: int) -> None:
    """Refuse a header that is one field holding semicolons or tabs (another separator)."""
    if len(header) != 1:
        return
    for sep, name in ((";", "semicolons (';')"), ("\t", "tabs")):
        if sep in header[0]:
            raise DataError(f"{source}: line {line_no}: the fields are separated by {name}; "
                            "cellcal reads comma-separated values with '.' as the decimal "
                            "point (docs/formats.md §1)")


def _float(source: str, line_no: int, col: str, text: str) -> float:
    try:
        v = float(text)
    except ValueError:
        raise DataError(f"{source}: line {line_no}, column {col}: not a number: {text!r}") from None
    if not math.isfinite(v):
        raise DataError(f"{source}: line {line_no}, column {col}: {text!r} is not a finite number")
    return v


class CsvTable:
    """A CSV file read strictly, for every table format of docs/formats.md §1.

    Reading refuses a file with no header, duplicated columns or a row whose field
    count differs from the header's; :meth:`require` refuses missing columns and a
    file without data rows; the accessors refuse
    empty or non-numeric values, NaNs, duplicated ids and joints outside the limits.
    Every message names the file, the line and the column.
    """

    def __init__(self, path: str | Path) -> None:
        self.path = Path(path)
        self.source = str(self.path)
        self.meta, self.header, self.header_line, rows = _read_rows(self.path, self.source)
        dupes = {h for h in self.header if self.header.count(h) > 1}
        if dupes:
            raise self.error(f"duplicated column(s) {sorted(dupes)}")
        for line_no, f in rows:
            if len(f) != len(self.header):
                raise DataError(f"{self.source}: line {line_no}: {len(f)} fields, the header "
                                f"has {len(self.header)}")
        self.rows = rows
        self.col = {h: i for i, h in enumerate(self.header)}
        self.lines = np.array([ln for ln, _ in rows])

    def __len__(self) -> int:
        return len(self.rows)

    def __contains__(self, name: str) -> bool:
        return name in self.col

    def error(self, message: str) -> DataError:
        """An error about the header line."""
        return DataError(f"{self.source}: line {self.header_line}: {message}")

    def keep(self, rows: np.ndarray) -> None:
        """Keep only the data rows where ``rows`` (bool, one per row) is True."""
        self.rows = [r for r, k in zip(self.rows, rows, strict=True) if k]
        self.lines = self.lines[np.asarray(rows, bool)]

    def require(self, names: list[str], hint: str = "") -> None:
        """Refuse a file without these columns, or (then) without data rows."""
        missing = [c for c in names if c not in self.col]
        if missing:
            raise self.error(f"missing required column(s) {', '.join(missing)}"
                             + (f" ({hint})" if hint else ""))
        if not self.rows:
            raise DataError(f"{self.source}: no data rows")

    def all_or_none(self, names: list[str], what: str) -> bool:
        """True when all of ``names`` are present, False when none is; refuses a part."""
        present = [c for c in names if c in self.col]
        if present and len(present) != len(names):
            missing = [c for c in names if c not in self.col]
            raise self.error(f"{what} need all of {names[0]}..{names[-1]}; missing "
                             f"{', '.join(missing)}")
        return bool(present)

    def text(self, name: str) -> list[str]:
        k = self.col[name]
        return [f[k] for _, f in self.rows]

    def numeric(self, name: str) -> np.ndarray:
        k = self.col[name]
        out = np.empty(len(self.rows))
        for r, (line_no, f) in enumerate(self.rows):
            if f[k] == "":
                raise DataError(f"{self.source}: line {line_no}, column {name}: empty value")
            out[r] = _float(self.source, line_no, name, f[k])
        return out

    def within(self, name: str, values: np.ndarray, lo: float, hi: float, what: str) -> None:
        """Refuse a value of column ``name`` outside [lo, hi] (``what``: the expected form)."""
        bad = (values < lo) | (values > hi)
        if bad.any():
            r = int(np.argmax(bad))
            raise DataError(f"{self.source}: line {self.lines[r]}, column {name}: {values[r]:g} "
                            f"is not {what}")

    def ids(self, name: str = "pose_id") -> list[str]:
        """Unique, non-empty labels from a column (``1..n`` when the column is absent)."""
        if name not in self.col:
            return [str(i + 1) for i in range(len(self.rows))]
        seen: dict[str, int] = {}
        out = []
        for line_no, f in self.rows:
            pid = f[self.col[name]]
            if pid == "":
                raise DataError(f"{self.source}: line {line_no}, column {name}: empty value")
            if pid in seen:
                raise DataError(f"{self.source}: line {line_no}, column {name}: {pid!r} already "
                                f"used on line {seen[pid]}")
            seen[pid] = line_no
            out.append(pid)
        return out

    def joints_deg(self, model: RobotModel | int, check_limits: bool = True) -> np.ndarray:
        """``q1..qN`` (deg), shape (n, N); refuses extra joint columns and, with a model,
        values outside its limits."""
        N = model if isinstance(model, int) else model.n_joints
        extra = [h for h in self.header if h.startswith("q") and h[1:].isdigit()
                 and int(h[1:]) > N]
        if extra:
            raise self.error(f"column(s) {', '.join(extra)} but the model has {N} joints")
        q = np.column_stack([self.numeric(f"q{j + 1}") for j in range(N)])
        if not isinstance(model, int) and check_limits:
            lim = np.array([[j.min, j.max] for j in model.joints])
            bad = (q < lim[:, 0] - 1e-9) | (q > lim[:, 1] + 1e-9)
            if bad.any():
                r, j = map(int, np.argwhere(bad)[0])
                raise DataError(
                    f"{self.source}: line {self.lines[r]}, column q{j + 1}: {q[r, j]:g} deg is "
                    f"outside the model's limits [{lim[j, 0]:g}, {lim[j, 1]:g}] of joint {j + 1} "
                    f"({int(bad.any(axis=1).sum())} row(s) affected)"
                )
        return q


def load_csv(path: str | Path, model: RobotModel | int, *, check_limits: bool = True) -> Dataset:
    """Read a measurement CSV (docs/formats.md §1). Rows whose ``reading`` is ``rejected``
    (readings a capture did not accept) are left out.

    Parameters
    ----------
    path : the CSV file
    model : the robot model (its joint count and limits are checked), or a joint count
    check_limits : refuse joints outside the model's limits (only with a model)
    """
    t = CsvTable(path)
    source = t.source
    if "reading" in t:  # every reading of a run (cellcal export --all-readings)
        values = t.text("reading")
        for r, v in enumerate(values):
            if v not in ("accepted", "rejected", ""):
                raise DataError(f"{source}: line {t.lines[r]}, column reading: {v!r} is "
                                "neither 'accepted' nor 'rejected'")
        t.keep(np.array([v != "rejected" for v in values]))
    N = model if isinstance(model, int) else model.n_joints
    required = [name for c in COLUMNS if c.required for name in c.csv_names(N)]
    t.require(required, f"the model has {N} joints: q1..q{N}, and x, y, z are required")
    ctx = CsvContext(N, None if isinstance(model, int) else model, check_limits)
    got: dict = {}
    for c in CSV_READ:  # the required columns first, then the table's order
        got.update(c.read_csv(t, ctx, got))
    meta = t.meta
    CaptureMeta.from_meta(meta, source)  # refuses malformed capture metadata now
    return Dataset(**got, meta=meta, source=source, lines=t.lines)

