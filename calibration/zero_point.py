"""Zero-point recalibration from 20 postures (5 on each of 4 planes) on one fixed point.

After a crash or a motor swap a joint's zero moves. The robot is taught, by hand,
20 postures that all put the tool tip on the same fixed target point; only the
joint readings are recorded (optionally also the tip, measured). Two methods
estimate the joint zero corrections from them (true angle = reported + offset):

- :func:`seed_method`, the published method this project was founded on, done
  faithfully: forward kinematics of each posture; least squares for the tool
  (TCP) coordinates; the target point of each posture from them; their mean as a
  virtual target; resampling around it (random candidates weighted by
  exp(-distance to the posture points), normalised, sorted, top 20 % averaged);
  the calibration equations of the postures solved for joint corrections with
  the damped pseudo-inverse ``Jᵀ(JJᵀ + kI)⁻¹``; repeated until every posture's
  tip matches the virtual target within a threshold.
- :func:`rigorous_method`: one least-squares problem in the joint offsets, the
  tool point (flange frame) and the target point (base frame), with an
  identifiability check (QR with column pivoting) that says which offsets the
  postures determine and which they cannot, uncertainties from the covariance
  and outlier postures flagged by their residual and left out.

A single fixed point leaves combinations free: joint 1's offset turns every tip
about the base z axis, which an unknown target absorbs, and the last joint's
offset turns the tool about the flange axis, which an unknown tool absorbs.
Measured tip positions (``x, y, z``) pin the target and make joint 1
identifiable.

:func:`zero20_postures` generates the 20 postures for a given (true) model, a
target point and a tool (the capture routine ``zero20`` and the tests use it);
:func:`load_postures` reads the postures CSV (FORMATS.md §1) strictly;
:func:`postures_from_dataset` adapts a :class:`~calibration.dataset.Dataset`
(e.g. loaded from a ``zero20`` run in the store).

Lengths mm, angles rad; degrees only in files.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import scipy.stats

from .dataset import CsvTable, DataError, Dataset
from .identifiability import analyse
from .identify import covariance
from .inverse import ChainFK, solve_ik_multistart, wrap_to_pi
from .kinematics import cross, run_chain
from .robot_model import RobotModel

#: tip repeatability assumed when none is given (per axis), mm
DEFAULT_SIGMA_MM = 0.02


# ---- postures ------------------------------------------------------------------
@dataclass
class Postures:
    """Recorded zero-point postures.

    Attributes
    ----------
    q : (n, N) joint readings of the controller, rad
    plane : (n,) plane number 1..4 of each posture
    pose_id : n labels
    xyz : (n, 3) measured tip, or None (frame: see :func:`rigorous_method`), mm
    source : where they came from
    lines : (n,) file line of each row (0 when not from a file)
    xyz_frame : the frame of ``xyz``: ``"base"`` (the robot base frame, usable as
        measured tips as they are) or ``"tracker"`` (the measurement frame: usable only
        with the base's pose, e.g. a calibrated model's ``base``)
    """

    q: np.ndarray
    plane: np.ndarray
    pose_id: list[str] = field(default_factory=list)
    xyz: np.ndarray | None = None
    source: str = "<arrays>"
    lines: np.ndarray | None = None
    xyz_frame: str = "base"

    def __post_init__(self) -> None:
        self.q = np.atleast_2d(np.asarray(self.q, float))
        n = len(self.q)
        self.plane = np.asarray(self.plane, int)
        if not self.pose_id:
            self.pose_id = [str(i + 1) for i in range(n)]
        if self.lines is None:
            self.lines = np.zeros(n, int)

    @property
    def n(self) -> int:
        return len(self.q)

    def subset(self, keep: np.ndarray) -> Postures:
        idx = np.arange(self.n)[keep]
        return Postures(self.q[idx], self.plane[idx], [self.pose_id[i] for i in idx],
                        None if self.xyz is None else self.xyz[idx], self.source, self.lines[idx],
                        self.xyz_frame)

    def to_csv(self, path: str | Path | None = None, meta: dict | None = None) -> str:
        """The postures CSV (deg); returns the text, writes it when a path is given.

        ``meta`` becomes ``# key: value`` comment lines before the header; with measured
        tips in the tracker frame, ``xyz_frame: tracker`` is always written.
        """
        N = self.q.shape[1]
        head = ["pose_id", "plane"] + [f"q{j + 1}" for j in range(N)]
        meta = dict(meta or {})
        if self.xyz is not None:
            head += ["x", "y", "z"]
            if self.xyz_frame != "base":
                meta["xyz_frame"] = self.xyz_frame
        lines = [f"# {k}: {v}" for k, v in meta.items()] + [",".join(head)]
        qd = np.degrees(self.q)
        for i in range(self.n):
            row = [self.pose_id[i], str(int(self.plane[i]))] + [repr(float(v)) for v in qd[i]]
            if self.xyz is not None:
                row += [repr(float(v)) for v in self.xyz[i]]
            lines.append(",".join(row))
        text = "\n".join(lines) + "\n"
        if path is not None:
            Path(path).write_text(text)
        return text


def load_postures(path: str | Path, model: RobotModel, *, check_limits: bool = True) -> Postures:
    """Read a zero-point postures CSV (FORMATS.md §1): ``pose_id, plane, q1..qN`` (deg),
    optional ``x, y, z`` (mm). Errors name the file, line and column; nothing is guessed.

    The tips are in the robot base frame unless a ``# xyz_frame: tracker`` comment says
    they are in the measurement frame (as ``cellcal export --postures`` writes them)."""
    t = CsvTable(path)
    N = model.n_joints
    t.require(["pose_id", "plane"] + [f"q{j + 1}" for j in range(N)],
              f"pose_id, plane, q1..q{N} are required")
    measured = t.all_or_none(["x", "y", "z"], "measured tips")
    q = t.joints_deg(model, check_limits)
    plane = t.numeric("plane")
    for r, v in enumerate(plane):
        if v not in (1.0, 2.0, 3.0, 4.0):
            raise DataError(f"{t.source}: line {t.lines[r]}, column plane: {v:g} is not 1, 2, "
                            "3 or 4")
    pose_id = t.ids("pose_id")
    xyz = np.column_stack([t.numeric(c) for c in "xyz"]) if measured else None
    frame = t.meta.get("xyz_frame", "base").strip().lower()
    if frame not in ("base", "tracker"):
        raise DataError(f"{t.source}: xyz_frame: {frame!r} is not base or tracker")
    return Postures(np.radians(q), plane.astype(int), pose_id, xyz, t.source, t.lines, frame)


def postures_from_dataset(data: Dataset, plane: np.ndarray | None = None,
                          measured: bool = True, xyz_frame: str = "base") -> Postures:
    """Postures from a :class:`Dataset` (e.g. a ``zero20`` run from the store).

    ``plane`` (n,) defaults to 5 consecutive postures per plane; ``measured`` keeps the
    data's ``xyz`` (mm) as measured tips, in the frame ``xyz_frame`` (``"base"`` or
    ``"tracker"``, see :class:`Postures`).
    """
    if plane is None:
        plane = np.arange(data.n) // 5 % 4 + 1
    return Postures(data.q, plane, list(data.pose_id), data.xyz if measured else None,
                    data.source, data.lines, xyz_frame)


def _frame_from_z(z: np.ndarray, x_hint: np.ndarray) -> np.ndarray:
    """Rotation matrices (n, 3, 3) with z axis z (n, 3) and x axis as near x_hint (n, 3)."""
    z = z / np.linalg.norm(z, axis=1, keepdims=True)
    x = x_hint - np.sum(x_hint * z, axis=1, keepdims=True) * z
    x /= np.linalg.norm(x, axis=1, keepdims=True)
    return np.stack([x, np.cross(z, x), z], axis=2)


def zero20_directions(target_mm: np.ndarray, *, n_planes: int = 4, per_plane: int = 5,
                      tilts_deg=(-35.0, -17.5, 0.0, 17.5, 35.0), spin_deg: float = 25.0):
    """Flange orientations for the 4-plane, 20-posture routine.

    Plane k is the vertical plane through the target at azimuth ``atan2(y, x) + k·45°``;
    in it the tool axis (flange z, pointing at the target) is tilted from straight down
    by each of ``tilts_deg``, and the flange is turned about the tool axis by
    ``spin_deg`` times the posture's index in the plane (varied wrist postures).

    Returns
    -------
    R : (n_planes·per_plane, 3, 3) flange orientations, base frame
    plane : (n_planes·per_plane,) plane number 1..n_planes
    """
    t = np.asarray(target_mm, float)
    az0 = math.atan2(t[1], t[0])
    tilts = np.radians(np.asarray(tilts_deg, float))[:per_plane]
    az = az0 + np.arange(n_planes) * np.pi / n_planes
    A, T = np.meshgrid(az, tilts, indexing="ij")
    A, T = A.ravel(), T.ravel()
    z = np.stack([np.sin(T) * np.cos(A), np.sin(T) * np.sin(A), -np.cos(T)], axis=1)
    normal = np.stack([-np.sin(A), np.cos(A), np.zeros_like(A)], axis=1)
    spin = np.radians(spin_deg) * np.tile(np.arange(per_plane) - per_plane // 2, n_planes)
    # turn the in-plane normal about the tool axis by the spin
    x = (np.cos(spin)[:, None] * normal + np.sin(spin)[:, None] * np.cross(z, normal))
    plane = np.repeat(np.arange(1, n_planes + 1), per_plane)
    return _frame_from_z(z, x), plane


def zero20_postures(
    convention: str,
    table: np.ndarray,
    tool_mm: np.ndarray,
    target_mm: np.ndarray,
    *,
    q_seed: np.ndarray | None = None,
    limits: np.ndarray | None = None,
    rng: np.random.Generator | None = None,
    n_starts: int = 32,
    flip_shoulder: bool = True,
    **direction_options,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """20 postures (5 on each of 4 planes) that put the tool point on one target.

    Inverse kinematics (batched, several starts) on the given chain, normally the
    *true* robot's: the returned joints are the true joint angles. Planes 1 and 3 use
    one arm configuration, planes 2 and 4 (with ``flip_shoulder``) the other shoulder
    configuration (joint 1 turned by roughly 150-180°): a single point seen from one
    configuration only hardly determines joint 2's offset, whose effect then barely
    differs from a shift of the target.

    Parameters
    ----------
    convention, table : the chain (table (N, 5), rad and mm)
    tool_mm : (3,) tool point in the flange frame, mm
    target_mm : (3,) the fixed target point, base frame, mm
    q_seed : (N,) preferred configuration (rad); default: the best-conditioned IK
        solution of the middle posture
    limits : (N, 2) joint limits, rad
    rng : for the random starts
    flip_shoulder : use the other shoulder configuration on planes 2 and 4
    direction_options : passed to :func:`zero20_directions`

    Returns
    -------
    q : (20, N) joint angles, rad
    plane : (20,) plane numbers 1..4
    success : (20,) bool, IK reached the target exactly
    """
    rng = rng or np.random.default_rng(0)
    R, plane = zero20_directions(target_mm, **direction_options)
    p_flange = np.asarray(target_mm, float) - R @ np.asarray(tool_mm, float)
    # flange pose targets: the tool point lands on the target
    flange = ChainFK(convention, table, np.zeros(3))
    N = flange.n_joints
    lim = limits if limits is not None else np.tile([-np.pi, np.pi], (N, 1))
    lo, hi = np.maximum(lim[:, 0], -np.pi), np.minimum(lim[:, 1], np.pi)
    seeds = rng.uniform(lo, hi, size=(n_starts, N))
    configs = _configurations(flange, p_flange, R, seeds, limits, q_seed)
    if not flip_shoulder or len(configs) == 1:
        configs = configs[:1]
    ref = np.array([configs[(k - 1) % len(configs)] for k in plane])
    res = solve_ik_multistart(flange, p_flange, R, np.vstack([configs, seeds]), reference=ref,
                              limits=limits, max_iter=200)
    q = ref + wrap_to_pi(res.q - ref)
    if limits is not None:  # prefer the turn that is within the limits
        q = np.where(q > limits[:, 1], q - 2 * np.pi, np.where(q < limits[:, 0], q + 2 * np.pi, q))
    return q, plane, res.success


def _configurations(flange, p_flange, R, seeds, limits, q_seed):
    """One or two reference configurations for the middle posture: the best-conditioned
    IK solution (largest smallest singular value of the scaled Jacobian) or ``q_seed``,
    and the best-conditioned one with joint 1 at least 90° away (the other shoulder)."""
    from .inverse import solve_ik

    mid = len(R) // 2
    res = solve_ik(flange, seeds, p_flange[mid], R[mid], limits=limits, max_iter=200)
    q = wrap_to_pi(res.q[res.success])
    if len(q) == 0:
        return np.atleast_2d(seeds[0] if q_seed is None else q_seed)
    _, _, Jp, Jw = flange(q)
    smin = np.linalg.svd(np.concatenate([Jp / 1000.0, Jw], axis=1), compute_uv=False)[:, -1]
    first = np.asarray(q_seed, float) if q_seed is not None else q[int(np.argmax(smin))]
    other = np.abs(wrap_to_pi(q[:, 0] - first[0])) > np.pi / 2
    if not other.any():
        return first[None]
    second = q[other][int(np.argmax(smin[other]))]
    return np.stack([first, second])


# ---- results -----------------------------------------------------------------------
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


def _kinematics(fk: ChainFK, q: np.ndarray, offsets: np.ndarray, tool: np.ndarray):
    """Tip (n, 3), flange R (n, 3, 3) and dP/d offsets (n, 3, N) at q + offsets."""
    chain = ChainFK(fk.convention, fk.table, tool, offsets)
    P, R, Jp, _ = chain(q)
    return P, R, Jp


def pivot_fit(o: np.ndarray, R: np.ndarray, w: np.ndarray | None = None):
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


def _flange(fk: ChainFK, q, offsets):
    chain = ChainFK(fk.convention, fk.table, np.zeros(3), offsets)
    P, R, _, _ = chain(q)
    return P, R


def _names(N: int) -> list[str]:
    return ([f"zero.j{j + 1}" for j in range(N)] + ["tool.x", "tool.y", "tool.z"]
            + ["target.x", "target.y", "target.z"])


def _identify_free(fk: ChainFK, postures: Postures, offsets, tool, target, measured: bool,
                   rtol: float = 1e-3):
    """Identifiability of (offsets, tool, target) from the postures: QR with pivoting.

    Structural, like :func:`~calibration.identify.identify` at the nominal geometry: the
    Jacobian is taken as if every tip were exactly on the target, so exact redundancies
    (joint 1 with the target, the last joint with the tool) stay exact.
    """
    N = fk.n_joints
    r = run_chain(fk.convention, fk.table, postures.q + offsets, tool, jacobian=False)
    n = postures.n
    Jq = cross(r.joint_axes, np.asarray(target, float) - r.joint_origins).transpose(0, 2, 1)
    R = r.flange_R
    J = np.concatenate([Jq, R, -np.broadcast_to(np.eye(3), (n, 3, 3))], axis=2)
    if measured:  # tip measured: rows tip - measured (target does not enter)
        Jm = np.concatenate([Jq, R, np.zeros((n, 3, 3))], axis=2)
        J = np.concatenate([J, Jm], axis=0)
    return _analyse(J.reshape(-1, N + 6), N, n, rtol)


def _analyse(J2: np.ndarray, N: int, n: int, rtol: float):
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


def _gauss_newton(fk, postures, x0, free, measured_base, max_iter, history):
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


def _rigorous_rj(fk, postures, x, measured_base):
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


def _worst_outlier(r, Jf, sigma_mm, p, n, measured):
    """Index of the posture whose residual is improbable, or None.

    r : (m, 3) residual rows; Jf : (3 m, k) Jacobian of the free parameters; n postures.
    """
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
    limit = scipy.stats.chi2.ppf(1 - p, 6 if measured else 3)
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


# ---- assessment -------------------------------------------------------------------
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


def summary(result: ZeroResult, model_name: str, n_poses: int, *, tolerance_deg: float,
            sigma_mm: float, measured: bool = False) -> dict:
    """The ``zero --json`` object (FORMATS.md §4) plus extra keys."""
    status, reasons = assess(result, tolerance_deg=tolerance_deg, sigma_mm=sigma_mm,
                             measured=measured)
    det = result.determined
    off = [round(math.degrees(v), 6) if d else None
           for v, d in zip(result.offsets, det, strict=True)]
    std = [round(math.degrees(s), 6) if d and np.isfinite(s) else None
           for s, d in zip(result.std, det, strict=True)]
    changed = [f"j{j + 1}" for j in range(len(det))
               if det[j] and abs(math.degrees(result.offsets[j])) > tolerance_deg]
    return {
        "model": model_name,
        "n_poses": n_poses,
        "offsets_deg": off,
        "std_deg": std,
        "unidentifiable": result.unidentifiable,
        "tool_mm": [round(float(v), 6) for v in result.tool],
        "target_mm": [round(float(v), 6) for v in result.target],
        "rms_mm": round(result.rms_mm, 6),
        "status": status,
        "method": result.method,
        "changed": changed,
        "tolerance_deg": tolerance_deg,
        "reasons": reasons,
        "outliers": result.outliers,
        "converged": result.converged,
        "reason": result.reason,
        "iterations": result.iterations,
        "solve_s": round(result.solve_s, 6),
        "offsets_rad": [float(v) for v in result.offsets],
    }


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
        (``xyz``, base frame)

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
    xyz = None
    if tracker_sigma_mm is not None:
        xyz = fk.point(q_true) + rng.normal(0.0, tracker_sigma_mm, size=(len(q_true), 3))
    q_reported = q_true - np.asarray(hidden_offsets, float)
    return Postures(q_reported, plane, xyz=xyz, source="simulated"), q_true
