"""``table:J``: a smooth correction table Δθ(θ_J) for joint errors no formula captures.

Knots every ``spacing_deg`` over the joint's range; Δθ is linear between knots (hat
functions). A second-difference smoothness penalty ties neighbouring knots together;
its weight is chosen by k-fold cross-validation (:func:`tune_smoothing`) unless given.
Knots whose support holds no data are pinned at zero (nothing measured there).
A constant table is the joint's zero offset, so one knot is redundant with
``geometric.jJ.theta`` and the identifiability analysis fixes it.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from ..dataset import Dataset
from .base import JointEffect

#: penalty rows are in mm: a second difference of 1 rad counts like this many mm
_PENALTY_ARM_MM = 1000.0


class Table(JointEffect):
    """Correction table for joint J: knot values ``k000``, ``k010``, ... (rad) at every
    ``spacing_deg`` degrees; Δθ is interpolated linearly. ``smoothing`` (dimensionless)
    weights the second-difference penalty; None = choose by cross-validation."""

    family = "table"
    summary = "a smooth correction table Δθ(θ) for one joint"

    spacing_deg = 10.0

    def __init__(self, model, joint=None, order=None, smoothing: float | None = None):
        super().__init__(model, joint, order)
        lo, hi = np.degrees(model.limits_rad()[self.joint - 1])
        lo, hi = max(lo, -360.0), min(hi, 360.0)
        step = self.spacing_deg
        start = np.floor(lo / step) * step
        stop = np.ceil(hi / step) * step
        self.knots_deg = np.arange(start, stop + step / 2, step)
        self.knots = np.radians(self.knots_deg)
        self.param_names = [f"k{int(round(k)):+04d}".replace("+", "p").replace("-", "m")
                            for k in self.knots_deg]
        self.units = ["rad"] * len(self.knots)
        self.scales = np.full(len(self.knots), 1e-5)
        self.smoothing = smoothing
        K = len(self.knots)
        D = np.zeros((max(K - 2, 0), K))
        for i in range(K - 2):
            D[i, i : i + 3] = (1.0, -2.0, 1.0)
        self._D2 = D
        self.cv_curve: list[tuple[float, float]] = []

    def basis(self, theta: np.ndarray) -> np.ndarray:
        """Hat-function values at angles ``theta`` (rad), shape (n, n_knots)."""
        h = self.knots[1] - self.knots[0]
        u = (np.clip(theta, self.knots[0], self.knots[-1]) - self.knots[0]) / h
        i = np.minimum(np.floor(u).astype(int), len(self.knots) - 2)
        f = u - i
        B = np.zeros((theta.size, len(self.knots)))
        rows = np.arange(theta.size)
        B[rows, i] = 1.0 - f
        B[rows, i + 1] += f
        return B

    def bind(self, data: Dataset, nominal: Any) -> np.ndarray:
        return self.basis(data.q[:, self.joint - 1])

    def delta(self, p, data, B):
        return B @ p, B

    def pinned(self, B) -> dict[str, str]:
        empty = B.sum(axis=0) < 1e-9
        return {
            self.param_names[k]: "no data within this knot's reach (pinned at zero)"
            for k in np.flatnonzero(empty)
        }

    def penalty(self, p: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Smoothness pseudo-observations: sqrt(smoothing) * arm * D2 p, and their Jacobian."""
        w = np.sqrt(self.smoothing or 0.0) * _PENALTY_ARM_MM
        return w * (self._D2 @ p), w * self._D2

    def typical(self, rng):
        # a smooth bump-and-ripple no single harmonic captures
        t = self.knots
        amp = 0.25 / 1000.0
        return amp * (np.exp(-((t - rng.uniform(-1, 1)) ** 2) / 0.3) - 0.3 * np.sin(3.3 * t))


def tune_smoothing(error_model, data: Dataset, effect: Table, identify_fn, grid=None,
                   folds: int = 5, seed: int = 0) -> float:
    """Choose ``effect.smoothing`` by k-fold cross-validation of the pose error.

    ``identify_fn(error_model, data, x0=None)`` fits; held-out poses are predicted with
    the fit; points that are blunders (:func:`calibration.outliers.find_blunders` on the
    held-out errors at any smoothing) are left out of the comparison. Records
    ``effect.cv_curve`` as (smoothing, held-out RMS mm) pairs.
    """
    from ..outliers import find_blunders, point_sigmas

    grid = [1e-3, 1e-2, 1e-1, 1.0, 10.0, 100.0] if grid is None else grid
    rng = np.random.default_rng(seed)
    fold_of = rng.permutation(data.n) % folds
    effect.cv_curve = []
    held = np.zeros((len(grid), data.n, 3))
    for g, lam in enumerate(grid):
        effect.smoothing = lam
        for f in range(folds):
            train, test = data.subset(fold_of != f), data.subset(fold_of == f)
            fit = identify_fn(error_model, train)
            held[g, fold_of == f] = test.xyz - fit.predict(test)
    # blunders would weigh on the held-out error more than the smoothing does: a point
    # out of line at any smoothing counts at none
    sigma = point_sigmas(data)[0]
    out = np.zeros(data.n, bool)
    for g in range(len(grid)):
        out[[b.index for b in find_blunders(held[g], sigma).blunders]] = True
    best = (np.inf, grid[0])
    for g, lam in enumerate(grid):
        rms = float(np.sqrt(np.sum(held[g, ~out] ** 2) / max(int((~out).sum()), 1)))
        effect.cv_curve.append((lam, rms))
        if rms < best[0]:
            best = (rms, lam)
    effect.smoothing = best[1]
    return best[1]
