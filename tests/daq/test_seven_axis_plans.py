"""Capture plans for the 7-axis panda: every routine's targets pass the dry run, which
checks all seven joint limits (joint 4 works in -176..-4 deg, joint 6 in -1..215 deg)."""

import numpy as np
import pytest

from calibration import load_model
from calibration.model.kinematics import tool_points
from daq.check import check_plan
from daq.routines import make_plan

READY = [0.0, -45.0, 0.0, -135.0, 0.0, 90.0, 45.0]  # a usual start posture of the panda


def _within_limits(model, plan):
    q = np.degrees(plan.joints())
    lim = np.array([[j.min, j.max] for j in model.joints])
    assert q.shape[1] == 7
    assert (q >= lim[:, 0] - 1e-9).all() and (q <= lim[:, 1] + 1e-9).all()


@pytest.mark.parametrize("routine, params", [
    ("poses", {"count": 60, "seed": 3}),
    ("poses", {"count": 20, "seed": 3, "method": "optimal", "pool": 200}),
    ("steps", {"start_deg": READY, "count": 5}),
    ("frame", {"start_deg": READY}),
    ("iso9283", {"start_deg": READY, "cycles": 3}),
])
def test_panda_plans_pass_the_dry_run(routine, params):
    m = load_model("panda")
    plan = make_plan(routine, m, **params)
    result = check_plan(plan, m)
    assert result.ok, result.report()
    _within_limits(m, plan)


def test_panda_zero20_postures_stay_within_the_limits():
    m = load_model("panda")
    target = tool_points(m, np.radians([READY]))[0]
    plan = make_plan("zero20", m, target_xyz=target, seed_deg=READY)
    assert len(plan) == 20
    _within_limits(m, plan)
    assert check_plan(plan, m, floor_z_mm=None).ok


def test_a_move_outside_joint_4s_range_is_refused():
    from daq.plans import Plan

    m = load_model("panda")
    d = make_plan("poses", m, count=5, seed=1).to_dict()
    d["targets"][2]["q"][3] = 0.0  # joint 4 must stay in -176..-4 deg
    bad = check_plan(Plan.from_dict(d), m)
    assert not bad.ok and bad.bad_indices == [2]
    assert "joint 4" in bad.report() or "q4" in bad.report()


def test_zero_point_refuses_a_prismatic_joint(tmp_path):
    from tests.calibration.test_urdf_model import track_model

    _, m = track_model(tmp_path)
    with pytest.raises(ValueError, match="prismatic joint"):
        make_plan("zero20", m, target_xyz=[500.0, 0.0, 500.0])
