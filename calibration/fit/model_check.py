"""A given model against new measurements: :func:`check_model`.

A plant's monthly question, *is the robot still as accurate as its calibration says?*,
asks for the calibrated model's error on poses it has never seen, with nothing refitted:
every pose's error and their statistics (:func:`~calibration.fit.identify.error_stats`,
the figures a calibration gives its validation rows, computed the same way: at the
parameters, on the rows as they are, no blunder left out).

One thing only may be refitted: the tracker-to-base transform (the ``base`` effect),
because it is not the robot's. When the tracker stands elsewhere than at the calibration
the new data are in another measurement frame, and the robot's accuracy is what remains
after the rigid transform between the frames is fitted (:func:`check_model` with
``refit_base``; a least-squares fit of the base's six parameters, every other one held).
:func:`frame_change` tells from what two captures recorded of their measurement frame
(``tracker_T_base`` of the files' metadata, :class:`~calibration.data.capture_meta.CaptureMeta`)
whether they are in the same one.

Given the calibrated envelope (:class:`~calibration.fit.envelope.Envelope`, the ranges the
calibration rows covered), :func:`check_model` names per pose the quantities beyond it
(``outside``) and splits the statistics inside and outside it
(:func:`~calibration.fit.envelope.split_stats`, as ``calibrate`` splits its validation rows).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ..data.capture_meta import CaptureMeta
from ..data.dataset import Dataset
from ..effects.geometric import Base
from ..errors import InsufficientData
from ..model.transforms import fit_rigid, matrix_to_rotvec, quat_to_matrix, rotvec_to_matrix
from .envelope import Envelope, data_columns, split_stats
from .error_model import ErrorModel
from .identify import error_stats
from .orientation_residuals import orientation_stats, rotation_residuals

#: two recorded measurement frames farther apart than this (the base origin, mm, or the
#: rotation, deg) are two frames: the tracker was moved (a frame routine repeated with the
#: tracker in place agrees to a few hundredths of a mm and of a degree)
FRAME_TOLERANCE_MM = 1.0
FRAME_TOLERANCE_DEG = 0.1
#: Gauss-Newton rounds of the base refit after its rigid start
BASE_REFIT_ROUNDS = 20


@dataclass(frozen=True)
class FrameVerdict:
    """Whether new data are in the calibration's measurement frame.

    ``same`` True, False, or None when either side recorded no frame (then the
    calibration's is assumed); ``reason`` says why in a sentence's worth of words;
    ``distance_mm``, ``angle_deg``: how far apart the two recorded frames are (None when
    not compared).
    """

    same: bool | None
    reason: str
    distance_mm: float | None = None
    angle_deg: float | None = None


def _frame_name(meta: CaptureMeta) -> str:
    if meta.frame_run is None:
        return "a frame"
    return f"frame run {meta.frame_run}" + (f" of {meta.store}" if meta.store else "")


def frame_change(calibration: CaptureMeta, data: CaptureMeta) -> FrameVerdict:
    """Compare the measurement frames a calibration's capture and new data recorded.

    The same frame run of the same store is the same frame; otherwise the two
    ``tracker_T_base`` are compared: beyond :data:`FRAME_TOLERANCE_MM` or
    :data:`FRAME_TOLERANCE_DEG` apart they are two frames (the tracker moved).
    """
    Tc, Td = calibration.tracker_T_base, data.tracker_T_base
    if Td is None or Tc is None:
        if Td is None and Tc is None:
            what = "neither the data nor the calibration recorded a measurement frame"
        else:
            who = "the data" if Td is None else "the calibration"
            what = f"{who} recorded no measurement frame"
        return FrameVerdict(None, f"{what}: the calibration's is assumed (--refit-base when "
                            "the tracker was moved)")
    if (calibration.frame_run is not None and calibration.frame_run == data.frame_run
            and calibration.store == data.store):
        return FrameVerdict(True, f"the calibration's ({_frame_name(data)})", 0.0, 0.0)
    Tc, Td = np.asarray(Tc, float), np.asarray(Td, float)
    dist = float(np.linalg.norm(Tc[:3, 3] - Td[:3, 3]))
    angle = float(np.degrees(np.linalg.norm(matrix_to_rotvec(Tc[:3, :3].T @ Td[:3, :3]))))
    apart = f"{dist:.3f} mm and {angle:.4f} deg from the calibration's ({_frame_name(calibration)})"
    if dist > FRAME_TOLERANCE_MM or angle > FRAME_TOLERANCE_DEG:
        return FrameVerdict(False, f"{_frame_name(data)} of the data is {apart}: the tracker "
                            "was moved", dist, angle)
    return FrameVerdict(True, f"{_frame_name(data)} of the data is within {apart}", dist, angle)


@dataclass
class ModelCheck:
    """The result of :func:`check_model`.

    Attributes
    ----------
    error_model : the model checked
    values : (p,) the parameters the errors are of (the given ones; with the base
        refitted, its six replaced), internal units
    given : (p,) the parameters as given
    data : the poses checked (as the model prepared them)
    residuals : (n, 3) measured minus predicted, mm
    errors : (n,) their lengths, mm
    stats : :func:`~calibration.fit.identify.error_stats` of ``residuals`` (and, for a
        model of a 6-DoF target's orientation on data with orientations, the orientation
        keys of :func:`~calibration.fit.orientation_residuals.orientation_stats`)
    refitted : the effects whose parameters were refitted on these poses (``["base"]``
        or empty)
    base_shift_mm, base_turn_deg : how far the refitted base moved from the given one
        (its origin, mm; its rotation, deg), None without a refit
    orientation_residuals : (n, 3) rad, or None
    notes : remarks on what was and was not compared
    envelope : the calibrated envelope the poses were compared with, or None
    outside : per pose, the quantities beyond ``envelope`` (``q2``, ``t_s``...; empty
        inside), None without an envelope
    split : :func:`~calibration.fit.envelope.split_stats` of the residuals (``inside``,
        ``outside`` with ``by_quantity``), None without an envelope
    """

    error_model: ErrorModel
    values: np.ndarray
    given: np.ndarray
    data: Dataset
    residuals: np.ndarray
    errors: np.ndarray
    stats: dict
    refitted: list[str] = field(default_factory=list)
    base_shift_mm: float | None = None
    base_turn_deg: float | None = None
    orientation_residuals: np.ndarray | None = field(default=None, repr=False)
    notes: list[str] = field(default_factory=list)
    envelope: Envelope | None = None
    outside: list[list[str]] | None = field(default=None, repr=False)
    split: dict | None = None

    def worst_index(self, k: int = 5, beyond_mm: float | None = None) -> np.ndarray:
        """The rows of the ``k`` largest errors, largest first; with ``beyond_mm`` only
        those larger than it."""
        order = np.argsort(-self.errors, kind="stable")
        if beyond_mm is not None:
            order = order[self.errors[order] > beyond_mm]
        return order[:k]

    def worst(self, k: int = 5, beyond_mm: float | None = None) -> list[tuple[str, int, float]]:
        """The ``k`` largest errors, largest first, as (pose id, file line, error mm);
        with ``beyond_mm`` only those larger than it."""
        return [(str(self.data.pose_id[i]), int(self.data.lines[i]), float(self.errors[i]))
                for i in self.worst_index(k, beyond_mm)]

    def outside_of(self, i: int) -> list[str]:
        """The quantities of pose ``i`` beyond the envelope (empty inside or without one)."""
        return [] if self.outside is None else list(self.outside[i])

    @property
    def n_outside(self) -> int:
        """How many poses lie beyond the envelope (0 without one)."""
        return 0 if self.outside is None else sum(1 for names in self.outside if names)

    def n_beyond(self, tolerance_mm: float) -> int:
        """How many poses miss by more than ``tolerance_mm``."""
        return int(np.count_nonzero(self.errors > tolerance_mm))


def base_effect(error_model: ErrorModel) -> tuple[Base, np.ndarray] | None:
    """The model's ``base`` effect and the indices of its parameters, or None."""
    for e, sl in zip(error_model.effects, error_model.slices, strict=True):
        if isinstance(e, Base):
            return e, np.arange(sl.start, sl.stop)
    return None


def check_model(error_model: ErrorModel, values: np.ndarray, data: Dataset, *,
                refit_base: bool = False, envelope: Envelope | None = None) -> ModelCheck:
    """The error of the model ``(error_model, values)`` on ``data``, every row (a ``set``
    column is not looked at: every pose is new to the model).

    ``envelope``: the calibrated envelope; each pose's quantities beyond it are named
    (:meth:`Envelope.outside_names`) and the statistics split inside and outside it
    (:func:`~calibration.fit.envelope.split_stats`).

    ``refit_base``: fit the tracker-to-base transform (the ``base`` effect's six
    parameters) to these poses first, every other parameter held; ValueError for a model
    without a ``base`` effect, :class:`~calibration.errors.InsufficientData` when the
    poses cannot determine it (fewer than three points not on one line).
    """
    given = np.asarray(values, float).copy()
    x = given.copy()
    data = error_model.prepare(data)
    bound = error_model.bind(data)
    refitted: list[str] = []
    shift = turn = None
    if refit_base:
        found = base_effect(error_model)
        if found is None:
            raise ValueError(f"the model ({','.join(error_model.labels)}) has no base effect "
                             "to refit")
        effect, idx = found
        x = _refit_base(error_model, x, bound, idx)
        refitted.append(effect.label)
        R0, t0 = effect.transform(given[idx])
        R1, t1 = effect.transform(x[idx])
        shift = float(np.linalg.norm(t1 - t0))
        turn = float(np.degrees(np.linalg.norm(matrix_to_rotvec(R0.T @ R1))))
    P = error_model.evaluate(x, bound, False)[0]
    resid = data.tracker_p_smr - P
    stats = error_stats(resid)
    ores = None
    notes = []
    if data.quat is not None:
        if any(e.stage == "target" for e in error_model.effects):
            R = error_model.evaluate_pose(x, bound, jacobian=False)[2]
            ores = rotation_residuals(quat_to_matrix(data.quat), R)
            stats.update(orientation_stats(ores))
        else:
            notes.append("the data have orientations, but the calibration did not fit the "
                         "target's orientation (no tool_rotation effect): positions only "
                         "are checked")
    errors = np.linalg.norm(resid, axis=1)
    outside = split = None
    if envelope is not None:
        outside = envelope.outside_names(data.q, data_columns(data))
        split = split_stats(envelope, data, resid)
    return ModelCheck(error_model, x, given, data, resid, errors, stats, refitted, shift, turn,
                      ores, notes, envelope, outside, split)


def _refit_base(em: ErrorModel, x: np.ndarray, bound: Any, idx: np.ndarray) -> np.ndarray:
    """``x`` with the base parameters (``idx``) fitted to the bound data by least squares:
    a rigid fit of the predictions onto the measurements first (any distance, any
    rotation), then Gauss-Newton on the six parameters (exact with effects acting after
    the base: a drift of the base, the tracker's scale)."""
    data = bound.data
    M = data.tracker_p_smr
    if data.n < 3:
        raise InsufficientData(f"{data.source}: {data.n} pose(s): the base (tracker-to-robot "
                               "transform) needs at least three points not on one line")
    x = x.copy()
    effect = em.effect_of(int(idx[0]))
    assert isinstance(effect, Base)
    P = em.evaluate(x, bound, False)[0]
    R, c = fit_rigid(P, M)  # M ~ R P + c, P = Rb p + tb
    Rb, tb = effect.transform(x[idx])
    x[idx] = np.concatenate([R @ tb + c, matrix_to_rotvec(R @ Rb)])
    scales = np.asarray(em.scales, float)[idx]
    for _ in range(BASE_REFIT_ROUNDS):
        P, J = em.evaluate(x, bound, True)
        A = J[:, :, idx].reshape(3 * data.n, -1) / scales  # scaled columns
        sv = np.linalg.svd(A, compute_uv=False)
        if sv[-1] <= 1e-9 * sv[0]:
            raise InsufficientData(f"{data.source}: the poses do not determine the base "
                                   "(tracker-to-robot transform): they lie on one line")
        step = np.linalg.lstsq(A, (M - P).ravel(), rcond=None)[0] / scales
        x[idx] += step
        if float(np.max(np.abs(step / scales))) < 1e-10:
            break
    # the rotation vector kept within pi (the same rotation)
    x[idx[3:]] = matrix_to_rotvec(rotvec_to_matrix(x[idx[3:]]))
    return x
