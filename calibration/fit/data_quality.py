"""Is a data set good enough to identify an error model? Refuse, do not fit, when not.

:func:`check_for_fit` raises :class:`InsufficientData` (exit 3 at the command line) with
the reason and what to capture instead when

- there are no calibration rows (every row is ``set=valid``);
- the joint values look like radians in the degree columns (every joint of every pose
  within ±2π while the model allows far more);
- there are fewer independent observations than identifiable parameters: 3 per
  *distinct* pose (poses whose joints agree within :data:`SAME_POSE_DEG` count once, so
  a hundred repeats of one pose are one pose);
- the design is rank-deficient: the poses leave parameters undetermined that a spread
  of poses over the same joint ranges would determine (the poses vary too little, or
  only together): a parameter of the core families (geometric, base, tool) or most of
  another effect's (a few knots of a correction table are only held, with a note).

What "identifiable" means here is structural: the analysis of
:func:`calibration.fit.identify.structural_identifiability` on a reference sample of poses
drawn uniformly within the data's own joint ranges (with the data's other columns), so
a cell that cannot use the whole workspace is judged against what it can reach.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace

import numpy as np

from ..data.dataset import Dataset
from ..effects import EffectError
from ..errors import InsufficientData
from ..model.kinematics import tool_points
from ..model.robot_model import RobotModel
from .error_model import ErrorModel
from .identifiability import Identifiability
from .identify import structural_identifiability

#: joints that agree within this (deg) on every axis are the same pose
SAME_POSE_DEG = 0.05
#: the largest |q| (deg) of a data set whose joints are really radians
RADIANS_MAX = 2 * math.pi + 1e-6
#: the reference sample for the observation count moves every joint at least this (deg)
MIN_SPAN_DEG = 30.0
#: the data's pivot threshold for a parameter to count as lost (looser than identify's
#: 1e-3: only parameters the poses leave (nearly) exactly undetermined)
LOST_RTOL = 1e-4


@dataclass
class DataVerdict:
    """What :func:`check_for_fit` found in data it accepted."""

    n_poses: int
    n_distinct: int
    n_identifiable: int
    notes: list[str] = field(default_factory=list)


def distinct_poses(q_rad: np.ndarray, tol_deg: float = SAME_POSE_DEG) -> int:
    """How many different joint configurations (within ``tol_deg`` on every joint)."""
    if len(q_rad) == 0:
        return 0
    cells = np.round(np.degrees(q_rad) / tol_deg).astype(np.int64)
    return int(np.unique(cells, axis=0).shape[0])


def looks_like_radians(q_rad: np.ndarray, limits_rad: np.ndarray) -> bool:
    """True when every joint value written in degrees lies within ±2π although the model's
    limits span far more: joints given in radians where degrees belong."""
    if len(q_rad) < 3:
        return False
    q_deg = np.degrees(q_rad)
    span_deg = np.degrees(limits_rad[:, 1] - limits_rad[:, 0])
    moving = np.ptp(q_deg, axis=0) > 1e-9
    return bool(np.all(np.abs(q_deg) <= RADIANS_MAX) and moving.any()
                and np.all(span_deg[moving] > 4 * RADIANS_MAX))


def reference_sample(error_model: ErrorModel, calib: Dataset, n: int, seed: int = 0,
                     min_span_deg: float = 0.0) -> Dataset:
    """Poses uniform within the data's joint ranges (each widened to at least
    ``min_span_deg`` within the limits), other columns resampled from the data's rows,
    measured by the nominal model: what a well-spread capture in the same cell gives."""
    rng = np.random.default_rng(seed)
    lo, hi = calib.q.min(axis=0), calib.q.max(axis=0)
    if min_span_deg > 0:
        half = np.radians(min_span_deg) / 2
        mid = (lo + hi) / 2
        lim = error_model.model.limits_rad()
        lo = np.maximum(np.minimum(lo, mid - half), lim[:, 0])
        hi = np.minimum(np.maximum(hi, mid + half), lim[:, 1])
    q = rng.uniform(lo, hi, size=(n, calib.n_joints))
    rows = rng.integers(0, calib.n, size=n)
    # every per-row column resampled (Dataset.subset), then the poses replaced: a column
    # left at the data's length (joint temperatures, orientations) would make the sample
    # inconsistent, and the checks that use it silently skipped
    return replace(calib.subset(rows), q=q, tracker_p_smr=tool_points(error_model.model, q),
                   pose_id=[f"r{i}" for i in range(n)], cmd=None, is_valid=np.zeros(n, bool),
                   lines=np.zeros(n, int), source="reference sample")


#: families whose every parameter the poses must determine (the core of every model)
CORE_FAMILIES = ("geometric", "base", "tool")


def _design_broken(error_model: ErrorModel, lost: list[int], free_ref: np.ndarray) -> bool:
    """A rank deficiency refuses the fit when it takes a parameter of the core families,
    or most of some effect's parameters (an effect the data cannot see at all); a few
    knots of a correction table without independent data are only held (a note)."""
    for e, sl in zip(error_model.effects, error_model.slices, strict=True):
        idx = set(range(sl.start, sl.stop))
        gone = len(idx & set(lost))
        if not gone:
            continue
        if e.family in CORE_FAMILIES:
            return True
        if gone * 2 > int(free_ref[sl].sum()):
            return True
    return False


def refuse_radians(data: Dataset, model: RobotModel) -> None:
    """InsufficientData (exit 3) when ``data``'s joints look like radians
    (:func:`looks_like_radians`) for ``model``."""
    if looks_like_radians(data.q, model.limits_rad()):
        raise InsufficientData(
            f"{data.source}: every joint value lies within ±{RADIANS_MAX:.2f}: they look like "
            f"radians, but q1..q{model.n_joints} are degrees (docs/formats.md §1); convert "
            "them (deg = rad × 180/π) and run again")


def check_for_fit(error_model: ErrorModel, data: Dataset) -> DataVerdict:
    """Raise :class:`InsufficientData` when ``data`` cannot identify ``error_model`` (see the
    module docstring); else what was found (with notes on marginal data)."""
    src = data.source
    if data.n and bool(np.all(data.is_valid)):
        raise InsufficientData(
            f"{src}: no calibration poses: all {data.n} rows are set=valid (validation); "
            "mark the poses to fit with set=calib, or leave the set column empty")
    calib = data.calib() if data.is_valid.any() else data
    if calib.n == 0:
        raise InsufficientData(f"{src}: no calibration poses")
    refuse_radians(calib, error_model.model)
    n_distinct = distinct_poses(calib.q)
    prepared = error_model.prepare(data)
    calib_p = prepared.calib() if prepared.is_valid.any() else prepared
    n_ref = max(3 * error_model.n_params, 60)

    def reference(min_span_deg: float) -> Identifiability | None:
        try:
            ref = reference_sample(error_model, calib_p, n_ref, min_span_deg=min_span_deg)
            return structural_identifiability(error_model, error_model.prepare(ref))[2]
        except (EffectError, ValueError, np.linalg.LinAlgError):
            return None

    # the count: against poses that do move (a pose repeated is still one pose)
    ident_wide = reference(MIN_SPAN_DEG)
    p = ident_wide.n_identifiable if ident_wide is not None else error_model.n_params
    same = (f" ({calib.n} poses, but only {n_distinct} distinct: joints within "
            f"{SAME_POSE_DEG}° count as one pose)" if n_distinct < calib.n else "")
    if 3 * n_distinct <= p:
        need = p // 3 + 1
        raise InsufficientData(
            f"{src}: {n_distinct} distinct calibration pose(s){same} give "
            f"{3 * n_distinct} independent observations for {p} identifiable parameters of "
            f"{','.join(error_model.labels)}; capture at least {need} distinct poses "
            f"(better {max(3 * need, 50)}), spread over the joint ranges")
    notes = []
    # the rank: against poses over the data's own ranges (what this cell can reach)
    ident_ref = reference(0.0)
    if ident_ref is not None:
        _, _, ident = structural_identifiability(error_model, calib_p, rtol=LOST_RTOL)
        lost = [k for k in range(error_model.n_params)
                if ident_ref.free[k] and not ident.free[k]]
        if lost:
            names = [error_model.names[k] for k in lost]
            shown = ", ".join(names[:6]) + (f" and {len(names) - 6} more" if len(names) > 6
                                            else "")
            if _design_broken(error_model, lost, ident_ref.free):
                raise InsufficientData(
                    f"{src}: rank-deficient design: these {n_distinct} distinct poses{same} "
                    f"cannot determine {shown}, which poses spread over the same joint "
                    "ranges would; capture more poses that vary every joint independently "
                    "(or drop the effect)")
            notes.append(f"these poses cannot determine {shown} (poses spread over the same "
                         "joint ranges would): held at their start values")
    redundancy = 3 * n_distinct - p
    if redundancy < p:
        notes.append(f"only {redundancy} observations beyond the {p} parameters "
                     f"({n_distinct} distinct poses): the fit is barely checked by the data; "
                     f"{max(p, 50)}+ poses are usual")
    if n_distinct < calib.n:
        notes.append(f"{calib.n - n_distinct} of {calib.n} calibration poses repeat another "
                     f"pose (joints within {SAME_POSE_DEG}°)")
    return DataVerdict(calib.n, n_distinct, p, notes)
