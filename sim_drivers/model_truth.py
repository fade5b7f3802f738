"""A true robot built from the calibration core: a nominal model plus hidden errors.

:class:`ModelTruth` implements :class:`~sim_drivers.truth.TrueRobot` for the simulated
cell: the "real" robot is an :class:`~calibration.ErrorModel` (geometric errors, the base
2-3 m from the tracker, an SMR offset, and any hidden physical effects) at a hidden
parameter vector; the controller only knows the nominal model.
"""

from __future__ import annotations

import numpy as np

from calibration import Dataset, ErrorModel, RobotModel, load_model
from calibration.effects import DEFAULT_EFFECTS, display_unit
from calibration.inverse import ChainFK, solve_ik
from calibration.kinematics import tool_points
from calibration.simulate import realistic_truth
from calibration.transforms import make_T, rotvec_to_matrix

from .truth import PoseContext

#: where the SMR sits on the flange in the simulated cell (mm): on a 60 mm holder
DEFAULT_TOOL_MM = (0.0, 0.0, 60.0)


class ModelTruth:
    """The robot as it really is, for the simulated cell.

    Parameters
    ----------
    model : the nominal model the controller knows (its ``tool`` is the controller's TCP)
    error_model : the true robot's error model (must contain ``base``)
    x_true : its hidden parameters (internal units)
    """

    def __init__(self, model: RobotModel, error_model: ErrorModel, x_true: np.ndarray):
        self.model = model
        self.error_model = error_model
        self.x_true = np.asarray(x_true, float)
        self.n_joints = model.n_joints
        self.limits = model.limits_rad()
        #: the robot model the simulated controller reports it moves
        self.name = model.name
        self._fk = ChainFK(model.convention, model.dh_table(), model.tool_mm())

    @classmethod
    def from_spec(
        cls,
        model: str | RobotModel = "ur10e",
        hidden: str | None = None,
        seed: int = 0,
        tool_mm=DEFAULT_TOOL_MM,
    ) -> ModelTruth:
        """Realistic hidden errors (seeded) plus the ``hidden`` effects (e.g. "compliance:3")."""
        nominal = load_model(model) if isinstance(model, str) else model
        nominal = nominal.with_changes(tool=tuple(float(v) for v in tool_mm))
        spec = DEFAULT_EFFECTS + ("," + hidden if hidden else "")
        em = ErrorModel(nominal, spec)
        # the tracker stands 1.2-2.2 m beyond the robot's reach (it cannot measure closer
        # than ~0.8 m, and a cell keeps it out of the robot's way)
        reach = sum(abs(j.a) + abs(j.d) for j in nominal.joints) + float(np.abs(tool_mm).sum())
        x = realistic_truth(em, np.random.default_rng(seed),
                            base_distance_mm=(reach + 1200.0, reach + 2200.0))
        return cls(nominal, em, x)

    # ---- TrueRobot -------------------------------------------------------------
    def true_point(self, q: np.ndarray, ctx: PoseContext) -> np.ndarray:
        q = np.asarray(q, float).reshape(1, -1)
        dirs = None if ctx.direction is None else np.asarray(ctx.direction, int).reshape(1, -1)
        data = Dataset(
            q=q, tracker_p_smr=np.zeros((1, 3)), dirs=dirs, temp_c=np.array([ctx.temp_c]),
            t_s=np.array([ctx.t_s]),
            payload_kg=None if ctx.payload_kg is None else np.array([ctx.payload_kg]),
        )
        return self.error_model.evaluate(self.x_true, self.error_model.bind(data), False)[0][0]

    def nominal_tcp(self, q: np.ndarray) -> np.ndarray:
        return tool_points(self.model, np.asarray(q, float).reshape(1, -1))[0]

    def nominal_ik(self, xyz: np.ndarray, q_seed: np.ndarray) -> np.ndarray:
        """Joints putting the nominal TCP at ``xyz`` from ``q_seed``; an arm of 6 joints or
        more keeps the flange orientation it has at ``q_seed``, as a controller's linear
        move does (docs/line-robot-protocol.md: "orientation kept")."""
        q_seed = np.asarray(q_seed, float)
        R = self._fk(q_seed[None])[1][0] if self.n_joints >= 6 else None
        res = solve_ik(self._fk, q_seed, np.asarray(xyz, float), R, limits=self.limits)
        if not res.success[0]:
            raise ValueError(f"point {np.round(xyz, 3).tolist()} mm is out of reach "
                             f"({res.reason})")
        return res.q[0]

    # ---- what tests may compare with ---------------------------------------------
    @property
    def tracker_T_base(self) -> np.ndarray:
        """The hidden pose of the robot base in the tracker frame, 4x4 (mm)."""
        k = self.error_model.index("base.x")
        p = self.x_true[k : k + 6]
        return make_T(rotvec_to_matrix(p[3:]), p[:3])

    def hidden_parameters(self) -> list[dict]:
        """The hidden parameters in display units (deg for angles)."""
        rows = []
        for k, name in enumerate(self.error_model.names):
            unit, f = display_unit(self.error_model.units[k])
            rows.append({"name": name, "value": float(self.x_true[k] * f), "unit": unit})
        return rows


def model_truth_factory(seed: int, hidden: str | None) -> ModelTruth:
    """``truth_factory`` for the simulated cell: a UR10e with hidden errors (and effects)."""
    return ModelTruth.from_spec("ur10e", hidden or None, seed)
