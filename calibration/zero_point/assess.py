"""Is a zero-point result usable? :func:`assess` decides "ok" or "poor" with the reasons
(convergence, offsets a fixed point should determine, uncertainty against the tolerance,
residual against the tip scatter)."""

from __future__ import annotations

import math

import numpy as np

from .solvers import ZeroResult


def expected_undetermined(n_joints: int, measured: bool) -> set[int]:
    """0-based joints a single fixed point cannot determine by construction: the first
    (about the base axis, absorbed by an unknown target) unless the tip was measured, and
    the last (about the flange axis, absorbed by an unknown tool)."""
    return ({n_joints - 1} if measured else {0, n_joints - 1})


def assess(result: ZeroResult, *, tolerance_deg: float, sigma_mm: float,
           measured: bool = False) -> tuple[str, list[str]]:
    """Decide whether a result is usable: ("ok", []) or ("poor", reasons).

    Poor: the method did not converge; an offset is undetermined that a fixed point can
    normally determine; a determined offset's uncertainty (2 sigma) exceeds the tolerance;
    the residual RMS is far (over 3x) above what the tip scatter explains.
    """
    N = len(result.offsets)
    reasons = []
    if not result.converged:
        reasons.append(f"not converged: {result.reason}")
    missing = [j for j in np.flatnonzero(~result.determined)
               if j not in expected_undetermined(N, measured)]
    if missing:
        reasons.append("the postures cannot determine offset(s) "
                       + ", ".join(f"j{j + 1}" for j in missing))
    tol = math.radians(tolerance_deg)
    wide = [j for j in np.flatnonzero(result.determined)
            if np.isfinite(result.std[j]) and 2 * result.std[j] > tol]
    if wide:
        reasons.append("uncertainty above the tolerance for "
                       + ", ".join(f"j{j + 1} (±{2 * math.degrees(result.std[j]):.4f}°)"
                                   for j in wide))
    expected = math.sqrt(3) * sigma_mm
    if result.rms_mm > 3 * expected:
        reasons.append(f"residual RMS {result.rms_mm:.4f} mm is far above the "
                       f"{expected:.4f} mm the tip scatter explains")
    return ("poor" if reasons else "ok"), reasons
