"""The one motion check: every move before it is sent, and what the robot did after it.

The dry run (:func:`daq.check.check_plan`) and the executor (every move of every point:
planned joint and linear moves, vias, zero20's corrections and probe moves, resumed
runs) check motion with the same :class:`MotionGuard`, built from the robot model and the
run's :class:`MotionLimits` (stored with the run, so a resume checks what the start did).

Before a move (:meth:`MotionGuard.check_joint_move`, :meth:`MotionGuard.check_linear_move`)
    * the joint count and finite values;
    * the model's joint limits at the target;
    * where the move ends (and, with ``check_paths``, along a joint move sampled every
      ``path_step_rad``; always along a linear move's segment for its tool point): the
      floor plane (``floor_z_mm``: link origins after the first joint and the tool point,
      base frame), the keep-out boxes (``keepout_mm``) and the reach (``max_reach_mm``,
      the tool point from the base origin);
    * a linear move: the planned posture is the one the controller reaches moving the
      short way from where the robot stands (no joint more than half a turn away: a
      multi-turn circle that left joint 1 at +360 deg would otherwise land elsewhere);
    * an adaptive move (one the plan did not list: a correction, a probe): within
      ``max_dev_rad`` per joint and ``max_dev_mm`` of tool motion from the point's
      planned posture.

After a move (:meth:`MotionGuard.check_arrival`)
    the joints read back must match the command within ``joint_tol_rad`` (a joint move)
    or put the nominal tool point within ``tcp_tol_mm`` of the target and the joints
    within ``max_dev_rad`` of the planned posture (a linear move).

A refused move raises :class:`MotionRefused`, a robot that is not where it was sent
:class:`MotionMismatch`; both are capture errors that pause the run (never retried,
never a stored sample). Units: rad, mm.
"""

from __future__ import annotations

import math

import numpy as np
from pydantic import BaseModel, ConfigDict, Field, field_validator

from calibration.model.kinematics import run_chain

from .errors import CaptureError

Box = tuple[float, float, float, float, float, float]


class MotionLimits(BaseModel):
    """What a run's moves must respect besides the joint limits (mm, rad), stored with the
    run (:class:`daq.run_context.RunContext`)."""

    model_config = ConfigDict(frozen=True, extra="forbid", allow_inf_nan=False)

    #: lowest z of link origins and the tool point (base frame); None: no floor
    floor_z_mm: float | None = 0.0
    #: largest distance of the tool point from the base origin; None: no limit
    max_reach_mm: float | None = Field(None, gt=0)
    #: boxes (x0, y0, z0, x1, y1, z1, base frame) no link origin or tool point may enter
    keepout_mm: tuple[Box, ...] = ()
    #: joints read after a joint move must match the command within this
    joint_tol_rad: float = Field(0.002, gt=0)
    #: the nominal tool point after a linear move must be within this of the target
    tcp_tol_mm: float = Field(1.0, gt=0)
    #: adaptive moves (and the landing of linear ones): each joint within this of the
    #: point's planned posture
    max_dev_rad: float = Field(0.06, gt=0)
    #: adaptive moves: the nominal tool point within this of the planned posture's
    max_dev_mm: float = Field(25.0, gt=0)
    #: also check the postures along every joint move (sampled every ``path_step_rad``),
    #: not only where it ends: a joint move between two postures above the floor can dip
    #: below it (random calibration poses often do), so a plan of free poses may need
    #: vias before it passes
    check_paths: bool = False
    path_step_rad: float = Field(0.05, gt=0)

    @field_validator("keepout_mm")
    @classmethod
    def _boxes(cls, v):
        for b in v:
            if not all(lo < hi for lo, hi in zip(b[:3], b[3:], strict=True)):
                raise ValueError(f"keep-out box {list(b)}: expected x0,y0,z0,x1,y1,z1 with "
                                 "each lower corner below the upper one")
        return v


class MotionRefused(CaptureError):
    """A move was refused before it was sent (limits, floor, keep-out, reach, deviation)."""

    kind = "move_refused"


class MotionMismatch(CaptureError):
    """The robot is not where it was sent (joints read back differ from the command)."""

    kind = "motion_mismatch"


def _deg(v: float) -> str:
    return f"{math.degrees(v):.3f} deg"


class MotionGuard:
    """Checks moves against a robot model and :class:`MotionLimits`.

    ``model`` may be None: then only the read-back (:meth:`check_arrival` of joint moves)
    and the joint count of the first reading are checked.
    """

    def __init__(self, model=None, limits: MotionLimits | None = None) -> None:
        self.model = model
        self.limits = limits or MotionLimits()
        if model is not None:
            self._lim = model.limits_rad()
            self._table = model.dh_table()
            self._tool = model.tool_mm()

    # ------------------------------------------------------------ geometry
    def _chain(self, Q: np.ndarray):
        m = self.model
        return run_chain(m.convention, self._table, Q, self._tool, jacobian=False,
                         prismatic=m.prismatic_mask())

    def tool_points(self, Q) -> np.ndarray:
        """Nominal tool points (mm, base frame) at joints ``Q`` ((n, N) rad): (n, 3)."""
        return self._chain(np.atleast_2d(np.asarray(Q, float))).base_p_tcp

    def pose_problems(self, Q) -> list[tuple[int, str]]:
        """(row, reason) for every posture of ``Q`` ((n, N) rad) that breaks a joint limit,
        the floor, a keep-out box or the reach; vectorised."""
        return sorted(self.limit_problems(Q) + self.space_problems(Q), key=lambda p: p[0])

    def limit_problems(self, Q) -> list[tuple[int, str]]:
        """(row, reason) for every joint of ``Q`` ((n, N) rad) beyond the model's limits."""
        Q = np.atleast_2d(np.asarray(Q, float))
        if self.model is None or Q.size == 0:
            return []
        lo = (Q - self._lim[:, 0]) < -1e-9
        hi = (Q - self._lim[:, 1]) > 1e-9
        out = []
        for r, j in zip(*np.nonzero(lo | hi), strict=True):
            side = "min" if lo[r, j] else "max"
            bound = math.degrees(self._lim[j, 0 if side == "min" else 1])
            out.append((int(r), f"joint {j + 1} = {math.degrees(Q[r, j]):.3f} deg beyond its "
                                f"{side} limit {bound:g} deg"))
        return out

    def space_problems(self, Q) -> list[tuple[int, str]]:
        """(row, reason) for every posture of ``Q`` whose link origins or tool point are
        below the floor or inside a keep-out box, or whose tool point is beyond the reach."""
        Q = np.atleast_2d(np.asarray(Q, float))
        if self.model is None or Q.size == 0:
            return []
        N = self.model.n_joints
        chain = self._chain(Q)
        # link origins after each joint (frames 1..N) and the tool point
        pts = np.concatenate([chain.frames_p[:, 1:, :], chain.base_p_tcp[:, None, :]], axis=1)

        def name(k: int) -> str:
            return "tool point" if k == N else f"origin of link {k + 1}"

        L, out = self.limits, []
        if L.floor_z_mm is not None:
            for r, k in zip(*np.nonzero(pts[:, :, 2] < L.floor_z_mm), strict=True):
                out.append((int(r), f"{name(k)} at z = {pts[r, k, 2]:.1f} mm, below the floor "
                                    f"{L.floor_z_mm:g} mm"))
        for b, box in enumerate(L.keepout_mm):
            lo_c, hi_c = np.asarray(box[:3]), np.asarray(box[3:])
            inside = np.all((pts > lo_c) & (pts < hi_c), axis=2)
            for r, k in zip(*np.nonzero(inside), strict=True):
                out.append((int(r), f"{name(k)} at {np.round(pts[r, k], 1).tolist()} mm inside "
                                    f"keep-out box {b + 1}"))
        if L.max_reach_mm is not None:
            dist = np.linalg.norm(chain.base_p_tcp, axis=1)
            for r in np.flatnonzero(dist > L.max_reach_mm):
                out.append((int(r), f"tool point {dist[r]:.1f} mm from the base, beyond the "
                                    f"reach limit {L.max_reach_mm:g} mm"))
        return out

    def path(self, q_from, q_to) -> np.ndarray:
        """Postures along a joint move (joint space, every ``path_step_rad``), both ends
        included: (k, N)."""
        a, b = np.asarray(q_from, float), np.asarray(q_to, float)
        k = int(min(200, max(2, math.ceil(float(np.max(np.abs(b - a), initial=0.0))
                                          / self.limits.path_step_rad) + 1)))
        s = np.linspace(0.0, 1.0, k)[:, None]
        return a + s * (b - a)

    def path_problems(self, q_from, q_to) -> list[str]:
        """Why a joint move from ``q_from`` to ``q_to`` is refused (limits at the target,
        floor, keep-out and reach along the way); [] when it is fine."""
        P = self.path(q_from, q_to) if self.limits.check_paths else np.atleast_2d(q_to)
        out = [m for _, m in self.limit_problems(P[-1:])]
        seen = set()
        for r, msg in self.space_problems(P):
            key = msg.split(" at ")[0].split(" mm from")[0]
            if key not in seen:  # the first posture on the way that breaks it
                seen.add(key)
                out.append(f"{msg} ({'at the target' if r == len(P) - 1 else 'on the way'})")
        return out

    # --------------------------------------------------------------- moves
    def _shape(self, q, what: str) -> np.ndarray:
        q = np.asarray(q, float).ravel()
        n = None if self.model is None else self.model.n_joints
        if n is not None and q.shape != (n,):
            raise ValueError(f"{what} has {q.size} joints, the model {self.model.name} has {n}")
        if not np.all(np.isfinite(q)):
            raise ValueError(f"{what} is not finite: {q.tolist()}")
        return q

    def deviation_problems(self, q, planned) -> list[str]:
        """Why ``q`` is too far from the point's planned posture for an adaptive move."""
        q, planned = np.asarray(q, float), np.asarray(planned, float)
        L, out = self.limits, []
        d = np.abs(q - planned)
        j = int(np.argmax(d))
        if d[j] > L.max_dev_rad:
            out.append(f"joint {j + 1} {_deg(d[j])} from the planned posture (at most "
                       f"{_deg(L.max_dev_rad)})")
        if self.model is not None:
            p = self.tool_points(np.vstack([q, planned]))
            dist = float(np.linalg.norm(p[0] - p[1]))
            if dist > L.max_dev_mm:
                out.append(f"tool point {dist:.1f} mm from the planned posture's (at most "
                           f"{L.max_dev_mm:g} mm)")
        return out

    def check_joint_move(self, q_from, q, *, planned=None, adaptive: bool = False) -> list[str]:
        """Problems of a joint move from ``q_from`` (the joints read, or None when unknown)
        to ``q``; ``adaptive`` moves also stay near ``planned``. [] when it may be sent."""
        try:
            q = self._shape(q, "the target")
        except ValueError as e:
            return [str(e)]
        if self.model is None:
            return []
        start = q if q_from is None else np.asarray(q_from, float)
        out = self.path_problems(start, q)
        if adaptive and planned is not None:
            out += self.deviation_problems(q, planned)
        return out

    def check_linear_move(self, q_from, xyz, *, planned=None) -> list[str]:
        """Problems of a linear move of the tool point from where the robot stands
        (``q_from``) to ``xyz`` (mm), expected to end at the planned posture ``planned``."""
        xyz = np.asarray(xyz, float)
        if xyz.shape != (3,) or not np.all(np.isfinite(xyz)):
            return [f"the target {xyz.tolist()} is not a finite x, y, z"]
        if self.model is None or q_from is None:
            return []
        q_from = np.asarray(q_from, float)
        out = []
        if planned is not None:
            planned = np.asarray(planned, float)
            turn = planned - q_from
            for j in np.flatnonzero(np.abs(turn) > math.pi):
                out.append(f"joint {j + 1} stands at {_deg(q_from[j])}, the planned posture "
                           f"has {_deg(planned[j])}: a linear move turns it the short way "
                           "and would not land on the planned posture (move joints first)")
            out += [m for _, m in self.pose_problems(planned[None])]
        # the tool point along the segment (floor, keep-out, reach of the tool point)
        p0 = self.tool_points(q_from[None])[0]
        k = int(min(200, max(2, math.ceil(float(np.linalg.norm(xyz - p0)) / 10.0) + 1)))
        seg = p0 + np.linspace(0.0, 1.0, k)[:, None] * (xyz - p0)
        out += self._point_problems(seg)
        return out

    def _point_problems(self, pts: np.ndarray) -> list[str]:
        L, out = self.limits, []
        if L.floor_z_mm is not None and np.any(pts[:, 2] < L.floor_z_mm):
            out.append(f"the tool point passes z = {pts[:, 2].min():.1f} mm, below the floor "
                       f"{L.floor_z_mm:g} mm")
        for b, box in enumerate(L.keepout_mm):
            if np.any(np.all((pts > np.asarray(box[:3])) & (pts < np.asarray(box[3:])), axis=1)):
                out.append(f"the tool point passes through keep-out box {b + 1}")
        if L.max_reach_mm is not None:
            far = float(np.linalg.norm(pts, axis=1).max())
            if far > L.max_reach_mm:
                out.append(f"the tool point passes {far:.1f} mm from the base, beyond the reach "
                           f"limit {L.max_reach_mm:g} mm")
        return out

    # ------------------------------------------------------------- arrival
    def check_arrival(self, q_read, *, q_cmd=None, xyz=None, planned=None) -> list[str]:
        """Whether the joints read after a move are where it sent the robot: a joint move
        (``q_cmd``) within ``joint_tol_rad``; a linear move (``xyz``) with the nominal
        tool point within ``tcp_tol_mm`` and the joints within ``max_dev_rad`` of
        ``planned``. [] when they are."""
        q_read = np.asarray(q_read, float).ravel()
        L = self.limits
        if q_cmd is not None:
            q_cmd = np.asarray(q_cmd, float).ravel()
            if q_read.shape != q_cmd.shape:
                return [f"the controller reports {q_read.size} joints, {q_cmd.size} were sent"]
            d = np.abs(q_read - q_cmd)
            j = int(np.argmax(d))
            if d[j] > L.joint_tol_rad:
                return [f"joint {j + 1} reads {_deg(q_read[j])}, sent to {_deg(q_cmd[j])} "
                        f"({_deg(d[j])} off, tolerance {_deg(L.joint_tol_rad)})"]
            return []
        out = []
        if xyz is not None and self.model is not None:
            miss = float(np.linalg.norm(self.tool_points(q_read[None])[0] - np.asarray(xyz)))
            if miss > L.tcp_tol_mm:
                out.append(f"the nominal tool point is {miss:.2f} mm from the linear move's "
                           f"target (tolerance {L.tcp_tol_mm:g} mm; is the model's tool, "
                           "--tool-mm, the controller's TCP?)")
        if planned is not None:
            d = np.abs(q_read - np.asarray(planned, float))
            j = int(np.argmax(d))
            if d[j] > L.max_dev_rad:
                out.append(f"joint {j + 1} reads {_deg(q_read[j])}, the planned posture has "
                           f"{_deg(planned[j])} ({_deg(d[j])} off, at most "
                           f"{_deg(L.max_dev_rad)})")
        return out
