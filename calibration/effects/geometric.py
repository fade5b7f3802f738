"""Geometric effects: the kinematic parameters, the base and the tool."""

from __future__ import annotations

from typing import Any

import numpy as np

from ..data.dataset import Dataset
from ..model.kinematics import ALPHA, BETA, THETA
from ..model.robot_model import DH_COLUMNS, RobotModel
from ..model.transforms import fit_rigid, matrix_to_rotvec, right_jacobian, rotvec_to_matrix
from .base import Effect, EffectError

_LENGTH_SCALE = 0.1  # mm, typical size of a length error
_ANGLE_SCALE = np.radians(0.01)  # rad, typical size of an angle error


class Geometric(Effect):
    """Errors of the kinematic parameters: Δθ_offset, Δd, Δa, Δα of every joint, and the
    Hayati tilt Δβ on rows whose neighbouring axes are parallel. Units mm and rad; the
    parameters are deltas to the nominal table (``geometric.j2.a`` = Δa₂)."""

    family = "geometric"
    stage = "table"
    summary = "errors of the kinematic parameters (DH/MDH table, Hayati beta)"

    def __init__(self, model: RobotModel, joint: int | None = None,
                 order: int | None = None) -> None:
        super().__init__(model, joint, order)
        parallel = set(model.parallel_rows())
        self.entries: list[tuple[int, int]] = []  # (row, column)
        for j in range(model.n_joints):
            for col, name in enumerate(DH_COLUMNS):
                if col == BETA and j not in parallel:
                    continue
                self.entries.append((j, col))
                short = "theta" if name == "theta_offset" else name
                self.param_names.append(f"j{j + 1}.{short}")
                angle = col in (THETA, ALPHA, BETA)
                self.units.append("rad" if angle else "mm")
        self.scales = np.array(
            [_ANGLE_SCALE if u == "rad" else _LENGTH_SCALE for u in self.units]
        )
        N = model.n_joints
        self._partials = np.zeros((N, 5, len(self.entries)))
        for k, (j, col) in enumerate(self.entries):
            self._partials[j, col, k] = 1.0

    @property
    def prefix(self) -> str:
        return "geometric"

    def table_delta(self, p: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Deltas to the (N, 5) table and their partials (N, 5, n_params)."""
        return self._partials @ p, self._partials


class Base(Effect):
    """Pose of the robot base in the measurement (tracker) frame: position x, y, z (mm) and
    orientation as a rotation vector rx, ry, rz (rad). Absolute values, estimated at the
    start by a best-fit rigid transform of nominal points onto the measured ones."""

    family = "base"
    stage = "base"
    summary = "pose of the robot base in the measurement frame"

    def __init__(self, model: RobotModel, joint: int | None = None,
                 order: int | None = None) -> None:
        super().__init__(model, joint, order)
        self.param_names = ["x", "y", "z", "rx", "ry", "rz"]
        self.units = ["mm"] * 3 + ["rad"] * 3
        self.scales = np.array([1.0, 1.0, 1.0, 1e-3, 1e-3, 1e-3])

    def initial(self, data: Dataset, nominal: Any, state: Any) -> np.ndarray:
        R, t = fit_rigid(nominal.base_p_tcp, data.tracker_p_smr)
        return np.concatenate([t, matrix_to_rotvec(R)])

    def transform(self, p: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """tracker_T_base as (R (3, 3), t (3,))."""
        return rotvec_to_matrix(p[3:]), p[:3]

    def apply(self, p: np.ndarray, P: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Map base-frame points (n, 3) to the tracker frame.

        Returns the points, the rotation (to carry other Jacobian columns along) and
        this effect's own columns, shape (n, 3, 6).
        """
        R, t = self.transform(p)
        out = P @ R.T + t
        n = P.shape[0]
        J = np.zeros((n, 3, 6))
        J[:, 0, 0] = J[:, 1, 1] = J[:, 2, 2] = 1.0
        # d(R(r) v)/dr_k = -R [v]x J_r e_k = (R J_r e_k) x (R v)
        W = R @ right_jacobian(p[3:])
        Rv = out - t
        for k in range(3):
            w = W[:, k]
            J[:, 0, 3 + k] = w[1] * Rv[:, 2] - w[2] * Rv[:, 1]
            J[:, 1, 3 + k] = w[2] * Rv[:, 0] - w[0] * Rv[:, 2]
            J[:, 2, 3 + k] = w[0] * Rv[:, 1] - w[1] * Rv[:, 0]
        return out, R, J


class Tool(Effect):
    """Target (SMR) centre in the flange frame, x, y, z (mm). Absolute values, starting from
    the model's nominal tool."""

    family = "tool"
    stage = "tool"
    summary = "target (SMR) position in the flange frame"

    def __init__(self, model: RobotModel, joint: int | None = None,
                 order: int | None = None) -> None:
        super().__init__(model, joint, order)
        self.param_names = ["x", "y", "z"]
        self.units = ["mm"] * 3
        self.scales = np.ones(3)

    def initial(self, data: Dataset, nominal: Any, state: Any) -> np.ndarray:
        return self.model.tool_mm().copy()

    def tool_point(self, p: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        return p, np.eye(3)

    def with_parameter_names(self, local: list[str]) -> Tool:
        """This tool as params.json names its parameters: one point per SMR nest
        (``<tool_id>.x``...) makes a :class:`NestedTool` of those nests, in their order."""
        nests = list(dict.fromkeys(n.rsplit(".", 1)[0] for n in local if "." in n))
        return NestedTool(self.model, nests) if nests else self


class NestedTool(Tool):
    """Several targets on the tool (SMR nests, the ``tool_id`` of each row), each a point of
    its own in the flange frame: ``<tool_id>.x, .y, .z`` (mm) per nest, in the order given.
    The first nest is the tool where one point is asked for (exports, perturbations
    without data). Rows without a ``tool_id`` measured the first nest."""

    def __init__(self, model: RobotModel, nests: list[str]) -> None:
        super().__init__(model)
        self.nests = [str(k) for k in nests]
        if not self.nests or len(set(self.nests)) != len(self.nests):
            raise EffectError(f"tool nests must be distinct and at least one: {self.nests}")
        self.param_names = [f"{k}.{c}" for k in self.nests for c in "xyz"]
        self.units = ["mm"] * self.n_params
        self.scales = np.ones(self.n_params)

    def initial(self, data: Dataset, nominal: Any, state: Any) -> np.ndarray:
        return np.tile(self.model.tool_mm(), len(self.nests))

    def bind(self, data: Dataset, nominal: Any) -> np.ndarray:
        """The nest of each row, (n,) index into :attr:`nests`."""
        if data.tool_id is None:
            return np.zeros(data.n, int)
        unknown = sorted(set(data.tool_id) - set(self.nests))
        if unknown:
            raise EffectError(f"{data.source}: tool_id {', '.join(unknown)} not among the "
                              f"tool's nests ({', '.join(self.nests)})")
        where = {k: i for i, k in enumerate(self.nests)}
        return np.array([where[t] for t in data.tool_id], int)

    def tool_point(self, p: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        partials = np.zeros((3, self.n_params))
        partials[:, :3] = np.eye(3)
        return p[:3], partials

    def tool_points(self, p: np.ndarray, data: Dataset, nest: np.ndarray
                    ) -> tuple[np.ndarray, np.ndarray]:
        """Each row's nest centre in the flange frame (n, 3), and the partials (n, 3, k)."""
        partials = np.zeros((len(nest), 3, self.n_params))
        for c in range(3):
            partials[np.arange(len(nest)), c, 3 * nest + c] = 1.0
        return p.reshape(-1, 3)[nest], partials


BUILTIN: dict[str, type[Effect]] = {
    "geometric": Geometric,
    "base": Base,
    "tool": Tool,
}
