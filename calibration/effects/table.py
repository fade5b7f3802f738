"""``table:J`` / ``tableS:J`` / ``tableS:J@LO..HI``: a smooth correction table Δθ(θ_J) for
joint errors no formula captures.

Knots every S degrees (``tableS:J``; ``table:J`` is S = 10), linear between knots (hat
functions), constant beyond the end knots. ``@LO..HI`` names the first and the last knot
(multiples of S, deg): ``table2:2@-186..-126``. By name without a range the knots span
the joint's range (within ±360°) and those whose support holds no data are pinned at zero;
:meth:`Table.covering` builds a table whose knots span only the angles the data cover.

A fitted table holds only the knots its data support (:meth:`Table.supported_knots`, the
rule :data:`MIN_KNOT_SHARE`, :data:`MIN_KNOT_POSES`): an end knot whose hat holds less
than half the weight of the median knot, or fewer than ten poses, is dropped, so the
table ends at the last knot the data fill and holds that knot's value beyond; the
smoothing then cannot make an edge knot free (the data determine it like any other).
The automatic diagnosis adds :meth:`Table.supported` tables, and ``calibrate`` fits every
table over its supported knots (:func:`calibration.fit.envelope.supported_model`), so a
table named without a range covers the data it is fitted to. In params.json the knots are
the parameter names (``kp010`` is the knot at +10°), so a table reads back with exactly
its knots (:meth:`Table.with_parameter_names`).

A second-difference penalty ties neighbouring knots together; its weight ``smoothing`` is
chosen by generalised cross-validation (GCV) on the linearised problem
(:func:`choose_smoothing`, :func:`penalised_path`): one fit, then a closed-form path over
the weights. The penalty leaves a table's constant and linear parts free; the
identifiability analysis checks only those two directions (a constant table is the joint's
zero offset, so with ``geometric`` one knot is held at zero) and counts the rest as
determined by the penalty (:meth:`Table.null_space`).
"""

from __future__ import annotations

import re
from collections.abc import Callable
from typing import Any

import numpy as np
import numpy.typing as npt

from ..data.dataset import Dataset
from ..model.robot_model import RobotModel
from .base import EffectError, JointEffect

#: penalty rows are in mm: a second difference of 1 rad counts like this many mm
_PENALTY_ARM_MM = 1000.0
#: knot spacing of ``table:J`` (degrees)
DEFAULT_SPACING_DEG = 10
#: smoothing weights GCV chooses among, and the weight of the first fit
SMOOTHING_GRID = np.logspace(-6, 6, 25)
#: :meth:`Table.knot_support` remembers its answers for at most this many sets of angles,
#: each of at most this many angles
_MEMO_ENTRIES, _MEMO_MAX_ANGLES = 64, 20_000
START_SMOOTHING = 1.0
#: an end knot is kept only when its hat holds at least this share of the median knot's
#: data weight (the sum of its hat function over the poses): half, so the data must fill
#: the inner half of its hat; a knot the data barely reach is dropped and the table holds
#: the next knot's value beyond
MIN_KNOT_SHARE = 0.5
#: ... and at least this many poses within its hat (a handful decides nothing)
MIN_KNOT_POSES = 10

_KNOT = re.compile(r"^k([pm])(\d+)$")


def _knot_name(deg: float) -> str:
    return f"k{int(round(deg)):+04d}".replace("+", "p").replace("-", "m")


class Table(JointEffect):
    """Correction table for joint J: knot values ``km010``, ``kp000``, ``kp010``... (rad) every
    ``spacing_deg`` degrees; Δθ is interpolated linearly and constant beyond the end knots.
    ``smoothing`` (dimensionless) weights the second-difference penalty; None = choose it by
    GCV when fitting. ``range_deg`` (lo, hi) limits the knots to that span of the joint;
    ``knots_deg`` gives them explicitly (evenly spaced by ``order`` degrees)."""

    family = "table"
    takes_order = True
    #: the name may carry the knots' range: ``table2:2@-186..-126``
    takes_range = True
    summary = "a smooth correction table Δθ(θ) for one joint"

    def __init__(self, model: RobotModel, joint: int | None = None, order: int | None = None,
                 smoothing: float | None = None, range_deg: tuple[float, float] | None = None,
                 knots_deg: npt.ArrayLike | None = None, explicit_range: bool = False) -> None:
        super().__init__(model, joint, order)
        self.explicit_range = False
        spacing = DEFAULT_SPACING_DEG if order is None else int(order)
        if not 2 <= spacing <= 90:
            raise EffectError(f"table knot spacing must be 2..90 degrees, got {spacing} "
                              f"(table{spacing}:{self.joint})")
        self.order = None if spacing == DEFAULT_SPACING_DEG else spacing
        self.spacing_deg = float(spacing)
        step = self.spacing_deg
        if knots_deg is None:
            if range_deg is None:
                lo, hi = np.degrees(model.limits_rad()[self.joint - 1])
                lo, hi = max(lo, -360.0), min(hi, 360.0)
            else:
                lo, hi = float(min(range_deg)), float(max(range_deg))
            start = np.floor(lo / step + 1e-9) * step
            stop = max(np.ceil(hi / step - 1e-9) * step, start + 2 * step)
            knots_deg = np.arange(start, stop + step / 2, step)
        knots_deg = np.asarray(knots_deg, float)
        if knots_deg.size < 3 or not np.allclose(np.diff(knots_deg), step):
            raise EffectError(f"{self.label}: knots must be at least 3, every {step:g} degrees")
        if explicit_range and range_deg is not None and (
                knots_deg[0] != min(range_deg) or knots_deg[-1] != max(range_deg)):
            raise EffectError(f"{self.label}@{min(range_deg):g}..{max(range_deg):g}: the "
                              f"range's ends must be knots, multiples of {step:g} degrees "
                              f"(e.g. @{knots_deg[0]:g}..{knots_deg[-1]:g}), at least "
                              f"{2 * step:g} degrees apart")
        #: the knots were named (``@LO..HI``): the label carries them
        self.explicit_range = bool(explicit_range)
        self.knots_deg = knots_deg
        self.knots = np.radians(knots_deg)
        self.param_names = [_knot_name(k) for k in knots_deg]
        self.units = ["rad"] * len(self.knots)
        self.scales = np.full(len(self.knots), 1e-5)
        self.smoothing = smoothing
        K = len(self.knots)
        D = np.zeros((K - 2, K))
        for i in range(K - 2):
            D[i, i : i + 3] = (1.0, -2.0, 1.0)
        self._D2 = D
        #: (smoothing, GCV estimate of the held-out RMS, mm) of the last GCV choice
        self.cv_curve: list[tuple[float, float]] = []
        #: knot_support's answers by the angles asked about (the auto loop's range-blocked
        #: folds ask the same few sets at every step)
        self._support_memo: dict[bytes, np.ndarray] = {}

    @property
    def label(self) -> str:
        """``tableS:J``, and ``@LO..HI`` when the knots were named."""
        base = super().label
        if not self.explicit_range:
            return base
        return f"{base}@{self.knots_deg[0]:g}..{self.knots_deg[-1]:g}"

    # ---- construction from data or from a params file ---------------------------
    @classmethod
    def covering(cls, model: RobotModel, joint: int, theta_rad: np.ndarray, spacing_deg: int,
                 smoothing: float | None = None) -> Table:
        """A table whose knots span the angles ``theta_rad`` of joint ``joint`` (and no more)."""
        deg = np.degrees(np.asarray(theta_rad, float))
        return cls(model, joint, spacing_deg, smoothing, range_deg=(deg.min(), deg.max()))

    @classmethod
    def supported(cls, model: RobotModel, joint: int, theta_rad: np.ndarray, spacing_deg: int,
                  smoothing: float | None = None) -> Table:
        """:meth:`covering`, then only the knots the angles support
        (:meth:`supported_knots`): what the automatic diagnosis adds."""
        return cls.covering(model, joint, theta_rad, spacing_deg,
                            smoothing).supported_knots(theta_rad)

    def knot_support(self, theta_rad: np.ndarray) -> np.ndarray:
        """(K,) bool: the knots the poses at angles ``theta_rad`` support: the hat holds at
        least :data:`MIN_KNOT_SHARE` of the median knot's weight and :data:`MIN_KNOT_POSES`
        poses (poses beyond an end knot count for it: it is their value)."""
        theta = np.asarray(theta_rad, float)
        key = theta.tobytes() if theta.size <= _MEMO_MAX_ANGLES else None
        memo = self.__dict__.setdefault("_support_memo", {})
        if key is not None and key in memo:
            return memo[key].copy()
        ok = self._knot_support(theta)
        if key is not None:
            if len(memo) >= _MEMO_ENTRIES:
                memo.clear()
            memo[key] = ok.copy()
        return ok

    def _knot_support(self, theta: np.ndarray) -> np.ndarray:
        i, f = self._hat(theta)
        # the columns of basis() summed without forming it: each pose's two weights in
        # pose order (a column's sum adds them in that order: the same sums)
        at = np.stack([i, i + 1], axis=1).ravel()
        value = np.stack([1.0 - f, f], axis=1).ravel()
        K = len(self.knots)
        w = np.bincount(at, value, minlength=K)
        if not (w > 0).any():
            return np.zeros(K, bool)
        count = np.bincount(at, value > 1e-12, minlength=K)
        return (w >= MIN_KNOT_SHARE * np.median(w[w > 0])) & (count >= MIN_KNOT_POSES)

    def supported_knots(self, theta_rad: np.ndarray) -> Table:
        """This table with only the knots from the first to the last one the angles
        ``theta_rad`` support (:meth:`knot_support`), constant beyond; ``self`` when every
        knot is kept. At least three knots: where fewer are supported, the three that hold
        the most weight."""
        ok = self.knot_support(theta_rad)
        idx = np.flatnonzero(ok)
        K = len(self.knots)
        if idx.size and idx[-1] - idx[0] >= 2:
            first, last = int(idx[0]), int(idx[-1])
        else:
            w = self.basis(np.asarray(theta_rad, float)).sum(axis=0)
            if K <= 3 or not (w > 0).any():
                return self
            first = int(np.argmax(np.convolve(w, np.ones(3), "valid")))
            last = first + 2
        if first == 0 and last == K - 1:
            return self
        out = Table(self.model, self.joint, int(self.spacing_deg), self.smoothing,
                    knots_deg=self.knots_deg[first : last + 1],
                    explicit_range=self.explicit_range)
        out.cv_curve = list(self.cv_curve)
        return out

    def with_parameter_names(self, local_names: list[str]) -> Table:
        """The same table with the knots named in a params file (``km030``, ``kp000``...)."""
        knots = []
        for name in local_names:
            m = _KNOT.match(name)
            if not m:
                raise EffectError(f"{self.label}: bad knot name {name!r}")
            knots.append(int(m[2]) * (1 if m[1] == "p" else -1))
        return Table(self.model, self.joint, int(self.spacing_deg), self.smoothing,
                     knots_deg=sorted(knots), explicit_range=self.explicit_range)

    # ---- the correction --------------------------------------------------------
    def _hat(self, theta: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(i, f): at angles ``theta`` (rad) the hat functions of knots i and i + 1 hold
        1 - f and f (every other knot 0)."""
        h = self.knots[1] - self.knots[0]
        u = (np.clip(theta, self.knots[0], self.knots[-1]) - self.knots[0]) / h
        i = np.minimum(np.floor(u).astype(int), len(self.knots) - 2)
        return i, u - i

    def basis(self, theta: np.ndarray) -> np.ndarray:
        """Hat-function values at angles ``theta`` (rad), shape (n, n_knots)."""
        i, f = self._hat(theta)
        B = np.zeros((theta.size, len(self.knots)))
        rows = np.arange(theta.size)
        B[rows, i] = 1.0 - f
        B[rows, i + 1] += f
        return B

    def bind(self, data: Dataset, nominal: Any) -> np.ndarray:
        return self.basis(data.q[:, self.joint - 1])

    def delta(self, p: np.ndarray, data: Dataset, B: np.ndarray
              ) -> tuple[np.ndarray, np.ndarray]:
        return B @ p, B

    def pinned(self, B: np.ndarray) -> dict[str, str]:
        empty = B.sum(axis=0) < 1e-9
        return {
            self.param_names[k]: "no data within this knot's reach (pinned at zero)"
            for k in np.flatnonzero(empty)
        }

    # ---- the penalty -------------------------------------------------------------
    def penalty(self, p: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Smoothness pseudo-observations: sqrt(smoothing) * arm * D2 p, and their Jacobian."""
        w = np.sqrt(self.smoothing or 0.0) * _PENALTY_ARM_MM
        return w * (self._D2 @ p), w * self._D2

    def penalty_matrix(self) -> np.ndarray:
        """Ω with penalty = smoothing · pᵀ Ω p (mm²), (K, K)."""
        return _PENALTY_ARM_MM**2 * (self._D2.T @ self._D2)

    def penalty_factor(self) -> np.ndarray:
        """F (K - 2, K) with ``FᵀF`` = :meth:`penalty_matrix` (to rounding): the penalty's
        rows, of rank K - 2 (:func:`gcv_smoothing` works in that low rank)."""
        return _PENALTY_ARM_MM * self._D2

    def null_space(self) -> np.ndarray:
        """The directions the penalty leaves free: constant and linear in θ, (K, 2)."""
        return np.column_stack([np.ones(len(self.knots)), self.knots - self.knots.mean()])

    def typical(self, rng: np.random.Generator) -> np.ndarray:
        # a smooth bump-and-ripple no single harmonic captures
        t = self.knots
        amp = 0.25 / 1000.0
        return amp * (np.exp(-((t - rng.uniform(-1, 1)) ** 2) / 0.3) - 0.3 * np.sin(3.3 * t))


# ---- GCV on a linearised penalised least-squares problem ------------------------------
def penalised_path(N0: np.ndarray, b: np.ndarray, h: np.ndarray, Q: np.ndarray, r2: float,
                   omega: np.ndarray, grid: npt.ArrayLike = SMOOTHING_GRID, n_obs: int = 0,
                   trace0: float = 0.0) -> dict[str, Any]:
    """The solution path of c(s) = (N0 + s Ω)⁻¹ b over the weights ``grid``.

    The residual sum of squares is ``r2 - 2 h·c + cᵀ Q c`` and the degrees of freedom
    ``trace0 + tr((N0 + s Ω)⁻¹ Q)``; for ordinary penalised least squares ``N0 = Q = XᵀX``
    and ``b = h = Xᵀy``. One Cholesky and one symmetric eigen-decomposition, then O(k²)
    per weight.

    Returns a dict with ``grid``, ``rss`` (g,), ``edf`` (g,), ``gcv`` (g,) (the GCV
    estimate of the mean squared residual per observation, ``n_obs rss / (n_obs - edf)²``),
    ``best`` (index of the smallest GCV) and ``solve(s)`` giving c at any weight.
    """
    import scipy.linalg  # here: scipy's import is half of `cellcal calibrate`'s start-up

    k = N0.shape[0]
    grid = np.asarray(grid, float)
    d = np.sqrt(np.maximum(np.diag(N0) + np.diag(omega), 1e-300))
    N0s, Os, Qs = (M / np.outer(d, d) for M in (N0, omega, Q))
    bs, hs = b / d, h / d
    eps = 1e-10 * max(float(np.trace(N0s)) / max(k, 1), 1e-300)
    try:
        L = np.linalg.cholesky(N0s + eps * np.eye(k))
        Li = scipy.linalg.solve_triangular(L, np.eye(k), lower=True, check_finite=False)
    except np.linalg.LinAlgError:  # Li Lᵢᵀ inverts N0s with its tiny eigenvalues clipped
        w, U = np.linalg.eigh(N0s)
        Li = (U / np.sqrt(np.maximum(w, eps))).T
    om, U = np.linalg.eigh(Li @ Os @ Li.T)
    om = np.maximum(om, 0.0)
    S = Li.T @ U  # (N0s + s Os)⁻¹ = S diag(1 / (1 + s om)) Sᵀ
    beta, eta = S.T @ bs, S.T @ hs
    K = S.T @ Qs @ S
    f = 1.0 / (1.0 + grid[:, None] * om[None, :])  # (g, k)
    z = f * beta
    rss = r2 - 2 * z @ eta + np.einsum("gi,ij,gj->g", z, K, z)
    edf = trace0 + f @ np.diag(K)
    n = max(n_obs, 1)
    gcv = n * np.maximum(rss, 0.0) / np.maximum(n - edf, 1e-9) ** 2

    def solve(s: float) -> np.ndarray:
        return (S @ (beta / (1.0 + s * om))) / d

    return {"grid": grid, "rss": rss, "edf": edf, "gcv": gcv, "best": int(np.argmin(gcv)),
            "solve": solve}


def _low_rank_path(N0: np.ndarray, b: np.ndarray, Q: np.ndarray, r2: float,
                   omega: np.ndarray, F: np.ndarray, others: list[tuple[float, np.ndarray]],
                   grid: np.ndarray, n_obs: int) -> dict[str, Any] | None:
    """:func:`penalised_path` with ``h = b`` for a penalty of low rank, ``omega = FᵀF``
    (F (r, k), r much below k: one table's rows among every parameter), when
    ``N0 = Q + Σ s_o F_oᵀF_o`` (``others``: the other tables' (s_o, F_o)); without its
    k x k eigen-decomposition and products (the same figures to rounding).

    In the scaled variables of :func:`penalised_path`, with N = N0s + ε I = L Lᵀ and
    Z = L⁻¹ Fᵀ V, V the eigenvectors (eigenvalues μ) of the r x r ``(L⁻¹Fᵀ)ᵀ L⁻¹Fᵀ``:
    ``(N + s FᵀF)⁻¹ = N⁻¹ + H diag(-s / (1 + s μ)) Hᵀ`` with H = L⁻ᵀ Z, so every figure
    of the path is O(k r) per weight after O(k² r) once; ``tr(N⁻¹ Q)`` comes from
    ``Q = N - ε I - Σ s_o F_oᵀF_o``. None when N is not positive definite (the caller
    takes :func:`penalised_path`)."""
    import scipy.linalg  # here: scipy's import is half of `cellcal calibrate`'s start-up

    k = N0.shape[0]
    d = np.sqrt(np.maximum(np.diag(N0) + np.diag(omega), 1e-300))
    N0s, Qs = N0 / np.outer(d, d), Q / np.outer(d, d)
    bs = b / d
    eps = 1e-10 * max(float(np.trace(N0s)) / max(k, 1), 1e-300)
    try:
        L = np.linalg.cholesky(N0s + eps * np.eye(k))
    except np.linalg.LinAlgError:
        return None
    Li = scipy.linalg.solve_triangular(L, np.eye(k), lower=True, check_finite=False)
    W = Li @ (F / d).T  # (k, r)
    mu, V = np.linalg.eigh(W.T @ W)
    mu = np.maximum(mu, 0.0)
    H = Li.T @ (W @ V)  # (k, r)
    c0 = Li.T @ (Li @ bs)
    QH, Qc0 = Qs @ H, Qs @ c0
    HQH = H.T @ QH
    beta = H.T @ bs
    w = -grid[:, None] / (1.0 + grid[:, None] * mu[None, :])  # (g, r)
    g = w * beta  # c(s) = c0 + H g(s)
    rss = (r2 - 2.0 * (bs @ c0 + g @ beta) + c0 @ Qc0 + 2.0 * g @ (H.T @ Qc0)
           + np.einsum("gi,ij,gj->g", g, HQH, g))
    trace_q = k - eps * float(np.sum(Li * Li))
    for s_o, F_o in others:
        Wo = Li @ (F_o / d).T
        trace_q -= s_o * float(np.sum(Wo * Wo))
    edf = trace_q + w @ np.diag(HQH)
    n = max(n_obs, 1)
    gcv = n * np.maximum(rss, 0.0) / np.maximum(n - edf, 1e-9) ** 2
    return {"grid": grid, "rss": rss, "edf": edf, "gcv": gcv, "best": int(np.argmin(gcv))}


def choose_smoothing(error_model: Any, data: Dataset, fit_fn: Callable[[Any, Dataset], Any],
                     grid: np.ndarray = SMOOTHING_GRID) -> None:
    """Set the ``smoothing`` of every table (any effect with ``penalty_matrix``) whose
    smoothing is None, by GCV on the problem linearised at one fit.

    ``fit_fn(error_model, data)`` fits (with the tables at :data:`START_SMOOTHING`); the
    pose errors are then linear in the parameters to well within the noise, so the GCV
    path (:func:`penalised_path`) stands in for refits (:func:`gcv_smoothing`).
    """
    tables = [e for e in error_model.effects
              if hasattr(e, "penalty_matrix") and getattr(e, "smoothing", 0.0) is None]
    if not tables:
        return
    for e in tables:
        e.smoothing = START_SMOOTHING
    gcv_smoothing(fit_fn(error_model, data), tables, grid)


def gcv_smoothing(fit: Any, tables: list[Any] | None = None,
                  grid: np.ndarray = SMOOTHING_GRID,
                  linear: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None) -> bool:
    """Re-choose the smoothing of ``tables`` (default: every table of the fit's model) by
    GCV on the problem linearised at ``fit``, one table after the other, twice round.
    Records ``cv_curve`` on each as (smoothing, GCV RMS mm). Returns True when any
    smoothing changed (the fit is then out of date). ``linear``: the fit linearised
    already, (X (3n, m) the Jacobian's free columns, r (n, 3) the residuals, XᵀX)."""
    em, free, x = fit.error_model, fit.free, fit.values
    if tables is None:
        tables = [e for e in em.effects if hasattr(e, "penalty_matrix")]
    if not tables or not free.any():
        return False
    before = [e.smoothing for e in tables]
    if linear is None:
        P, J = em.evaluate(x, em.bind(fit.data), jacobian=True)
        X = J[:, :, free].reshape(-1, int(free.sum()))
        r = fit.data.tracker_p_smr - P
        XtX = X.T @ X
    else:
        X, r, XtX = linear
    y = r.ravel() + X @ x[free]
    b, y2 = X.T @ y, float(y @ y)
    omegas: dict[int, tuple[Any, np.ndarray]] = {}
    factors: dict[int, np.ndarray] = {}  # the penalties' rows over the free parameters
    for e, sl in zip(em.effects, em.slices, strict=True):
        if hasattr(e, "penalty_matrix"):
            O = np.zeros((em.n_params, em.n_params))
            O[sl, sl] = e.penalty_matrix()
            omegas[id(e)] = (e, O[np.ix_(free, free)])
            if hasattr(e, "penalty_factor"):
                Fe = e.penalty_factor()
                F = np.zeros((Fe.shape[0], em.n_params))
                F[:, sl] = Fe
                factors[id(e)] = F[:, free]
    grid = np.asarray(grid, float)
    for _ in range(2):
        for e in tables:
            A0 = XtX + sum(o.smoothing * O for key, (o, O) in omegas.items() if key != id(e))
            path = None
            if len(factors) == len(omegas):  # every penalty of low rank: no k x k eigh
                others = [(o.smoothing, factors[key]) for key, (o, _) in omegas.items()
                          if key != id(e)]
                path = _low_rank_path(A0, b, XtX, y2, omegas[id(e)][1], factors[id(e)],
                                      others, grid, X.shape[0])
            if path is None:
                path = penalised_path(A0, b, b, XtX, y2, omegas[id(e)][1], grid, X.shape[0])
            e.smoothing = float(grid[path["best"]])
            e.cv_curve = [(float(s), float(np.sqrt(3 * g))) for s, g in zip(grid, path["gcv"],
                                                                             strict=True)]
    return any(e.smoothing != s for e, s in zip(tables, before, strict=True))
