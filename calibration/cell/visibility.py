"""Can the tracker see the SMR? Line-of-sight geometry vectorised over poses.

A laser tracker measures a spherically mounted reflector (SMR) only when

* the SMR's opening faces it: the angle between the SMR axis (fixed in the flange
  frame, :class:`~calibration.cell.cell.Smr`) and the direction from the SMR to the tracker
  is within the reflector's acceptance half-angle (about 30 deg for a 1.5" SMR), and
* the beam, the straight segment from the SMR centre to the tracker head, passes by
  the robot's own links and the cell's fixtures.

The links are capsules (:func:`link_capsules`): around each row's d and a segments of
the kinematic chain (the skeleton through the frame origins) with the row's
``link_radius``; the last link's capsule ends flat at the flange, so an SMR on a short
holder in front of the flange is not hidden by its own wrist. Fixtures are boxes and
cylinders (:mod:`calibration.cell.cell`). :func:`assess` checks every pose at once and
:class:`Sight` says why a pose is not visible. With the margins of a plan (the
facing margin, the clearance) it is the planner's prediction; with no margins and the
true robot it is the simulated tracker's physics.

Poses the tracker sees are built, not searched for: :func:`facing_rotations` turns the
flange so the SMR axis points along a chosen direction (random within the acceptance
cone about the tracker, :func:`sample_cone`) and :func:`solve_facing` solves the pose
by batched inverse kinematics.

Lengths mm, angles rad inside (degrees only in :class:`Sight`'s reports).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np
import numpy.typing as npt

from ..model.inverse import ChainFK, solve_ik, wrap_to_pi
from ..model.kinematics import run_chain
from ..model.robot_model import RobotModel
from .cell import Box, CellSpec, Cylinder, Fixture

_EPS = 1e-12


def _dot(u: np.ndarray, v: np.ndarray) -> np.ndarray:
    return np.einsum("...i,...i->...", u, v)


def _unit(v: np.ndarray) -> np.ndarray:
    return v / np.maximum(np.linalg.norm(v, axis=-1, keepdims=True), _EPS)


# ------------------------------------------------------------------ links
@dataclass(frozen=True)
class Capsules:
    """The robot's links as capsules for n poses: segment ends ``a``, ``b`` (n, k, 3) mm,
    base frame; ``radius`` (k,) mm; ``link`` (k,) the 1-based row each belongs to."""

    a: np.ndarray
    b: np.ndarray
    radius: np.ndarray
    link: np.ndarray


def _row_segments(model: RobotModel) -> list[tuple[int, int]]:
    """The (row, part) segments that make the capsules; part 0 is the row's first
    elementary translation (dh: d, mdh: a), part 1 the second. A zero-length part is kept
    only when its whole row is zero-length (a sphere at the joint)."""
    t = model.dh_table()
    first, second = (1, 2) if model.convention == "dh" else (2, 1)  # table columns
    out = []
    for i in range(model.n_joints):
        parts = [p for p, c in ((0, first), (1, second)) if abs(t[i, c]) > 1e-9]
        out += [(i, p) for p in (parts or [1])]
    return out


def link_capsules(model: RobotModel, q: np.ndarray) -> Capsules:
    """The capsules of ``model``'s links at joints ``q`` (rad, (n, N)).

    Row i's segments run from frame i's origin along its first translation (dh: d along
    z, mdh: a along x) and on to frame i+1's origin. The last row's last segment stops
    ``link_radius`` short of the flange (a flat end: its cap reaches the flange face)."""
    q = np.atleast_2d(np.asarray(q, float))
    r = run_chain(model.convention, model.dh_table(), q, model.tool_mm(), jacobian=False,
                  prismatic=model.prismatic_mask())
    t = model.dh_table()
    radii = model.link_radii()
    dh = model.convention == "dh"
    segs = _row_segments(model)
    A, B = [], []
    for i, part in segs:
        p0, p1 = r.frames_p[:, i], r.frames_p[:, i + 1]
        mid = p0 + (t[i, 1] * r.frames_R[:, i, :, 2] if dh else t[i, 2] * r.frames_R[:, i, :, 0])
        A.append(p0 if part == 0 else mid)
        B.append(mid if part == 0 else p1)
    last = len(segs) - 1
    length = np.linalg.norm(B[last] - A[last], axis=1, keepdims=True)
    if float(length.max(initial=0.0)) > 1e-9:  # a flat end at the flange
        cut = np.minimum(radii[segs[last][0]], length)
        B[last] = B[last] - cut * _unit(B[last] - A[last])
    rows = np.array([i for i, _ in segs])
    return Capsules(np.stack(A, axis=1), np.stack(B, axis=1), radii[rows], rows + 1)


def segment_distance(p0: np.ndarray, p1: np.ndarray, q0: np.ndarray,
                     q1: np.ndarray) -> np.ndarray:
    """Shortest distance between segments p0-p1 and q0-q1 (arrays (..., 3), broadcast), mm.

    The clamped closest-point solution (Ericson, *Real-Time Collision Detection* §5.1.9),
    degenerate segments (points) included."""
    d1, d2, r = p1 - p0, q1 - q0, p0 - q0
    a, e = _dot(d1, d1), _dot(d2, d2)
    b, c, f = _dot(d1, d2), _dot(d1, r), _dot(d2, r)
    a_ok, e_ok = a > _EPS, e > _EPS
    a_s, e_s = np.where(a_ok, a, 1.0), np.where(e_ok, e, 1.0)
    denom = a * e - b * b
    s = np.where(denom > _EPS * np.maximum(a * e, 1.0),
                 np.clip((b * f - c * e) / np.where(denom > 0, denom, 1.0), 0.0, 1.0), 0.0)
    t = (b * s + f) / e_s
    s = np.where(t < 0, np.clip(-c / a_s, 0, 1), np.where(t > 1, np.clip((b - c) / a_s, 0, 1), s))
    t = np.clip(t, 0.0, 1.0)
    # degenerate cases: a point against a segment, or two points
    s = np.where(~a_ok, 0.0, np.where(~e_ok, np.clip(-c / a_s, 0, 1), s))
    t = np.where(~e_ok, 0.0, np.where(~a_ok, np.clip(f / e_s, 0, 1), t))
    return np.linalg.norm(p0 + s[..., None] * d1 - q0 - t[..., None] * d2, axis=-1)


# --------------------------------------------------------------- fixtures
def _interval(lo: np.ndarray, hi: np.ndarray, s_lo: np.ndarray,
              s_hi: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    return np.maximum(lo, s_lo), np.minimum(hi, s_hi)


def box_blocks(p0: np.ndarray, p1: np.ndarray, box: Box, grow_mm: float = 0.0) -> np.ndarray:
    """Whether each segment p0-p1 ((n, 3), base frame, mm) passes through ``box`` grown by
    ``grow_mm`` on every side (slab test in the box's frame), (n,) bool."""
    R, c = box.rotation(), np.asarray(box.centre, float)
    half = np.asarray(box.size, float) / 2 + grow_mm
    u0, d = (p0 - c) @ R, (p1 - p0) @ R
    lo, hi = np.zeros(len(u0)), np.ones(len(u0))
    for k in range(3):
        flat = np.abs(d[:, k]) < _EPS
        dk = np.where(flat, 1.0, d[:, k])
        t1, t2 = (-half[k] - u0[:, k]) / dk, (half[k] - u0[:, k]) / dk
        lo, hi = _interval(lo, hi, np.where(flat, -np.inf, np.minimum(t1, t2)),
                           np.where(flat, np.inf, np.maximum(t1, t2)))
        hi = np.where(flat & (np.abs(u0[:, k]) > half[k]), -np.inf, hi)
    return lo <= hi


def cylinder_blocks(p0: np.ndarray, p1: np.ndarray, cyl: Cylinder,
                    grow_mm: float = 0.0) -> np.ndarray:
    """Whether each segment p0-p1 ((n, 3), mm) passes through the solid cylinder ``cyl``
    grown by ``grow_mm`` (radius and both ends), (n,) bool."""
    s0, s1 = np.asarray(cyl.start, float), np.asarray(cyl.end, float)
    u = _unit(s1 - s0)
    L = float(np.linalg.norm(s1 - s0)) + 2 * grow_mm
    s0, rad = s0 - grow_mm * u, cyl.radius + grow_mm
    d, w0 = p1 - p0, p0 - s0
    h0, hd = w0 @ u, d @ u
    w0r, wdr = w0 - h0[:, None] * u, d - hd[:, None] * u
    lo, hi = np.zeros(len(p0)), np.ones(len(p0))
    flat = np.abs(hd) < _EPS
    hds = np.where(flat, 1.0, hd)
    t1, t2 = -h0 / hds, (L - h0) / hds
    lo, hi = _interval(lo, hi, np.where(flat, -np.inf, np.minimum(t1, t2)),
                       np.where(flat, np.inf, np.maximum(t1, t2)))
    hi = np.where(flat & ((h0 < 0) | (h0 > L)), -np.inf, hi)
    A, Bq, C = _dot(wdr, wdr), 2 * _dot(w0r, wdr), _dot(w0r, w0r) - rad**2
    parallel = A < _EPS
    disc = Bq**2 - 4 * A * C
    root = np.sqrt(np.maximum(disc, 0.0))
    As = np.where(parallel, 1.0, A)
    qlo = np.where(parallel, np.where(C <= 0, -np.inf, np.inf), (-Bq - root) / (2 * As))
    qhi = np.where(parallel, np.where(C <= 0, np.inf, -np.inf), (-Bq + root) / (2 * As))
    qhi = np.where(~parallel & (disc < 0), -np.inf, qhi)
    lo, hi = _interval(lo, hi, qlo, qhi)
    return lo <= hi


# ------------------------------------------------------------------ sight
@dataclass
class Sight:
    """What the tracker sees at n poses (see :func:`assess`).

    Attributes
    ----------
    facing_deg : (n,) angle between the SMR axis and the direction to the tracker, deg
    clearance_mm : (n, k) distance of the beam from each link capsule's surface, mm
    capsule_link : (k,) the 1-based link (row) of each capsule
    fixture_hit : (n, f) the beam passes through fixture j (grown by the clearance)
    fixture_names : the fixtures' names
    limit_deg, clearance_min_mm : the facing limit and the clearance a visible pose keeps
    """

    facing_deg: np.ndarray
    clearance_mm: np.ndarray
    capsule_link: np.ndarray
    fixture_hit: np.ndarray
    fixture_names: list[str] = field(default_factory=list)
    limit_deg: float = 30.0
    clearance_min_mm: float = 0.0

    @property
    def facing_ok(self) -> np.ndarray:
        return self.facing_deg <= self.limit_deg

    @property
    def links_ok(self) -> np.ndarray:
        return np.asarray((self.clearance_mm >= self.clearance_min_mm).all(axis=1))

    @property
    def fixtures_ok(self) -> np.ndarray:
        return np.asarray(~self.fixture_hit.any(axis=1))

    @property
    def visible(self) -> np.ndarray:
        """(n,) bool: facing within the limit, beam clear of every link and fixture."""
        return self.facing_ok & self.links_ok & self.fixtures_ok

    def blocking_link(self, i: int) -> int | None:
        """The link whose capsule comes closest to pose i's beam when it blocks it."""
        c = self.clearance_mm[i]
        if c.size == 0 or c.min() >= self.clearance_min_mm:
            return None
        return int(self.capsule_link[int(np.argmin(c))])

    def reason(self, i: int) -> str:
        """Why pose i is not visible ("" when it is)."""
        out = []
        if not self.facing_ok[i]:
            out.append(f"the SMR faces {self.facing_deg[i]:.1f} deg away from the tracker "
                       f"(limit {self.limit_deg:g} deg)")
        link = self.blocking_link(i)
        if link is not None:
            c = float(self.clearance_mm[i].min())
            out.append(f"link {link} in the beam" if c < 0 else
                       f"the beam passes link {link} by {c:.0f} mm (needs "
                       f"{self.clearance_min_mm:g} mm)")
        out += [f"fixture {n} in the beam" for n, hit in
                zip(self.fixture_names, self.fixture_hit[i], strict=True) if hit]
        return "; ".join(out)


def smr_pose(model: RobotModel, q: np.ndarray,
             axis_flange: npt.ArrayLike) -> tuple[np.ndarray, np.ndarray]:
    """SMR centre (n, 3) mm and its opening direction (n, 3) unit, base frame."""
    r = run_chain(model.convention, model.dh_table(), np.atleast_2d(q), model.tool_mm(),
                  jacobian=False, prismatic=model.prismatic_mask())
    return r.base_p_tcp, _unit(r.base_R_flange @ np.asarray(axis_flange, float))


def facing_angle(p_smr: np.ndarray, axis: np.ndarray, tracker_mm: npt.ArrayLike) -> np.ndarray:
    """Angle (rad, (n,)) between each SMR axis and the direction from the SMR to the tracker."""
    to = _unit(np.asarray(tracker_mm, float) - p_smr)
    return np.arccos(np.clip(_dot(_unit(axis), to), -1.0, 1.0))


def assess(model: RobotModel, q: np.ndarray, cell: CellSpec, *, margins: bool = True,
           smr_p: np.ndarray | None = None, smr_axis: npt.ArrayLike | None = None) -> Sight:
    """Whether the tracker at ``cell.tracker`` sees the SMR at joints ``q`` (rad, (n, N)).

    ``margins``: keep the cell's margins (a plan's prediction) or none (the physics).
    ``smr_p`` (n, 3) overrides the SMR centre (mm, base frame; the simulator's true
    point); ``smr_axis`` (3,) the SMR axis in the flange frame (default the cell's).
    """
    T = cell.tracker_mm
    if T is None:
        raise ValueError("the tracker position is unknown: the cell has no tracker")
    q = np.atleast_2d(np.asarray(q, float))
    p, axis = smr_pose(model, q, cell.smr.axis_unit() if smr_axis is None else smr_axis)
    if smr_p is not None:
        p = np.atleast_2d(np.asarray(smr_p, float))
    facing = np.degrees(facing_angle(p, axis, T))
    caps = link_capsules(model, q)
    tr = np.broadcast_to(T, p.shape)
    clear = (segment_distance(p[:, None], tr[:, None], caps.a, caps.b) - caps.radius)
    grow = cell.margins.clearance_mm if margins else 0.0
    hits = [_fixture_blocks(f, p, tr, grow) for f in cell.fixtures]
    fix = np.stack(hits, axis=1) if hits else np.zeros((len(q), 0), bool)
    limit = cell.smr.half_angle_deg - (cell.margins.facing_deg if margins else 0.0)
    return Sight(facing, clear, caps.link, fix, [f.name for f in cell.fixtures], limit, grow)


def _fixture_blocks(f: Fixture, p0: np.ndarray, p1: np.ndarray, grow_mm: float) -> np.ndarray:
    """Whether each segment p0-p1 passes through the fixture ``f`` (its box or cylinder)."""
    if f.box is not None:
        return box_blocks(p0, p1, f.box, grow_mm)
    assert f.cylinder is not None  # a fixture has exactly one shape (Fixture checks it)
    return cylinder_blocks(p0, p1, f.cylinder, grow_mm)


# ------------------------------------------------------- facing the tracker
def facing_rotations(direction: np.ndarray, roll: np.ndarray,
                     axis_flange: npt.ArrayLike) -> np.ndarray:
    """Flange orientations (n, 3, 3) that turn the SMR axis (flange frame, (3,)) onto each
    unit ``direction`` (n, 3), turned by ``roll`` (n,) rad about it."""
    a = _unit(np.asarray(axis_flange, float))
    d = _unit(np.atleast_2d(direction))

    # columns x, y, z with z given and x as near the hint as may be
    def frame(z: np.ndarray, hint: np.ndarray) -> np.ndarray:
        alt = np.where(np.abs(_dot(hint, z))[..., None] > 0.9, np.roll(hint, 1, axis=-1), hint)
        x = _unit(alt - _dot(alt, z)[..., None] * z)
        return np.stack([x, np.cross(z, x), z], axis=-1)

    G = frame(a[None], np.array([[1.0, 0.0, 0.0]]))[0]  # flange frame: z = the SMR axis
    F = frame(d, np.broadcast_to([0.0, 0.0, 1.0], d.shape).copy())
    c, s = np.cos(roll), np.sin(roll)
    Rz = np.zeros((len(d), 3, 3))
    Rz[:, 0, 0], Rz[:, 0, 1], Rz[:, 1, 0], Rz[:, 1, 1], Rz[:, 2, 2] = c, -s, s, c, 1.0
    return F @ Rz @ G.T


def sample_cone(centre: np.ndarray, half_angle_rad: float, rng: np.random.Generator
                ) -> np.ndarray:
    """Unit directions (n, 3) uniform on the spherical cap of ``half_angle_rad`` about each
    unit ``centre`` (n, 3)."""
    c = _unit(np.atleast_2d(centre))
    n = len(c)
    cos_t = rng.uniform(np.cos(half_angle_rad), 1.0, n)
    phi = rng.uniform(0.0, 2 * np.pi, n)
    sin_t = np.sqrt(1.0 - cos_t**2)
    hint = np.where(np.abs(c[:, 2:3]) > 0.9, [[1.0, 0.0, 0.0]], [[0.0, 0.0, 1.0]])
    e1 = _unit(np.cross(c, hint))
    e2 = np.cross(c, e1)
    return (cos_t[:, None] * c + sin_t[:, None] * (np.cos(phi)[:, None] * e1
                                                   + np.sin(phi)[:, None] * e2))


def solve_facing(model: RobotModel, p_smr: np.ndarray, direction: np.ndarray, roll: np.ndarray,
                 seeds: np.ndarray, axis_flange: npt.ArrayLike) -> tuple[np.ndarray, np.ndarray]:
    """Joints (n, N) that put the SMR at ``p_smr`` (n, 3) with its axis along ``direction``
    (n, 3) and ``roll`` (n,), from the starts ``seeds`` (n, N); and (n,) bool success.

    Batched pose inverse kinematics on the nominal chain within the joint limits; every
    joint turned by whole turns into [-180, 180) deg where its limits allow."""
    R = facing_rotations(direction, roll, axis_flange)
    lim = model.limits_rad()
    res = solve_ik(ChainFK.from_model(model), seeds, p_smr, R, limits=lim, tol_mm=1e-6,
                   tol_rad=1e-9, success_mm=1e-3, success_rad=1e-6)
    # the same pose with every joint turned into [-180, 180) deg where the limits allow
    q = wrap_to_pi(res.q)
    q = np.where((q >= lim[:, 0]) & (q <= lim[:, 1]), q, res.q)
    return q, res.success


def workspace_ok(model: RobotModel, q: np.ndarray, *, floor_z_mm: float | None = 0.0,
                 max_reach_mm: float | None = None) -> np.ndarray:
    """(n,) bool: every link origin after the first joint and the tool point at
    ``z >= floor_z_mm``, the tool point within ``max_reach_mm`` of the base origin."""
    r = run_chain(model.convention, model.dh_table(), np.atleast_2d(q), model.tool_mm(),
                  jacobian=False, prismatic=model.prismatic_mask())
    ok = np.ones(len(r.base_p_tcp), bool)
    if floor_z_mm is not None:
        ok &= (r.frames_p[:, 1:, 2] >= floor_z_mm).all(axis=1) & (r.base_p_tcp[:, 2] >= floor_z_mm)
    if max_reach_mm is not None:
        ok &= np.linalg.norm(r.base_p_tcp, axis=1) <= max_reach_mm
    return ok


def draw_facing(model: RobotModel, cell: CellSpec, m: int, rng: np.random.Generator, *,
                cone_rad: float,
                floor_z_mm: float | None = 0.0, max_reach_mm: float | None = None,
                max_abs_deg: float = 180.0) -> np.ndarray:
    """Joint poses (rad, (k, N), k <= m) drawn to face the tracker, before the line of sight
    is checked: ``m`` uniform poses within the limits and the workspace; for an arm that
    orients its tool (6+ joints) each turned by pose IK so that the SMR axis lies in the
    cone of ``cone_rad`` about the direction to the tracker (a uniform roll about it)."""
    lim = np.clip(model.limits_rad(), -np.radians(max_abs_deg), np.radians(max_abs_deg))
    kw: dict[str, Any] = {"floor_z_mm": floor_z_mm, "max_reach_mm": max_reach_mm}
    axis = cell.smr.axis_unit()
    q = rng.uniform(lim[:, 0], lim[:, 1], size=(m, model.n_joints))
    q = q[workspace_ok(model, q, **kw)]
    if model.n_joints >= 6 and len(q):
        p, _ = smr_pose(model, q, axis)
        d = sample_cone(cell.tracker_mm - p, cone_rad, rng)
        q, ok = solve_facing(model, p, d, rng.uniform(-np.pi, np.pi, len(q)), q, axis)
        q = q[ok & np.all(np.abs(q) <= np.radians(max_abs_deg) + 1e-9, axis=1)]
    return q[workspace_ok(model, q, **kw)] if len(q) else q


def sample_visible(model: RobotModel, cell: CellSpec, n: int, rng: np.random.Generator, *,
                   floor_z_mm: float | None = 0.0, max_reach_mm: float | None = None,
                   max_abs_deg: float = 180.0, rounds: int = 40) -> np.ndarray:
    """Up to ``n`` joint poses (rad, (m, N), m <= n) that the tracker sees, with margins.

    For an arm that orients its tool (6+ joints): SMR positions of uniformly drawn poses
    within the workspace, the SMR axis drawn uniformly in the acceptance cone (less the
    margin) about the direction to the tracker, a uniform roll about it, solved by pose IK
    from the drawn pose (:func:`draw_facing`); kept when within the workspace and the beam
    clears every link and fixture. Smaller arms: uniformly drawn poses that happen to be
    visible. Fewer than ``n`` come back when ``rounds`` batches do not find them.
    """
    cone = np.radians(max(cell.smr.half_angle_deg - cell.margins.facing_deg, 0.0))
    out, have = [], 0
    for _ in range(rounds):
        q = draw_facing(model, cell, max(2 * (n - have), 64), rng, cone_rad=cone,
                        floor_z_mm=floor_z_mm, max_reach_mm=max_reach_mm,
                        max_abs_deg=max_abs_deg)
        if len(q):
            q = q[assess(model, q, cell).visible]
        out.append(q)
        have += len(q)
        if have >= n:
            break
    return np.vstack(out)[:n] if out else np.zeros((0, model.n_joints))
