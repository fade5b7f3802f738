"""What every solver receives (:class:`Problem`) and returns (:class:`SolverResult`)."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..error_model import Bound, ErrorModel
from ..orientation_residuals import OrientationRows

#: evaluations a :class:`Problem` keeps (the solver's last accepted and rejected steps)
REMEMBERED = 3


@dataclass
class Problem:
    """A least-squares problem over the free parameters of an error model.

    Solvers work on the free parameters only (``xf``, internal units) and may use
    ``scales`` (typical magnitudes) to scale them. Residuals are measured minus
    predicted, flattened to (3 n,), optionally weighted by ``weights`` (n,). With
    ``pose`` (a 6-DoF target's orientations,
    :class:`~calibration.fit.orientation_residuals.OrientationRows`) the orientation rows
    (3 n, mm-equivalent) follow the position rows.
    """

    error_model: ErrorModel
    bound: Bound
    x0: np.ndarray
    free: np.ndarray
    weights: np.ndarray | None = None
    pose: OrientationRows | None = None
    #: the last few (x, P, J) evaluated (see :meth:`evaluate`), newest first
    seen: list[tuple[np.ndarray, np.ndarray, np.ndarray]] = field(default_factory=list,
                                                                   repr=False)
    #: the same for (x, P, J, R, W) of :meth:`evaluate_pose`
    seen_pose: list[tuple[np.ndarray, ...]] = field(default_factory=list, repr=False)

    @property
    def scales(self) -> np.ndarray:
        return np.asarray(self.error_model.scales)[self.free]

    @property
    def xf0(self) -> np.ndarray:
        return self.x0[self.free]

    @property
    def n_poses(self) -> int:
        return self.bound.data.n

    def full(self, xf: np.ndarray) -> np.ndarray:
        x = self.x0.copy()
        x[self.free] = xf
        return self.error_model.normalize(x)

    def residual(self, xf: np.ndarray) -> np.ndarray:
        """Measured minus predicted, (3 n,), followed by any penalty rows (regularised
        effects: minus the penalty, so the cost adds its square)."""
        x = self.full(xf)
        if self.pose is not None:
            P, _, R, _ = self.error_model.evaluate_pose(x, self.bound, jacobian=False)
            r = np.vstack([self.bound.data.tracker_p_smr - P, self.pose.residual(R)])
        else:
            r = self.error_model.residuals(x, self.bound)
        if self.weights is not None:
            r = r * np.tile(np.sqrt(self.weights), len(r) // len(self.weights))[:, None]
        pen = self.error_model.penalty(x)
        return r.ravel() if pen is None else np.concatenate([r.ravel(), -pen[0]])

    def evaluate(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Predicted points (n, 3) and Jacobian (n, 3, p) at full parameters ``x``.

        The last :data:`REMEMBERED` evaluations are kept, so the identification reuses
        the Jacobian of the identifiability check at the start and the solver's last one
        at the end instead of evaluating the chain again; callers must not modify them.
        """
        for xs, P, J in self.seen:
            if np.array_equal(xs, x):
                return P, J
        P, J = self.error_model.evaluate(x, self.bound, jacobian=True)
        self.remember(x, P, J)
        return P, J

    def evaluate_pose(
            self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """(P, J, R, W) of :meth:`ErrorModel.evaluate_pose` at ``x``, kept like
        :meth:`evaluate`'s (and its (P, J) there too)."""
        for xs, *kept in self.seen_pose:
            if np.array_equal(xs, x):
                P, J, R, W = kept
                return P, J, R, W
        out = self.error_model.evaluate_pose(x, self.bound, jacobian=True)
        self.seen_pose = [(np.array(x, float), *out), *self.seen_pose[: REMEMBERED - 1]]
        self.remember(x, out[0], out[1])
        return out

    def remember(self, x: np.ndarray, P: np.ndarray, J: np.ndarray) -> None:
        """Keep an evaluation at ``x`` made elsewhere (e.g. the nominal one)."""
        self.seen = [(np.array(x, float), P, J), *self.seen[: REMEMBERED - 1]]

    def residual_and_jacobian(self, xf: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Residual (3 n [+ m],) and its Jacobian d r / d xf, (3 n [+ m], n_free)."""
        x = self.full(xf)
        if self.pose is not None:
            P, J, R, W = self.evaluate_pose(x)
            ro, Jo = self.pose.residual_and_jacobian(R, W[:, :, self.free])
        P, J = self.evaluate(x)
        r = self.bound.data.tracker_p_smr - P
        Jr = J[:, :, self.free]  # a copy: negated in place
        np.negative(Jr, out=Jr)
        if self.pose is not None:
            r, Jr = np.vstack([r, ro]), np.concatenate([Jr, Jo])
        if self.weights is not None:
            w = np.tile(np.sqrt(self.weights), len(r) // len(self.weights))[:, None]
            r = r * w
            Jr = Jr * w[:, :, None]
        r, Jr = r.ravel(), Jr.reshape(-1, Jr.shape[-1])
        pen = self.error_model.penalty(x)
        if pen is not None:
            r = np.concatenate([r, -pen[0]])
            Jr = np.vstack([Jr, -pen[1][:, self.free]])
        return r, Jr


@dataclass
class SolverResult:
    """What a solver found. Non-convergence is a result with a reason, not an exception."""

    xf: np.ndarray
    converged: bool
    reason: str
    iterations: int
    history: list[dict] = field(default_factory=list)
    #: solver-specific extras (weights, ridge parameter, rejected points...)
    info: dict = field(default_factory=dict)
