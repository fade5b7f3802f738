"""Program targets against a known truth: a UR10e with hidden non-geometric effects
(compliance, harmonics, thermal growth) is calibrated, a program's joint and pose targets
(a TCP with an offset and a tilt) are compensated with the fit, and the TRUE robot at the
compensated joints must reach the nominal targets, position and orientation, far better
than uncompensated and than a geometric-only calibration (calibration.conf's reach)."""

import numpy as np
import pytest

from calibration import Dataset, ErrorModel, identify, load_model
from calibration.compensation.compensation import CalibratedFK
from calibration.compensation.pose_compensation import (
    NominalTcpFK,
    as_poses,
    compensate_joint_targets,
    compensate_pose_targets,
    compensate_targets,
    neighbour_seeds,
    pose_difference,
)
from calibration.effects import EffectError
from calibration.fit.identifiability import analyse
from calibration.fit.simulate import random_joints, realistic_truth, simulate
from calibration.model.inverse import solve_ik
from calibration.model.transforms import make_T, rotvec_to_matrix

HIDDEN = "geometric,base,tool,compliance:2,compliance:3,harmonic:1,harmonic:2,thermal"
TCP = make_T(rotvec_to_matrix([0.1, 0.2, 0.3]), [10.0, -20.0, 150.0])
TEMP = 28.0


def _base(em, x):
    i = em.labels.index("base")
    return make_T(*em.effects[i].transform(x[em.slices[i]]))


def _rms(v):
    return float(np.sqrt(np.mean(np.square(v))))


@pytest.fixture(scope="module")
def cell():
    """The truth (only what the poses can determine is perturbed, so the flange the fit
    sees is the true one), the full fit, and a geometric-only fit of the same data."""
    m = load_model("ur10e").with_changes(tool=(40.0, 60.0, 80.0))
    em = ErrorModel(m, HIDDEN)
    rng = np.random.default_rng(3)
    n = 400
    q = random_joints(m, n, rng, max_abs_deg=170)
    temp = rng.uniform(18.0, 32.0, n)
    b = em.bind(Dataset(q=q, tracker_p_smr=np.zeros((n, 3)), temp_c=temp))
    x0 = em.initial(b)
    x0[em.index("base.x"):em.index("base.x") + 6] = [2500, 0, 0, 0.3, -0.2, 0.1]
    only = analyse(em.evaluate(x0, b)[1].reshape(-1, em.n_params), em.names, em.scales,
                   [em.effect_of(k).family for k in range(em.n_params)]).free
    x_true = realistic_truth(em, rng, only=only)
    data = simulate(em, x_true, q, 0.015, rng, is_valid=np.arange(n) >= 300, temp_c=temp)
    geo = ErrorModel(m, "geometric,base,tool")
    return m, em, x_true, identify(em, data), geo, identify(geo, data), rng


def _true_pose(em, x_true, q, temp=TEMP):
    """The true TCP pose (tracker frame) at joints q."""
    k = len(q)
    fk = CalibratedFK(em, x_true, {"temp_c": np.full(k, temp)}, TCP[:3, 3])
    r = fk.chain(q)
    return _base(em, x_true) @ as_poses(r.base_p_tcp, r.base_R_flange @ TCP[:3, :3])


def test_joint_targets_reach_the_nominal_poses_on_the_true_robot(cell):
    m, em, x_true, fit, geo, fit_geo, rng = cell
    q = random_joints(m, 150, rng, max_abs_deg=150)
    cols = {"temp_c": np.full(len(q), TEMP)}
    c = compensate_joint_targets(em, fit.values, q, TCP, columns=cols)
    assert c.success.mean() > 0.97, c.reason
    ok = c.success
    desired = _base(em, fit.values) @ c.target  # the targets where the tracker sees them
    before = pose_difference(_true_pose(em, x_true, q), desired)
    after = pose_difference(_true_pose(em, x_true, c.q), desired)
    g = compensate_joint_targets(geo, fit_geo.values, q, TCP)
    geometric = pose_difference(_true_pose(em, x_true, g.q), _base(geo, fit_geo.values) @ g.target)
    mm = [_rms(d[0][ok]) for d in (before, after, geometric)]
    deg = [_rms(d[1][ok]) for d in (before, after, geometric)]
    assert mm[0] > 1.0 and deg[0] > 0.05  # the uncalibrated robot misses
    assert mm[1] < 0.02 * mm[0] and deg[1] < 0.1 * deg[0], (mm, deg)
    assert mm[1] < 0.1 * mm[2] and deg[1] < 0.3 * deg[2], (mm, deg)  # geometric only
    # the calibration predicts the uncompensated miss; the correction is that size
    assert abs(_rms(c.predicted_mm[ok]) - mm[0]) < 0.05 * mm[0]
    assert c.residual_mm[ok].max() < 1e-5 and c.residual_deg[ok].max() < 1e-4
    np.testing.assert_allclose(c.q_nominal, q)


def test_pose_targets_pick_the_configuration_of_their_seed(cell):
    m, em, x_true, fit, *_ = cell
    rng = np.random.default_rng(11)
    q = random_joints(m, 80, rng, max_abs_deg=150)
    T = as_poses(*(lambda r: (r.base_p_tcp, r.base_R_flange @ TCP[:3, :3]))(
        NominalTcpFK(m, TCP[:3, 3]).chain(q)))
    cols = {"temp_c": np.full(len(q), TEMP)}
    c = compensate_pose_targets(em, fit.values, T, q + 0.05, TCP, columns=cols)
    ok = c.success
    assert ok.mean() > 0.97, c.reason
    # the seed's configuration (a pose beside the elbow singularity may flip)
    assert np.all(np.abs(c.q_nominal - q) < 1e-6, axis=1)[ok].mean() > 0.97
    after = pose_difference(_true_pose(em, x_true, c.q), _base(em, fit.values) @ T)
    assert _rms(after[0][ok]) < 0.02 and _rms(after[1][ok]) < 0.01
    # the nominal controller's own IK of the commanded pose gives back the compensated q
    fk = NominalTcpFK(m, TCP[:3, 3])
    back = solve_ik(fk, c.q_nominal, c.cmd[:, :3, 3], c.cmd[:, :3, :3] @ TCP[:3, :3].T,
                    success_rad=1e-7)
    good = ok & back.success
    assert good.mean() > 0.95
    np.testing.assert_allclose(back.q[good], c.q[good], atol=1e-6)
    assert np.all(np.abs(c.correction_mm[ok] - c.predicted_mm[ok]) < 0.1 * c.predicted_mm[ok]
                  + 0.01)


def test_mixed_targets_in_program_order_and_the_thermal_state(cell):
    m, em, x_true, fit, *_ = cell
    rng = np.random.default_rng(5)
    # a program's path: the pose targets lie between joint targets
    q = np.radians([10, -80, 90, -100, -90, 20]) + np.cumsum(rng.normal(0, 0.1, (6, 6)), 0)
    T = np.broadcast_to(np.eye(4), (6, 4, 4)).copy()
    r = NominalTcpFK(m, TCP[:3, 3]).chain(q)
    T[:] = as_poses(r.base_p_tcp, r.base_R_flange @ TCP[:3, :3])
    is_pose = np.array([False, True, True, False, True, False])
    seeds = neighbour_seeds(is_pose, q, np.zeros(6))
    mixed = compensate_targets(em, fit.values, seeds, pose=T, is_pose=is_pose,
                               flange_T_tcp=TCP, columns={"temp_c": np.full(6, TEMP)})
    assert mixed.success.all(), mixed.reason
    np.testing.assert_allclose(mixed.q_nominal, q, atol=1e-6)
    # the thermal state changes the answer as the true robot does
    warm = compensate_targets(em, fit.values, q, flange_T_tcp=TCP,
                              columns={"temp_c": np.full(6, 35.0)})
    miss_warm = pose_difference(_true_pose(em, x_true, warm.q, 35.0),
                                _base(em, fit.values) @ warm.target)[0]
    miss_cold = pose_difference(_true_pose(em, x_true, mixed.q, 35.0),
                                _base(em, fit.values) @ mixed.target)[0]
    assert miss_warm.max() < 0.02 < miss_cold.max()
    with pytest.raises(EffectError, match="temp_c"):
        compensate_targets(em, fit.values, q, flange_T_tcp=TCP)


def test_neighbour_seeds():
    joints = np.arange(12.0).reshape(6, 2)
    is_pose = np.array([True, False, True, True, False, True])
    seeds = neighbour_seeds(is_pose, joints, np.array([-1.0, -1.0]))
    np.testing.assert_array_equal(seeds[:, 0], [2, 2, 2, 2, 8, 8])  # after, own, before...
    alone = neighbour_seeds(np.ones(2, bool), joints[:2], np.array([-1.0, -2.0]))
    np.testing.assert_array_equal(alone, [[-1, -2], [-1, -2]])
