"""The calibrated envelope: where the calibration data were measured, and which poses lie
beyond it.

A calibration is known only where it was measured. :class:`Envelope` is the range each
joint covered in the calibration rows (deg, as the measurement CSV's ``q1..qN``; mm for a
prismatic joint), and the range of each quantity a drift effect reads where the model
has one: the air temperature (``temp_c``: ``thermal``), the joint temperatures
(``joint_temp1..N``: ``thermal_growth``, ``thermal_zero:J``) and the time (``t_s``:
``time_growthK``, ``base_driftK``). params.json records it (``envelope``,
:meth:`Envelope.to_json`; a version of its own, :data:`ENVELOPE_VERSION`) and every
prediction names the quantities that lie beyond it (:meth:`Envelope.outside`): a
compensated target's ``outside_range``, the validation statistics split inside and
outside (:func:`split_stats`).

A value is inside when it lies within the range widened by :data:`EDGE_TOL` (the
rounding of a CSV's or a params.json's decimal degrees).

The table effects' knot support (:func:`supported_model`) belongs here too: a table is
fitted only over the knots its calibration rows support (``Table.supported_knots``),
constant beyond them, whatever range it was named with.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from ..data.dataset import Dataset
from ..effects.table import Table
from ..errors import OutsideEnvelope, ParamsError
from .error_model import ErrorModel
from .identify import Fit, error_stats, identify

#: the version of the ``envelope`` record written; readers take 1..ENVELOPE_VERSION
ENVELOPE_VERSION = 1
#: a value within this of the envelope's edge (deg, °C, s) is inside it
EDGE_TOL = 1e-6
#: the families that read each drift quantity (the quantity is part of the envelope
#: only when the model has one of them)
_QUANTITY_FAMILIES = {"temp_c": {"thermal"},
                      "joint_temp": {"thermal_growth", "thermal_zero"},
                      "t_s": {"time_growth", "base_drift"}}


def _range(v: np.ndarray) -> tuple[float, float]:
    return float(np.min(v)), float(np.max(v))


@dataclass(frozen=True)
class Envelope:
    """The ranges the calibration rows covered.

    Attributes
    ----------
    joints_deg : per joint (lo, hi), deg (mm for a prismatic joint)
    temp_c : (lo, hi) °C of the air temperature, when a model effect reads it, else None
    joint_temp_c : per joint (lo, hi) °C, when a model effect reads them, else None
    t_s : (lo, hi) s, when a model effect reads the time, else None
    n_poses : the calibration rows it was taken from
    """

    joints_deg: tuple[tuple[float, float], ...]
    temp_c: tuple[float, float] | None = None
    joint_temp_c: tuple[tuple[float, float], ...] | None = None
    t_s: tuple[float, float] | None = None
    n_poses: int = 0

    # ---- construction ------------------------------------------------------------
    @classmethod
    def of_data(cls, data: Dataset, error_model: ErrorModel | None = None) -> Envelope:
        """The envelope of ``data``'s rows (all of them: give the calibration rows); the
        drift quantities only where ``error_model`` has an effect that reads them (every
        quantity the data have without a model)."""
        families = None if error_model is None else {e.family for e in error_model.effects}

        def wanted(key: str) -> bool:
            return families is None or bool(families & _QUANTITY_FAMILIES[key])

        deg = np.degrees(data.q)
        joints = tuple(_range(deg[:, j]) for j in range(deg.shape[1]))
        temp = (_range(data.temp_c) if data.temp_c is not None and wanted("temp_c")
                else None)
        jt = (tuple(_range(data.joint_temp[:, j]) for j in range(data.joint_temp.shape[1]))
              if data.joint_temp is not None and wanted("joint_temp") else None)
        t = _range(data.t_s) if data.t_s is not None and wanted("t_s") else None
        return cls(joints, temp, jt, t, int(data.n))

    @classmethod
    def of_fit(cls, fit: Fit) -> Envelope:
        """The envelope of a fit's calibration rows (the blunders it left out are not
        measurements of the robot, and are not in it)."""
        return cls.of_data(fit.data, fit.error_model)

    # ---- params.json ---------------------------------------------------------------
    def to_json(self) -> dict:
        """The ``envelope`` record of params.json."""
        out: dict = {"version": ENVELOPE_VERSION, "n_poses": self.n_poses,
                     "joints_deg": [list(r) for r in self.joints_deg]}
        if self.temp_c is not None:
            out["temp_c"] = list(self.temp_c)
        if self.joint_temp_c is not None:
            out["joint_temp_c"] = [list(r) for r in self.joint_temp_c]
        if self.t_s is not None:
            out["t_s"] = list(self.t_s)
        return out

    @classmethod
    def from_json(cls, rec: Any, n_joints: int, source: str) -> Envelope | None:
        """The ``envelope`` record read back strictly (ParamsError naming the file and key);
        None for a file written before envelopes were recorded."""
        if rec is None:
            return None
        where = f"{source}: envelope"
        if not isinstance(rec, dict):
            raise ParamsError(f"{where}: not an object")
        version = rec.get("version")
        if not isinstance(version, int) or isinstance(version, bool) or version < 1:
            raise ParamsError(f"{where}.version: {version!r} is not a version number")
        if version > ENVELOPE_VERSION:
            raise ParamsError(f"{where}.version: {version} is newer than this cellcal reads "
                              f"({ENVELOPE_VERSION}); update cellcal")

        def pair(v: Any, key: str) -> tuple[float, float]:
            if (not isinstance(v, list) or len(v) != 2
                    or not all(isinstance(a, (int, float)) and not isinstance(a, bool)
                               and math.isfinite(a) for a in v) or v[0] > v[1]):
                raise ParamsError(f"{where}.{key}: {v!r} is not a range [lo, hi] of two "
                                  "finite numbers, lo <= hi")
            return float(v[0]), float(v[1])

        def pairs(v: Any, key: str) -> tuple[tuple[float, float], ...]:
            if not isinstance(v, list) or len(v) != n_joints:
                raise ParamsError(f"{where}.{key}: expected {n_joints} ranges, one per joint")
            return tuple(pair(r, f"{key}.{j}") for j, r in enumerate(v))

        n = rec.get("n_poses", 0)
        if not isinstance(n, int) or isinstance(n, bool) or n < 0:
            raise ParamsError(f"{where}.n_poses: {n!r} is not a count")
        if "joints_deg" not in rec:
            raise ParamsError(f"{where}: joints_deg missing")
        return cls(pairs(rec["joints_deg"], "joints_deg"),
                   pair(rec["temp_c"], "temp_c") if rec.get("temp_c") is not None else None,
                   pairs(rec["joint_temp_c"], "joint_temp_c")
                   if rec.get("joint_temp_c") is not None else None,
                   pair(rec["t_s"], "t_s") if rec.get("t_s") is not None else None, n)

    # ---- which values lie beyond it ------------------------------------------------------
    def outside(self, q: np.ndarray, columns: dict | None = None) -> tuple[np.ndarray, list[str]]:
        """Which values of each pose lie beyond the envelope.

        Parameters
        ----------
        q : (n, N) joints, rad
        columns : per-pose quantities (``temp_c`` (n,), ``joint_temp`` (n, N) °C, ``t_s``
            (n,) s), those given; a quantity the envelope does not hold is not checked

        Returns
        -------
        (n, k) bool, and the k names of the columns checked (``q1..qN``, ``temp_c``,
        ``joint_temp1..N``, ``t_s``, as in the measurement CSV)
        """
        columns = columns or {}
        deg = np.degrees(np.atleast_2d(np.asarray(q, float)))
        blocks, names = [self._beyond(deg, self.joints_deg)], [
            f"q{j + 1}" for j in range(len(self.joints_deg))]
        if self.temp_c is not None and columns.get("temp_c") is not None:
            blocks.append(self._beyond(np.asarray(columns["temp_c"], float)[:, None],
                                       (self.temp_c,)))
            names.append("temp_c")
        if self.joint_temp_c is not None and columns.get("joint_temp") is not None:
            blocks.append(self._beyond(np.asarray(columns["joint_temp"], float),
                                       self.joint_temp_c))
            names += [f"joint_temp{j + 1}" for j in range(len(self.joint_temp_c))]
        if self.t_s is not None and columns.get("t_s") is not None:
            blocks.append(self._beyond(np.asarray(columns["t_s"], float)[:, None], (self.t_s,)))
            names.append("t_s")
        return np.hstack(blocks), names

    @staticmethod
    def _beyond(v: np.ndarray, ranges: Any) -> np.ndarray:
        r = np.asarray(ranges, float)
        return np.asarray((v < r[:, 0] - EDGE_TOL) | (v > r[:, 1] + EDGE_TOL))

    def outside_names(self, q: np.ndarray, columns: dict | None = None) -> list[list[str]]:
        """Per pose, the names of the values beyond the envelope (empty inside)."""
        mask, names = self.outside(q, columns)
        return [[names[k] for k in np.flatnonzero(row)] for row in mask]

    def of_data_outside(self, data: Dataset) -> np.ndarray:
        """(n,) bool: the rows of ``data`` with any value beyond the envelope."""
        return np.asarray(self.outside(data.q, data_columns(data))[0].any(axis=1))

    def lines(self) -> list[str]:
        """The envelope in words, one quantity a line (deg, °C, s)."""
        out = [", ".join(f"q{j + 1} {lo:.1f}..{hi:.1f}"
                         for j, (lo, hi) in enumerate(self.joints_deg)) + " deg"]
        if self.temp_c is not None:
            out.append(f"temp_c {self.temp_c[0]:.1f}..{self.temp_c[1]:.1f} °C")
        if self.joint_temp_c is not None:
            out.append(", ".join(f"joint_temp{j + 1} {lo:.1f}..{hi:.1f}"
                                 for j, (lo, hi) in enumerate(self.joint_temp_c)) + " °C")
        if self.t_s is not None:
            out.append(f"t_s {self.t_s[0]:.0f}..{self.t_s[1]:.0f} s "
                       f"({self.t_s[1] - self.t_s[0]:.0f} s of capture)")
        return out


#: the per-pose quantities of a target an envelope checks (as in Targets.columns)
_CHECKED = ("temp_c", "joint_temp", "t_s")


def outside_envelope(envelope: Envelope | None, q: np.ndarray, columns: dict | None = None
                     ) -> list[list[str]]:
    """Per target, the quantities beyond ``envelope`` (``q2``, ``joint_temp3``, ``t_s``...;
    empty inside): the joints ``q`` (rad, (n, N): those the robot will be sent) and the
    thermal state the targets give (``columns``); all empty without an envelope."""
    if envelope is None:
        return [[] for _ in range(len(q))]
    cols = {k: v for k, v in (columns or {}).items() if k in _CHECKED}
    return envelope.outside_names(q, cols)


def refuse_outside(outside: list[list[str]], labels: list[str], what: str, source: str
                   ) -> None:
    """Strict range: refuse (:class:`~calibration.errors.OutsideEnvelope`, exit 3) when any
    target lies beyond the envelope, naming them (``labels``: one per target; ``what``:
    "targets", "waypoints"; ``source``: the file)."""
    bad = [i for i, names in enumerate(outside) if names]
    if not bad:
        return
    rows = [f"{labels[i]}: {', '.join(outside[i])}" for i in bad[:10]]
    more = f"; and {len(bad) - 10} more" if len(bad) > 10 else ""
    raise OutsideEnvelope(
        f"{source}: {len(bad)} of {len(outside)} {what} lie beyond the calibrated envelope "
        f"(the ranges the calibration data covered): {'; '.join(rows)}{more}. Refused "
        "(--strict-range): calibrate with data that cover them, or leave --strict-range out "
        "to compensate them with the calibration held at its edge (flagged in "
        "outside_range)")


def data_columns(data: Dataset) -> dict:
    """The per-pose quantities of ``data`` an envelope checks (those it has)."""
    return {k: getattr(data, k) for k in ("temp_c", "joint_temp", "t_s")
            if getattr(data, k, None) is not None}


def count_by_name(mask: np.ndarray, names: list[str]) -> dict[str, int]:
    """How many poses lie beyond the envelope in each quantity (those with any)."""
    counts = mask.sum(axis=0)
    return {n: int(c) for n, c in zip(names, counts, strict=True) if c}


def split_stats(envelope: Envelope, data: Dataset, residuals: np.ndarray) -> dict:
    """Error statistics of ``data``'s rows (``residuals`` (n, 3) mm) inside and outside the
    envelope: ``{"inside": stats, "outside": stats + {"by_quantity": {"q2": 12, ...}}}``
    (:func:`~calibration.fit.identify.error_stats`)."""
    mask, names = envelope.outside(data.q, data_columns(data))
    out_rows = mask.any(axis=1)
    outside = error_stats(residuals[out_rows])
    outside["by_quantity"] = count_by_name(mask, names)
    return {"inside": error_stats(residuals[~out_rows]), "outside": outside}


# ---- the table effects' knot support -----------------------------------------------------
def supported_model(error_model: ErrorModel, calib: Dataset) -> tuple[ErrorModel, list[str]]:
    """``error_model`` with every table (any effect with ``supported_knots``) limited to the
    knots the calibration rows ``calib`` support (``Table.supported_knots``: constant beyond
    them); the same object when none changes. Notes name a table whose named range was
    cut (a table named without a range covers the data: nothing to say)."""
    effects, notes, changed = list(error_model.effects), [], False
    for i, e in enumerate(effects):
        if not isinstance(e, Table):
            continue
        new = e.supported_knots(calib.q[:, e.joint - 1])
        if new is e:
            continue
        changed = True
        if getattr(e, "explicit_range", False):
            notes.append(f"{e.label}: its knots are cut to {new.knots_deg[0]:g}.."
                         f"{new.knots_deg[-1]:g} deg, the range the calibration data support "
                         "(the table holds its edge value beyond)")
        effects[i] = new
    if not changed:
        return error_model, []
    return ErrorModel(error_model.model, effects), notes


def values_by_name(source: ErrorModel, x: np.ndarray, target: ErrorModel,
                   start: np.ndarray) -> np.ndarray:
    """``start`` (a parameter vector of ``target``) with every parameter ``source`` has by
    the same name taken from ``x``."""
    out = np.array(start, float)
    index = {n: k for k, n in enumerate(source.names)}
    for k, name in enumerate(target.names):
        if name in index:
            out[k] = x[index[name]]
    return out


def identify_supported(error_model: ErrorModel, data: Dataset, solver: str = "lm", *,
                       x0: np.ndarray | None = None, **kw: Any) -> tuple[Fit, list[str]]:
    """:func:`~calibration.fit.identify.identify` with every table over the knots its
    calibration rows support (:func:`supported_model`). When the fit leaves blunders out and
    the rows it kept support other knots, it is refitted over those (warm-started): a
    blunder is no measurement of the robot. ``x0`` is a parameter vector of
    ``error_model`` (mapped by name). Returns (fit, notes)."""
    calib = data.calib() if data.is_valid.any() else data
    em, notes = supported_model(error_model, calib)
    if x0 is not None and em is not error_model:
        x0 = values_by_name(error_model, x0, em, em.initial(em.bind(calib)))
    fit = identify(em, data, solver, x0=x0, **kw)
    if fit.outliers is not None and fit.outliers.excluded:
        em2, notes2 = supported_model(error_model, fit.data)
        if em2.names != em.names:
            start = em2.initial(em2.bind(fit.data))
            fit = identify(em2, data, solver, x0=values_by_name(em, fit.values, em2, start),
                           **kw)
            notes = notes2
    return fit, notes
