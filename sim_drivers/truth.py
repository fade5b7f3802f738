"""The simulated cell's "true" robot: what the hidden physics makes of a joint command.

:class:`TrueRobot` is the protocol the simulated cell (``SimCell``) uses; the
implementation backed by the calibration core (a nominal model plus hidden
errors and effects) lives beside it. Units: joints in rad, lengths in mm.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Protocol

import numpy as np


@dataclass
class PoseContext:
    """What the hidden physics may depend on besides the joint angles.

    ``direction``: per joint, the sign of the last motion that approached the
    pose (-1, 0, +1), for backlash. ``temp_c``: robot temperature.
    ``t_s``: simulated time. ``payload_kg``: payload mass, None for the model's.
    ``joint_temp``: each joint's temperature (°C) as the controller reports it (constant
    without a thermal model), None when it reports none.
    """

    direction: np.ndarray | None = None
    temp_c: float = 20.0
    t_s: float = 0.0
    payload_kg: float | None = None
    extra: dict = field(default_factory=dict)
    joint_temp: np.ndarray | None = None


class TrueRobot(Protocol):
    """The robot as it really is (hidden errors included) and as its controller believes it is."""

    #: number of joints
    n_joints: int
    #: joint limits, shape (n_joints, 2), rad
    limits: np.ndarray

    def true_point(self, q: np.ndarray, ctx: PoseContext) -> np.ndarray:
        """True target (SMR) centre in the tracker frame, mm; ``q`` shape (n_joints,), rad."""
        ...

    def nominal_tcp(self, q: np.ndarray) -> np.ndarray:
        """The controller's own (nominal) TCP position in the robot base frame, mm."""
        ...

    def nominal_ik(self, xyz: np.ndarray, q_seed: np.ndarray) -> np.ndarray:
        """Joints (rad) at which the nominal model puts the TCP at ``xyz`` (mm, base frame),
        the solution nearest ``q_seed``; raises ``ValueError`` when unreachable."""
        ...


class ToyArm:
    """A three-joint planar-ish arm with an exact closed form: a stand-in for unit tests of
    the cell's mechanics that must not depend on the calibration core.

    Links 400 mm and 300 mm in the x-y plane after a base rotation about z, the target
    100 mm above the last joint. ``error`` (rad, per joint) is a hidden zero offset, and
    ``tracker_offset`` (mm) the tracker frame's origin in the base frame.
    """

    n_joints = 3
    #: the model this arm is (tests/daq/data/toyarm.yaml)
    name = "toyarm"

    def __init__(self, error=(0.0, 0.0, 0.0), tracker_offset=(2000.0, 0.0, 0.0)):
        self.limits = np.array([[-np.pi, np.pi]] * 3)
        self.error = np.asarray(error, float)
        self.tracker_offset = np.asarray(tracker_offset, float)

    @staticmethod
    def _fk(q):
        q = np.asarray(q, float)
        r = 400.0 * np.cos(q[1]) + 300.0 * np.cos(q[1] + q[2])
        z = 400.0 * np.sin(q[1]) + 300.0 * np.sin(q[1] + q[2]) + 100.0
        return np.array([r * np.cos(q[0]), r * np.sin(q[0]), z])

    def true_point(self, q, ctx):
        return self._fk(np.asarray(q) + self.error) - self.tracker_offset

    def nominal_tcp(self, q):
        return self._fk(q)

    def nominal_ik(self, xyz, q_seed):
        x, y, z = np.asarray(xyz, float)
        q0 = np.arctan2(y, x)
        r, h = np.hypot(x, y), z - 100.0
        c2 = (r * r + h * h - 400.0**2 - 300.0**2) / (2 * 400.0 * 300.0)
        if abs(c2) > 1:
            raise ValueError(f"point {xyz} out of reach")
        cands = []
        for s in (1.0, -1.0):
            q2 = s * np.arccos(c2)
            q1 = np.arctan2(h, r) - np.arctan2(300.0 * np.sin(q2), 400.0 + 300.0 * np.cos(q2))
            cands.append(np.array([q0, q1, q2]))
        seed = np.asarray(q_seed, float)
        return min(cands, key=lambda c: float(np.sum((c - seed) ** 2)))
