"""The two zero-point methods, :func:`seed_method` (the published one) and
:func:`rigorous_method` (one least-squares problem with an identifiability check), their
:class:`ZeroResult` and the pieces they share (:func:`pivot_fit`, chain evaluation).
See :mod:`calibration.zero_point` for what each method does.

Lengths mm, angles rad.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ..fit.identifiability import Identifiability, analyse
from ..fit.identify import covariance
from ..model.inverse import ChainFK
from ..model.kinematics import cross, run_chain
from .postures_io import Postures

#: tip repeatability assumed when none is given (per axis), mm
DEFAULT_SIGMA_MM = 0.02


@dataclass
class ZeroResult:
    """Result of a zero-point method.

    Attributes
    ----------
    method : "seed" or "rigorous"
    offsets : (N,) joint zero corrections, rad (true = reported + offset); undetermined
        joints keep their start value
    std : (N,) standard uncertainties, rad (nan where undetermined)
    determined : (N,) bool, the postures determine this offset
    tool : (3,) tool point in the flange frame, mm
    target : (3,) target point in the base frame, mm
    residuals : (n, 3) tip minus target per posture, mm (all postures, outliers included)
    rms_mm : RMS of the residual norms over the postures used, mm
    used : (n,) bool, postures used in the final solution
    outliers : pose_ids flagged as outliers
    iterations, converged, reason, solve_s : how it went
    fixed : undetermined parameters with the reason
    history : per iteration, rms (mm) and step (rad)
    """

    method: str
    offsets: np.ndarray
    std: np.ndarray
    determined: np.ndarray
    tool: np.ndarray
    target: np.ndarray
    residuals: np.ndarray
    rms_mm: float
    used: np.ndarray
    outliers: list[str] = field(default_factory=list)
    iterations: int = 0
    converged: bool = True
    reason: str = ""
    solve_s: float = 0.0
    fixed: dict[str, str] = field(default_factory=dict)
    history: list[dict] = field(default_factory=list)

    @property
    def unidentifiable(self) -> list[str]:
        return [f"j{j + 1}" for j in np.flatnonzero(~self.determined)]


def _kinematics(fk: ChainFK, q: np.ndarray, offsets: np.ndarray,
                tool: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Tip (n, 3), flange R (n, 3, 3) and dP/d offsets (n, 3, N) at q + offsets."""
    chain = ChainFK(fk.convention, fk.table, tool, offsets)
    P, R, Jp, _ = chain(q)
    return P, R, Jp


def pivot_fit(o: np.ndarray, R: np.ndarray,
              w: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Least-squares tool and target from flange poses: o_i + R_i t = p.

    Parameters
    ----------
    o : (n, 3) flange origins, mm; R : (n, 3, 3) flange orientations; w : (n,) weights

    Returns
    -------
    tool : (3,) flange frame, mm; target : (3,) base frame, mm
    """
    n = len(o)
    A = np.concatenate([R, -np.broadcast_to(np.eye(3), (n, 3, 3))], axis=2).reshape(3 * n, 6)
    b = -o.reshape(3 * n)
    if w is not None:
        s = np.repeat(np.sqrt(w), 3)
        A, b = A * s[:, None], b * s
    x, *_ = np.linalg.lstsq(A, b, rcond=None)
    return x[:3], x[3:]


def _flange(fk: ChainFK, q: np.ndarray,
            offsets: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    chain = ChainFK(fk.convention, fk.table, np.zeros(3), offsets)
    P, R, _, _ = chain(q)
    return P, R


def _names(N: int) -> list[str]:
    return ([f"zero.j{j + 1}" for j in range(N)] + ["tool.x", "tool.y", "tool.z"]
            + ["target.x", "target.y", "target.z"])


def _identify_free(fk: ChainFK, postures: Postures, offsets: np.ndarray, tool: np.ndarray,
                   target: np.ndarray, measured: bool, rtol: float = 1e-3) -> Identifiability:
    """Identifiability of (offsets, tool, target) from the postures: QR with pivoting.

    Structural, like :func:`~calibration.fit.identify.identify` at the nominal geometry: the
    Jacobian is taken as if every tip were exactly on the target, so exact redundancies
    (joint 1 with the target, the last joint with the tool) stay exact.
    """
    N = fk.n_joints
    r = run_chain(fk.convention, fk.table, postures.q + offsets, tool, jacobian=False)
    n = postures.n
    Jq = cross(r.joint_axes, np.asarray(target, float) - r.joint_origins).transpose(0, 2, 1)
    R = r.base_R_flange
    J = np.concatenate([Jq, R, -np.broadcast_to(np.eye(3), (n, 3, 3))], axis=2)
    if measured:  # tip measured: rows tip - measured (target does not enter)
        Jm = np.concatenate([Jq, R, np.zeros((n, 3, 3))], axis=2)
        J = np.concatenate([J, Jm], axis=0)
    return _analyse(J.reshape(-1, N + 6), N, n, rtol)


def _analyse(J2: np.ndarray, N: int, n: int, rtol: float) -> Identifiability:
    """QR with column pivoting on a (m, N + 6) Jacobian; tool and target ranked first."""
    families = ["geometric"] * N + ["tool"] * 3 + ["base"] * 3
    scales = np.array([np.radians(0.01)] * N + [1.0] * 6)
    return analyse(J2, _names(N), scales, families, rtol=rtol, n_poses=n)


def rigorous_method(
    fk: ChainFK,
    postures: Postures,
    *,
    offsets0: np.ndarray | None = None,
    tool0: np.ndarray | None = None,
    measured_base: np.ndarray | None = None,
    sigma_mm: float | None = DEFAULT_SIGMA_MM,
    reject_outliers: bool = True,
    outlier_p: float = 1e-4,
    max_iter: int = 50,
    rtol: float = 1e-3,
) -> ZeroResult:
    """Joint offsets, tool and target in one least-squares problem (Gauss–Newton).

    Residuals: for every posture the tip P_i(q_i + δ, t) minus the target p; with
    measured tips (``measured_base``, base frame) also the tip minus the measurement.
    Parameters the postures cannot determine (QR with column pivoting on the
    normalised Jacobian, tool and target ranked first) stay at their start.

    Parameters
    ----------
    fk : the chain (the calibrated model without offsets); its tool is the default tool0
    postures : the recorded postures
    offsets0 : (N,) start offsets, rad (a previous pass's result)
    tool0 : (3,) start tool, mm (default: a pivot fit)
    measured_base : (n, 3) measured tips in the base frame, mm, or None
    sigma_mm : tip scatter per axis (repeatability, mm) for the outlier test; None to
        estimate it robustly from the residuals
    reject_outliers : leave out, one at a time, postures whose residual is improbable
        (chi-square with 3 dof at level ``outlier_p``, leverage-corrected), and refit
    """
    t0 = time.perf_counter()
    N = fk.n_joints
    offsets0 = np.zeros(N) if offsets0 is None else np.asarray(offsets0, float)
    o, R = _flange(fk, postures.q, offsets0)
    tool_start, target_start = pivot_fit(o, R)
    if tool0 is not None:
        tool_start = np.asarray(tool0, float)
    x0 = np.concatenate([offsets0, tool_start, target_start])
    used = np.ones(postures.n, bool)
    outliers: list[str] = []
    history: list[dict] = []
    total_iter = 0
    while True:
        sub = postures.subset(used)
        mb = None if measured_base is None else measured_base[used]
        ident = _identify_free(fk, sub, offsets0, tool_start, target_start, mb is not None,
                               rtol)
        # solve; judge identifiability again at the solution (where the residuals are
        # small and near-redundancies are as exact as the data allow); re-solve if it changed
        for _ in range(3):
            x, converged, reason, its = _gauss_newton(fk, sub, x0, ident.free, mb, max_iter,
                                                      history)
            total_iter += its
            r, J = _rigorous_rj(fk, sub, x, mb)
            again = _analyse(J.reshape(-1, N + 6), N, sub.n, rtol)
            if (again.free == ident.free).all():
                break
            ident = again
        free = ident.free
        if not reject_outliers or sub.n - 1 <= (N + 6) // 3 + 1:
            break
        k = _worst_outlier(r, J.reshape(-1, N + 6)[:, free], sigma_mm, outlier_p, sub.n,
                           mb is not None)
        if k is None:
            break
        idx = np.flatnonzero(used)[k]
        used[idx] = False
        outliers.append(postures.pose_id[idx])
        if len(outliers) > postures.n // 4:
            converged, reason = False, f"too many outliers ({len(outliers)})"
            break
    Jfull = J.reshape(-1, 3, N + 6)
    cov, _ = covariance(Jfull, r, free)
    std = np.sqrt(np.clip(np.diag(cov), 0, None))
    offsets, tool, target = x[:N], x[N:N + 3], x[N + 3:]
    P, _, _ = _kinematics(fk, postures.q, offsets, tool)
    resid = P - target
    determined = free[:N].copy()
    std_off = np.where(determined, std[:N], np.nan)
    return ZeroResult(
        "rigorous", offsets, std_off, determined, tool, target, resid,
        _rms(resid[used]), used, outliers, total_iter, converged, reason,
        time.perf_counter() - t0, ident.fixed, history,
    )


def _gauss_newton(fk: ChainFK, postures: Postures, x0: np.ndarray, free: np.ndarray,
                  measured_base: np.ndarray | None, max_iter: int,
                  history: list[dict[str, Any]]) -> tuple[np.ndarray, bool, str, int]:
    """Gauss–Newton on the free parameters from x0; returns x, converged, reason, iterations."""
    N = fk.n_joints
    x = x0.copy()
    n_off = int(free[:N].sum())
    for it in range(max_iter):
        r, J = _rigorous_rj(fk, postures, x, measured_base)
        Jf = J.reshape(-1, N + 6)[:, free]
        d = np.linalg.norm(Jf, axis=0)
        d[d == 0] = 1.0
        step, *_ = np.linalg.lstsq(Jf / d, -r.ravel(), rcond=None)
        step /= d
        x[free] += step
        ang = float(np.abs(step[:n_off]).max(initial=0.0))
        lin = float(np.abs(step[n_off:]).max(initial=0.0))
        history.append({"rms_mm": _rms(r[: postures.n]), "step_rad": ang})
        if ang < 1e-12 and lin < 1e-9:
            return x, True, f"converged after {it + 1} iterations", it + 1
    return x, False, f"no convergence in {max_iter} iterations", max_iter


def _rms(r: np.ndarray) -> float:
    return float(np.sqrt(np.mean(np.sum(r**2, axis=1)))) if len(r) else float("nan")


def _rigorous_rj(fk: ChainFK, postures: Postures, x: np.ndarray,
                 measured_base: np.ndarray | None) -> tuple[np.ndarray, np.ndarray]:
    """Residual rows (tip - target [; tip - measured]) (m, 3) and Jacobian (m, 3, N + 6)."""
    N = fk.n_joints
    P, R, Jq = _kinematics(fk, postures.q, x[:N], x[N:N + 3])
    n = len(P)
    r = P - x[N + 3:]
    J = np.concatenate([Jq, R, -np.broadcast_to(np.eye(3), (n, 3, 3))], axis=2)
    if measured_base is not None:
        r = np.concatenate([r, P - measured_base])
        J = np.concatenate([J, np.concatenate([Jq, R, np.zeros((n, 3, 3))], axis=2)])
    return r, J


def _worst_outlier(r: np.ndarray, Jf: np.ndarray, sigma_mm: float | None, p: float, n: int,
                   measured: bool) -> int | None:
    """Index of the posture whose residual is improbable, or None.

    r : (m, 3) residual rows; Jf : (3 m, k) Jacobian of the free parameters; n postures.
    """
    import scipy.special  # here: scipy's import is half of `cellcal calibrate`'s start-up

    # leverage of each posture's 3 rows (hat matrix diagonal, summed per posture)
    Q, _ = np.linalg.qr(Jf / np.maximum(np.linalg.norm(Jf, axis=0), 1e-300))
    h = np.sum(Q**2, axis=1).reshape(-1, 3).sum(axis=1)
    rows = r.reshape(-1, 3)
    chi = np.sum(rows**2, axis=1)
    dof_share = np.clip(3.0 - h, 0.3, 3.0)
    if measured:  # two residual rows per posture
        chi = chi[:n] + chi[n:]
        dof_share = dof_share[:n] + dof_share[n:]
    # unknown scatter: a robust scale (the median of chi2_3 / 3 is 0.79)
    s2 = float(np.median(chi / dof_share)) / 0.79 if sigma_mm is None else sigma_mm**2
    stat = chi / (s2 * dof_share / (6.0 if measured else 3.0))
    dof = 6 if measured else 3
    limit = 2 * scipy.special.gammaincinv(dof / 2, 1 - p)  # chi2(dof).ppf(1 - p)
    k = int(np.argmax(stat))
    return k if stat[k] > limit else None


def seed_method(
    fk: ChainFK,
    postures: Postures,
    *,
    offsets0: np.ndarray | None = None,
    rng: np.random.Generator | None = None,
    n_candidates: int = 2000,
    keep_fraction: float = 0.2,
    damping: float = 1e-6,
    threshold_mm: float | None = None,
    sigma_mm: float = DEFAULT_SIGMA_MM,
    max_iter: int = 300,
    determined: np.ndarray | None = None,
) -> ZeroResult:
    """The published method, step by step (see the module docstring).

    Parameters
    ----------
    fk : the chain (the calibrated model without offsets)
    postures : the recorded postures
    offsets0 : (N,) start offsets, rad (a first pass's result for the fine pass)
    rng : random candidates of the resampling step
    n_candidates : candidate points per resampling
    keep_fraction : share of the best-weighted candidates averaged (20 %)
    damping : k of Jᵀ(JJᵀ + kI)⁻¹, relative to the mean diagonal of JJᵀ
    threshold_mm : stop once every posture's tip is within this distance of the virtual
        target (the published stopping rule). The default (None) stops only when the
        matching degree (RMS tip-to-target distance) no longer improves by 0.01 % over
        10 iterations: a fixed threshold set above the scatter stops the method before its
        offsets have converged, one set below it is never reached.
    sigma_mm : tip scatter per axis (mm); only for reporting
    determined : (N,) which offsets the postures determine (default: from the rigorous
        identifiability analysis); only used for reporting
    """
    t0 = time.perf_counter()
    rng = rng or np.random.default_rng(0)
    N = fk.n_joints
    offsets = np.zeros(N) if offsets0 is None else np.asarray(offsets0, float).copy()
    thr = -1.0 if threshold_mm is None else threshold_mm
    history: list[dict] = []
    converged, reason = False, f"no convergence in {max_iter} iterations"
    best = np.inf
    stall = 0
    it = 0
    for it in range(1, max_iter + 1):
        # 1-3: forward kinematics, tool by least squares, tip of every posture
        o, R = _flange(fk, postures.q, offsets)
        tool, _ = pivot_fit(o, R)
        P, _, Jq = _kinematics(fk, postures.q, offsets, tool)
        # 4: the mean as virtual target; 5: resampling around it
        V = _resample(P, rng, n_candidates, keep_fraction)
        e = V - P
        dist = np.linalg.norm(e, axis=1)
        history.append({"rms_mm": _rms(e), "max_mm": float(dist.max())})
        if dist.max() <= thr:
            converged, reason = True, f"every posture within {thr:.3g} mm after {it} iterations"
            break
        # 6: calibration equations, damped pseudo-inverse J^T (J J^T + k I)^-1
        J = Jq.reshape(-1, N)
        A = J @ J.T
        k = damping * float(np.trace(A)) / len(A)
        step = J.T @ np.linalg.solve(A + k * np.eye(len(A)), e.ravel())
        offsets += step
        history[-1]["step_rad"] = float(np.abs(step).max())
        rms = history[-1]["rms_mm"]
        if rms < best * (1 - 1e-4):
            best, stall = rms, 0
        else:
            stall += 1
        if stall >= 10:
            converged = True
            reason = (f"stalled after {it} iterations with the worst posture "
                      f"{dist.max():.3g} mm from the target"
                      + (f" (threshold {thr:.3g} mm)" if thr >= 0 else ""))
            break
    o, R = _flange(fk, postures.q, offsets)
    tool, _ = pivot_fit(o, R)
    P, _, _ = _kinematics(fk, postures.q, offsets, tool)
    target = P.mean(axis=0)
    if determined is None:
        r_, J_ = _rigorous_rj(fk, postures, np.concatenate([offsets, tool, P.mean(axis=0)]), None)
        determined = _analyse(J_.reshape(-1, N + 6), N, postures.n, 1e-3).free[:N]
    resid = P - target
    return ZeroResult(
        "seed", offsets, np.full(N, np.nan), np.asarray(determined, bool).copy(), tool, target,
        resid, _rms(resid), np.ones(postures.n, bool), [], it, converged, reason,
        time.perf_counter() - t0, {}, history,
    )


def _resample(P: np.ndarray, rng: np.random.Generator, n_candidates: int,
              keep_fraction: float) -> np.ndarray:
    """Virtual target: candidates around the mean of P, weights exp(-mean distance to P),
    normalised, sorted, the top share averaged (weighted)."""
    mean = P.mean(axis=0)
    spread = max(_rms(P - mean), 1e-6)
    C = mean + rng.normal(0.0, spread, size=(n_candidates, 3))
    d = np.linalg.norm(C[:, None, :] - P[None], axis=2).mean(axis=1)
    w = np.exp(-(d - d.min()))
    w /= w.sum()
    order = np.argsort(-w)[: max(1, int(round(keep_fraction * n_candidates)))]
    wk = w[order] / w[order].sum()
    return wk @ C[order]
