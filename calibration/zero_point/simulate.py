"""Simulated zero-point postures: a true robot whose joint zeros moved, taught by hand
onto one target (with the teaching scatter), as the controller records them.

Lengths mm, angles rad.
"""

from __future__ import annotations

import numpy as np

from ..model.inverse import ChainFK
from .postures import zero20_postures
from .postures_io import Postures
from .solvers import DEFAULT_SIGMA_MM


def simulate_postures(
    convention: str,
    table: np.ndarray,
    hidden_offsets: np.ndarray,
    tool_mm: np.ndarray,
    target_mm: np.ndarray,
    *,
    scatter_mm: float = DEFAULT_SIGMA_MM,
    tracker_sigma_mm: float | None = None,
    limits: np.ndarray | None = None,
    rng: np.random.Generator | None = None,
    q_true: np.ndarray | None = None,
    plane: np.ndarray | None = None,
) -> tuple[Postures, np.ndarray]:
    """Taught postures of a true robot whose zeros moved by ``hidden_offsets``.

    The true robot (``table``, ``tool_mm``) is put on the target by IK
    (:func:`zero20_postures`, unless ``q_true`` is given); each posture is then disturbed
    by a minimum-norm joint change that moves the tip by N(0, scatter_mm) per axis (the
    repeatability of hand teaching); the controller reports true - hidden_offsets.

    Parameters
    ----------
    tracker_sigma_mm : when given, the tip is also "measured" with this noise per axis
        (``base_p_tip``)

    Returns
    -------
    postures : as the controller records them (rad)
    q_true : (n, N) the true joint angles of the taught postures, rad
    """
    rng = rng or np.random.default_rng(0)
    if q_true is None:
        q_true, plane, ok = zero20_postures(convention, table, tool_mm, target_mm,
                                            limits=limits, rng=rng)
        if not ok.all():
            raise ValueError(f"IK failed for {int((~ok).sum())} postures")
    fk = ChainFK(convention, table, tool_mm)
    _, _, Jp, _ = fk(q_true)
    dp = rng.normal(0.0, scatter_mm, size=(len(q_true), 3))
    q_true = q_true + (np.linalg.pinv(Jp) @ dp[..., None])[..., 0]
    tips = None
    if tracker_sigma_mm is not None:
        tips = fk.point(q_true) + rng.normal(0.0, tracker_sigma_mm, size=(len(q_true), 3))
    q_reported = q_true - np.asarray(hidden_offsets, float)
    if plane is None:
        raise ValueError("simulate_postures: q_true needs its plane numbers (plane=...)")
    return Postures(q_reported, plane, base_p_tip=tips, source="simulated"), q_true
