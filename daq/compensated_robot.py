"""Compensated motion from Python: a robot that goes where the nominal targets meant.

A cell that drives its robot from Python (ur-rtde, Modbus, the line protocol: any
:class:`~drivers.protocols.RobotDriver`) wraps the open driver in a
:class:`CompensatedRobot` with a calibration. Targets are given as the nominal model means
them: joints (where the nominal model puts the TCP), a TCP pose (4x4, robot base frame,
mm) or a point (the orientation the robot has now). The wrapper solves for the joints at
which the *calibrated* robot's TCP is there (:mod:`calibration.compensation.pose_compensation`, with
the thermal state, the payload and the approach direction where the model has them) and
sends them as a joint move. Every move passes the checks a capture's moves pass
(:class:`~daq.motion_guard.MotionGuard`: limits, floor, keep-out boxes, reach; after the
move the joints read back must match), and refusals raise the same errors.

The driver's linear move keeps the controller's nominal orientation and cannot carry a
compensated one, so Cartesian targets become joint moves. Units: mm, rad.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from calibration.compensation.pose_compensation import (
    NominalTcpFK,
    PoseCompensation,
    compensate_targets,
)
from drivers.protocols import JointReading, RobotDriver

from .motion_guard import MotionGuard, MotionLimits, MotionMismatch, MotionRefused


class CompensatedRobot:
    """An open robot driver plus a calibration.

    Parameters
    ----------
    robot : an open (connected) RobotDriver
    error_model, x : the calibration (e.g. :func:`calibration.exports.params_io.read_params`'s
        ``error_model`` and ``values``)
    flange_T_tcp : the TCP (4x4, flange frame, mm); None: the point the calibration
        measured (its tool stage; the nominal model's tool for the controller)
    temp_c : the robot's temperature (°C): a number, or a function read before every
        move; needed when the model has thermal growth
    payload_kg : the payload, when the model has compliance (None: the model's)
    limits : the motion limits (default :class:`MotionLimits`: the floor at z = 0)
    speed_rad_s, timeout_s : of every joint move
    """

    def __init__(self, robot: RobotDriver, error_model, x, *, flange_T_tcp=None,
                 temp_c: float | Callable[[], float] | None = None,
                 payload_kg: float | None = None, limits: MotionLimits | None = None,
                 speed_rad_s: float = 0.5, timeout_s: float = 60.0) -> None:
        self.robot = robot
        self.error_model, self.x = error_model, np.asarray(x, float)
        self.flange_T_tcp = None if flange_T_tcp is None else np.asarray(flange_T_tcp, float)
        self.temp_c, self.payload_kg = temp_c, payload_kg
        self.guard = MotionGuard(error_model.model, limits)
        self.speed_rad_s, self.timeout_s = speed_rad_s, timeout_s
        #: the last compensation sent (for a caller's log)
        self.last: PoseCompensation | None = None

    # ------------------------------------------------------------------ numbers
    def _columns(self, q_from: np.ndarray, q_to: np.ndarray) -> dict:
        cols = {"dirs": np.sign(q_to - q_from).astype(int)[None]}
        t = self.temp_c() if callable(self.temp_c) else self.temp_c
        if t is not None:
            cols["temp_c"] = np.array([float(t)])
        if self.payload_kg is not None:
            cols["payload_kg"] = np.array([float(self.payload_kg)])
        return cols

    def _solve(self, joints, pose, q_from) -> PoseCompensation:
        joints = np.asarray(joints, float).reshape(1, -1)
        c = compensate_targets(
            self.error_model, self.x, joints, pose=None if pose is None else pose[None],
            is_pose=np.array([pose is not None]), flange_T_tcp=self.flange_T_tcp,
            columns=self._columns(q_from, joints[0]), calibrated_tool=self.flange_T_tcp is None)
        if not c.success[0]:
            raise MotionRefused(self._device, "compensated move",
                                f"the calibrated robot cannot reach the target ({c.reason})")
        return c

    def compensate_joints(self, q) -> PoseCompensation:
        """The compensation of a joint target ``q`` (rad), from where the robot stands."""
        return self._solve(q, None, self.read_joints().q)

    def compensate_pose(self, base_T_tcp, seed=None) -> PoseCompensation:
        """The compensation of a TCP pose (4x4, mm), solved near ``seed`` (rad; default the
        joints the robot stands at: the configuration it is in)."""
        q_now = self.read_joints().q
        return self._solve(q_now if seed is None else seed, np.asarray(base_T_tcp, float),
                           q_now)

    # ------------------------------------------------------------------- motion
    @property
    def _device(self) -> str:
        return f"robot {getattr(self.robot, 'url', '')}"

    def read_joints(self) -> JointReading:
        return self.robot.read_joints(timeout=min(self.timeout_s, 2.0))

    def move_joints(self, q) -> JointReading:
        """Move so the TCP is where the nominal model puts it at joints ``q`` (rad)."""
        self.last = self.compensate_joints(q)
        return self.send(self.last.q[0])

    def move_pose(self, base_T_tcp, seed=None) -> JointReading:
        """Move the TCP to a pose (4x4, robot base frame, mm) as the nominal model means it."""
        self.last = self.compensate_pose(base_T_tcp, seed)
        return self.send(self.last.q[0])

    def move_point(self, xyz) -> JointReading:
        """Move the TCP to a point (mm, robot base frame), keeping the orientation the
        nominal model gives the robot where it stands."""
        q_now = self.read_joints().q
        model = self.error_model.model
        r = NominalTcpFK(model, model.tool_mm()).chain(q_now[None])
        T = np.eye(4)
        T[:3, :3], T[:3, 3] = r.base_R_flange[0], np.asarray(xyz, float)
        if self.flange_T_tcp is not None:
            T[:3, :3] = T[:3, :3] @ self.flange_T_tcp[:3, :3]
        self.last = self._solve(q_now, T, q_now)
        return self.send(self.last.q[0])

    def send(self, q) -> JointReading:
        """A checked joint move to ``q`` (rad, already compensated), settled and read back."""
        q = np.asarray(q, float)
        q_now = self.read_joints().q
        problems = self.guard.check_joint_move(q_now, q)
        if problems:
            raise MotionRefused(self._device, "compensated move",
                                "joint move refused: " + "; ".join(problems))
        self.robot.move_joints(q, speed=self.speed_rad_s, timeout=self.timeout_s)
        reading = self.read_joints()
        problems = self.guard.check_arrival(reading.q, q_cmd=q)
        if problems:
            raise MotionMismatch(self._device, "compensated move",
                                 "after the joint move: " + "; ".join(problems))
        return reading
