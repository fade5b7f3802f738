"""Compensated motion on the simulated cell, over a real socket: a UR10e with hidden
compliance and a gear harmonic is calibrated; a program of taught waypoints (joint targets
and TCP points) runs uncompensated and through :class:`CompensatedRobot` on the served
Modbus and line-protocol robots and over RTDE (the real ur-rtde receive client, the moves
through FakeRTDEControl on the same cell), and the simulated tracker measures where the
tool went. The compensated error must be within 1.3x the calibration's validation RMS (the
issue's bar) while the uncompensated program misses by the uncalibrated error; a
geometric-only calibration (what calibration.conf can carry) is measured beside it."""

import numpy as np
import pytest

from calibration import ErrorModel, identify
from calibration.cell.visibility import solve_facing
from calibration.fit.simulate import random_joints, simulate
from calibration.model.transforms import make_T
from daq.compensated_robot import CompensatedRobot
from daq.motion_guard import MotionLimits, MotionRefused
from sim_drivers.model_truth import ModelTruth

from .capture_helpers import connected_tracker, served_cell, stack_robot

HIDDEN = "compliance:2,compliance:3,harmonic:1"
SEED = 6


def _truth(seed, hidden):
    return ModelTruth.from_spec("ur10e", HIDDEN, SEED)


def _waypoints(truth, n=10):
    """Joints of taught waypoints whose SMR faces the tracker, in front of the robot."""
    rng = np.random.default_rng(1)
    p = np.column_stack([rng.uniform(600, 900, n), rng.uniform(-300, 300, n),
                         rng.uniform(200, 700, n)])
    seed = np.radians([0, -100, 100, -90, -90, 0])
    q, ok = solve_facing(truth.model, p, truth.tracker_in_base - p, np.zeros(n),
                         np.tile(seed, (n, 1)), (0.0, 0.0, 1.0))
    return q[ok]


def _base(em, x):
    i = em.labels.index("base")
    return make_T(*em.effects[i].transform(x[em.slices[i]]))


def _calibrate(truth, spec):
    rng = np.random.default_rng(SEED)
    q = random_joints(truth.model, 400, rng, max_abs_deg=170)
    data = simulate(truth.error_model, truth.x_true, q, 0.015, rng,
                    is_valid=np.arange(400) >= 300, temp_c=np.full(400, 20.0))
    em = ErrorModel(truth.model, spec)
    return em, identify(em, data)


def _run(robot, tracker, moves, B):
    """Run ``moves`` (callables); the measured SMR in the robot base frame of ``B``."""
    out = []
    for move in moves:
        move()
        p = tracker.measure(0.1, 10.0).xyz
        out.append(np.linalg.solve(B, np.append(p, 1.0))[:3])
    return np.array(out)


def _rms(v):
    return float(np.sqrt(np.mean(np.sum(np.square(v), axis=1))))


@pytest.mark.parametrize("protocol", ["modbus", "line", "rtde"])
def test_compensated_waypoints_on_the_served_cell(protocol):
    with served_cell(_truth, seed=SEED) as stack:
        truth = stack.cell.truth
        q = _waypoints(truth)
        assert len(q) >= 8
        model = truth.model
        from calibration.model.kinematics import tool_points

        target = tool_points(model, q)  # what the program means: the nominal TCP
        full, fit = _calibrate(truth, "geometric,base,tool," + HIDDEN)
        geo, fit_geo = _calibrate(truth, "geometric,base,tool")
        valid = fit.valid["rms_mm"]
        tracker_url = next(u for u in stack.urls if u.startswith("tracker"))
        limits = MotionLimits(floor_z_mm=None)
        with stack_robot(stack, protocol) as robot, connected_tracker(tracker_url) as tracker:
            B = _base(full, fit.values)
            cal = CompensatedRobot(robot, full, fit.values, limits=limits)
            plain = cal.send  # the joints as taught, through the same checks
            before = _run(robot, tracker, [lambda k=k: plain(q[k]) for k in range(len(q))], B)
            after = _run(robot, tracker, [lambda k=k: cal.move_joints(q[k])
                                          for k in range(len(q))], B)
            points = _run(robot, tracker, [lambda k=k: cal.move_point(target[k])
                                           for k in range(3)], B)
            g = CompensatedRobot(robot, geo, fit_geo.values, limits=limits)
            geometric = _run(robot, tracker, [lambda k=k: g.move_joints(q[k])
                                              for k in range(len(q))], _base(geo, fit_geo.values))
            # a compensated move passes the checks a capture's moves pass
            high = CompensatedRobot(robot, full, fit.values,
                                    limits=MotionLimits(floor_z_mm=5000.0))
            with pytest.raises(MotionRefused, match="below the floor"):
                high.move_joints(q[0])
        e_before, e_after = _rms(before - target), _rms(after - target)
        e_geo = _rms(geometric - target)
        print(f"waypoints {len(q)}: uncompensated {e_before:.3f} mm, compensated "
              f"{e_after:.3f} mm (validation RMS {valid:.3f} mm), geometric only "
              f"{e_geo:.3f} mm")
        assert e_before > 10 * valid
        assert e_after <= 1.3 * valid, (e_after, valid)
        assert e_geo > 2 * e_after
        assert _rms(points - target[:3]) <= 1.3 * valid * 1.5
