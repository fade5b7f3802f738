"""Drift checks inserted into a plan, their curve, the warm-up's plan and its end, and the
warm gate (issue 26): plain data, no devices."""

from __future__ import annotations

import types

import numpy as np
import pytest

from calibration import load_model
from cellcal.flags.choices import THERMAL_STARTS
from daq.drift_checks import DRIFT_SET, DriftCheck, drift_curve, with_drift_checks
from daq.plans import Plan, Target
from daq.routines import make_plan
from daq.routines.warmup import enough
from daq.store import RunSummary, WarmupSummary
from daq.warm_gate import NotWarm, require_warm
from sim_drivers.thermal import STARTS

UR = load_model("ur10e")


def _plan(n=10, spares=2):
    targets = [Target(i, "joints", q=np.full(6, 0.1 * i), label=f"p{i}") for i in range(n)]
    targets += [Target(n + k, "joints", q=np.full(6, -0.1 * k), info={"spare": True})
                for k in range(spares)]
    return Plan("poses", {"count": n}, tuple(targets), model="ur10e")


def test_drift_checks_every_n_points_first_and_last_spares_kept_last():
    plan = with_drift_checks(_plan(), DriftCheck(4))
    sets = [t.set for t in plan.targets]
    assert [i for i, s in enumerate(sets) if s == DRIFT_SET] == [0, 5, 10, 13]
    assert [t.index for t in plan.targets] == list(range(len(plan)))
    assert all(t.spare for t in plan.targets[-2:]) and plan.n_planned == 14
    assert plan.targets[5].q == plan.targets[1].q  # the plan's first posture
    assert plan.params["drift_check"]["every_points"] == 4


def test_drift_checks_in_minutes_and_several_references():
    plan = with_drift_checks(_plan(12, 0), DriftCheck.parse("1min", references=2),
                             seconds_per_point=20.0)  # every 3 points
    drift = [t for t in plan.targets if t.set == DRIFT_SET]
    assert len(drift) == 2 * 5 and {t.info["of"] for t in drift} == {"p0", "p11"}
    with pytest.raises(ValueError, match="estimated time"):
        with_drift_checks(_plan(), DriftCheck.parse("5min"))


@pytest.mark.parametrize("text", ["0", "-2", "x", "2.5", "0min"])
def test_bad_drift_checks_are_refused(text):
    with pytest.raises(ValueError):
        DriftCheck.parse(text)


def _samples(t, xyz, sets, temps=None, refs=None):
    n = len(t)
    refs = refs or [1] * n
    return types.SimpleNamespace(
        set_name=sets, t_s=np.asarray(t, float), tracker_p_smr=np.asarray(xyz, float),
        std_mm=np.full((n, 3), 0.01), joint_temp=temps,
        target=[{"info": {"reference": r, "of": f"ref{r}"}} for r in refs])


def test_the_drift_curve_of_each_reference_flagged_above_the_bound():
    t = np.arange(6) * 60.0
    xyz = np.c_[np.array([0, 0.01, 0.03, 0.05, 0.06, 0.065]), np.zeros(6), np.zeros(6)]
    temps = np.linspace(20, 25, 6)[:, None] * np.ones(6)
    s = _samples(t, xyz, [DRIFT_SET] * 6, temps)
    (c,) = drift_curve(s)
    assert c.bound_mm == pytest.approx(0.04)  # 4 sigma
    np.testing.assert_allclose(c.drift_mm, xyz[:, 0])
    assert c.flagged.tolist() == [False] * 3 + [True] * 3 and c.to_json()["flagged"]
    assert c.joint_temp_c[-1] == pytest.approx(25.0)
    assert drift_curve(_samples(t, xyz, ["calib"] * 6)) == []


def test_warmup_plan_and_its_end():
    plan = make_plan("warmup", UR, count=3, cycles=4, window_min=2.0, max_min=6.0)
    assert len(plan) == 4 * 4 + 1 and plan.targets[0].set == DRIFT_SET
    assert sum(t.set == DRIFT_SET for t in plan.targets) == 5
    t = np.arange(5) * 60.0
    drifting = _samples(t, np.c_[t * 1e-3, 0 * t, 0 * t], [DRIFT_SET] * 5)
    assert enough(plan, drifting, None) is None  # 0.12 mm per 2 min, still going
    still = _samples(t, np.c_[t * 1e-6, 0 * t, 0 * t], [DRIFT_SET] * 5)
    assert enough(plan, still, None).startswith("settled")
    t = np.arange(8) * 60.0
    bound = _samples(t, np.c_[t * 1e-3, 0 * t, 0 * t], [DRIFT_SET] * 8)
    assert enough(plan, bound, None).startswith("not settled after the time bound")


class _Store:
    address = "cell.db"

    def __init__(self, run):
        self._run = run

    def latest_run(self, routine, robot_id=None):
        from daq.store import StoreError

        if self._run is None:
            raise StoreError("none")
        return self._run


class _Robot:
    def __init__(self, temps):
        self.temps = temps

    def joint_temperatures(self, timeout=1.0):
        return tuple(self.temps)


def test_the_warm_gate():
    warm = RunSummary(warmup=WarmupSummary(settled=True, joint_temp_c=[30.0] * 6))
    run = types.SimpleNamespace(id=7, stopped=1000.0, summary=warm)
    robot = _Robot([29.5] * 6)
    require_warm(_Store(run), robot, "R1", 10.0, now=1000.0 + 300.0)  # 5 min, warm
    with pytest.raises(NotWarm, match="ended 20.0 min ago"):
        require_warm(_Store(run), robot, "R1", 10.0, now=1000.0 + 1200.0)
    with pytest.raises(NotWarm, match="joint 3 .* cooled by 4.0 K"):
        require_warm(_Store(run), _Robot([30, 30, 26, 30, 30, 30]), "R1", 10.0, now=1001.0)
    with pytest.raises(NotWarm, match="no completed warm-up of robot R1"):
        require_warm(_Store(None), robot, "R1", 10.0)
    assert NotWarm.exit_code == 2
    # a warm-up that ran out of time (the robot still drifted) is no warm-up
    unsettled = RunSummary(warmup=WarmupSummary(settled=False, reason="not settled after "
                                                "the time bound (60 min)"))
    late = types.SimpleNamespace(id=8, stopped=1000.0, summary=unsettled)
    with pytest.raises(NotWarm, match="run 8.* did not settle: not settled after the time"):
        require_warm(_Store(late), robot, "R1", 10.0, now=1001.0)


def test_an_unsettled_warm_up_does_not_exit_as_done():
    from presentation.run_outcome import outcome_exit_code

    def out(settled):
        return {"status": "completed", "summary": {"warmup": {"settled": settled}}}

    assert outcome_exit_code(out(True)) == 0 and outcome_exit_code(out(False)) == 1
    assert outcome_exit_code({"status": "completed", "summary": {}}) == 0


def test_the_parsers_thermal_starts_are_the_simulators():
    assert THERMAL_STARTS == STARTS
