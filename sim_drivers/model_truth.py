"""A true robot built from the calibration core: a nominal model plus hidden errors.

:class:`ModelTruth` implements :class:`~sim_drivers.truth.TrueRobot` for the simulated
cell: the "real" robot is an :class:`~calibration.ErrorModel` (geometric errors, the base
2-3 m from the tracker, an SMR offset, and any hidden physical effects) at a hidden
parameter vector; the controller only knows the nominal model.

The tracker stands where the cell puts it (``tracker_at``, robot base frame; the base
pose's orientation in the tracker frame stays random), and the SMR opens along
``smr_axis`` on the flange (:meth:`ModelTruth.from_spec` tilts it by a hidden ~1 deg): the
simulated tracker's line of sight (:mod:`sim_drivers.beam`) uses both with the model's link
radii (:meth:`ModelTruth.beam_geometry`).
"""

from __future__ import annotations

import numpy as np

from calibration import Dataset, ErrorModel, RobotModel, load_model
from calibration.effects import DEFAULT_EFFECTS, display_unit
from calibration.fit.simulate import realistic_truth
from calibration.model.inverse import ChainFK, solve_ik
from calibration.model.kinematics import run_chain, tool_points
from calibration.model.transforms import make_T, rotvec_to_matrix

from .thermal import thermal_effects
from .truth import PoseContext

#: where the SMR sits on the flange in the simulated cell (mm): on a 60 mm holder
DEFAULT_TOOL_MM = (0.0, 0.0, 60.0)
#: where the simulated tracker stands by default (mm, robot base frame): 2.5 m from the base
#: along +x, the head 0.5 m above the base
DEFAULT_TRACKER_AT_MM = (2500.0, 0.0, 500.0)
#: the hidden tilt of the true SMR axis from the nominal one (deg, std per axis)
SMR_TILT_DEG = 1.0


class ModelTruth:
    """The robot as it really is, for the simulated cell.

    Parameters
    ----------
    model : the nominal model the controller knows (its ``tool`` is the controller's TCP)
    error_model : the true robot's error model (must contain ``base``)
    x_true : its hidden parameters (internal units)
    """

    def __init__(self, model: RobotModel, error_model: ErrorModel, x_true: np.ndarray, *,
                 tracker_at=None, smr_axis=(0.0, 0.0, 1.0)):
        self.model = model
        self.error_model = error_model
        self.x_true = np.asarray(x_true, float).copy()
        self.n_joints = model.n_joints
        self.limits = model.limits_rad()
        #: the robot model the simulated controller reports it moves
        self.name = model.name
        self.smr_axis = np.asarray(smr_axis, float) / np.linalg.norm(smr_axis)
        self._fk = ChainFK(model.convention, model.dh_table(), model.tool_mm())
        if tracker_at is not None:  # keep the base's orientation, move the tracker there
            k = self.error_model.index("base.x")
            R = rotvec_to_matrix(self.x_true[k + 3 : k + 6])
            self.x_true[k : k + 3] = -R @ np.asarray(tracker_at, float)

    @classmethod
    def from_spec(
        cls,
        model: str | RobotModel = "ur10e",
        hidden: str | None = None,
        seed: int = 0,
        tool_mm=DEFAULT_TOOL_MM,
        tracker_at=DEFAULT_TRACKER_AT_MM,
        smr_axis=(0.0, 0.0, 1.0),
    ) -> ModelTruth:
        """Realistic hidden errors (seeded) plus the ``hidden`` effects (e.g. "compliance:3"),
        the tracker at ``tracker_at`` (mm, base frame; None: 1.2-2.2 m beyond the reach in
        a random direction), the SMR along ``smr_axis`` tilted by a hidden ~1 deg."""
        nominal = load_model(model) if isinstance(model, str) else model
        nominal = nominal.with_changes(tool=tuple(float(v) for v in tool_mm))
        spec = DEFAULT_EFFECTS + ("," + hidden if hidden else "")
        em = ErrorModel(nominal, spec)
        # the tracker stands 1.2-2.2 m beyond the robot's reach (it cannot measure closer
        # than ~0.8 m, and a cell keeps it out of the robot's way)
        reach = sum(abs(j.a) + abs(j.d) for j in nominal.joints) + float(np.abs(tool_mm).sum())
        x = realistic_truth(em, np.random.default_rng(seed),
                            base_distance_mm=(reach + 1200.0, reach + 2200.0))
        tilt = np.random.default_rng([seed, 7]).normal(0.0, np.radians(SMR_TILT_DEG), 3)
        axis = rotvec_to_matrix(tilt) @ np.asarray(smr_axis, float)
        return cls(nominal, em, x, tracker_at=tracker_at, smr_axis=axis)

    def with_thermal(self, seed: int) -> ModelTruth:
        """The same robot, warming up: the hidden thermal effects
        (:func:`sim_drivers.thermal.thermal_effects`, those not hidden already) added at
        realistic sizes drawn from ``seed``; every other hidden parameter is kept. Its
        true points then need the cell's joint temperatures (a thermal model)."""
        have = set(self.error_model.labels)
        extra = [e for e in thermal_effects(self.n_joints) if e not in have]
        if not extra:
            return self
        more = ErrorModel(self.model, extra)
        em = ErrorModel(self.model, self.error_model.effects + more.effects)
        x_more = realistic_truth(more, np.random.default_rng([seed, 0x7E]))
        return ModelTruth(self.model, em, np.concatenate([self.x_true, x_more]),
                          smr_axis=self.smr_axis)

    # ---- TrueRobot -------------------------------------------------------------
    def true_point(self, q: np.ndarray, ctx: PoseContext) -> np.ndarray:
        data = _pose_data(q, ctx)
        return self.error_model.evaluate(self.x_true, self.error_model.bind(data), False)[0][0]

    def nominal_tcp(self, q: np.ndarray) -> np.ndarray:
        return tool_points(self.model, np.asarray(q, float).reshape(1, -1))[0]

    def true_flange_rotation(self, q: np.ndarray, ctx: PoseContext) -> np.ndarray:
        """The true flange orientation in the tracker frame, ``tracker_R_flange`` (3, 3), at
        the reported joints ``q`` (rad): the hidden chain (joint effects, geometry) and the
        hidden base rotation, as :meth:`true_point` moves the target. The measure-stage
        effects (the instrument's length scale) leave orientations alone."""
        c = self.error_model.perturb(self.x_true, self.error_model.bind(_pose_data(q, ctx)))
        r = run_chain(self.model.convention, c.table, c.q, c.tool, c.length_scale,
                      jacobian=False, prismatic=self.model.prismatic_mask())
        R = r.base_R_flange[0]
        return R if c.tracker_T_base is None else c.tracker_T_base[0] @ R

    def nominal_ik(self, xyz: np.ndarray, q_seed: np.ndarray) -> np.ndarray:
        """Joints putting the nominal TCP at ``xyz`` near ``q_seed``: as a controller's linear
        move, keeping the flange orientation of ``q_seed`` on an arm that can (6+ joints)."""
        seed = np.asarray(q_seed, float)
        R = self._fk(seed[None])[1][0] if self.n_joints >= 6 else None
        res = solve_ik(self._fk, seed, np.asarray(xyz, float), R, limits=self.limits,
                       max_iter=200, success_mm=1e-5, success_rad=1e-7)
        if not res.success[0]:
            raise ValueError(f"point {np.round(xyz, 3).tolist()} mm is out of reach "
                             f"({res.reason})")
        return res.q[0]

    # ---- what tests may compare with ---------------------------------------------
    def beam_geometry(self):
        """What the simulated tracker's line of sight needs: (nominal model with link radii
        and tool, ``tracker_T_base``, the true SMR axis in the flange frame)."""
        return self.model, self.tracker_T_base, self.smr_axis

    @property
    def tracker_in_base(self) -> np.ndarray:
        """The tracker head in the robot base frame (mm)."""
        T = self.tracker_T_base
        return -T[:3, :3].T @ T[:3, 3]

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


def _pose_data(q: np.ndarray, ctx: PoseContext) -> Dataset:
    """A one-row data set of the joints ``q`` (rad) in the context ``ctx``, to evaluate at."""
    dirs = None if ctx.direction is None else np.asarray(ctx.direction, int).reshape(1, -1)
    return Dataset(
        q=np.asarray(q, float).reshape(1, -1), tracker_p_smr=np.zeros((1, 3)), dirs=dirs,
        temp_c=np.array([ctx.temp_c]), t_s=np.array([ctx.t_s]),
        payload_kg=None if ctx.payload_kg is None else np.array([ctx.payload_kg]),
        joint_temp=None if ctx.joint_temp is None else np.reshape(ctx.joint_temp, (1, -1)),
    )


def model_truth_factory(seed: int, hidden: str | None) -> ModelTruth:
    """``truth_factory`` for the simulated cell: a UR10e with hidden errors (and effects)."""
    return ModelTruth.from_spec("ur10e", hidden or None, seed)
