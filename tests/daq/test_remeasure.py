"""The re-measure policy (daq.remeasure) on its own, the schema-6 upgrade from a schema-5
store, and the readings a capture did not accept through export, the reader and runs.

The policy is driven with readings made from a simulated truth (a UR10e with hidden
geometric errors, the tracker's noise) through a scripted point context: which readings
it accepts, which it rejects and why, where the robot is sent.
"""

from __future__ import annotations

import csv
import json
import shutil
import sqlite3

import numpy as np
import pytest

from calibration import Dataset, load_csv, load_model
from calibration.model.kinematics import tool_points
from cellcal.cli import main
from daq.motion_guard import MotionGuard
from daq.remeasure import RETRACT_TOOL_MM, Remeasure, RunningModel
from daq.routines import make_plan
from daq.run_context import ExecutorOptions, RunContext
from daq.store import Reading, RunStore, Sample
from daq.store.schema import SCHEMA_VERSION, THERMAL_FULL_POSE_COLUMNS, UPGRADES
from drivers.protocols import JointReading, Measurement
from sim_drivers.model_truth import ModelTruth

from .capture_helpers import DATA, ur10e_controller_model

SIGMA = 0.017  # the simulated tracker's per-axis noise at ~3 m, mm


@pytest.fixture(scope="module")
def cell():
    """A 90-point plan (calib, one validation pose every tenth), the truth, its points."""
    model = ur10e_controller_model()
    plan = make_plan("poses", model, count=90, seed=5, valid_fraction=0.1)
    truth = ModelTruth.from_spec("ur10e", None, 5)
    Q = np.array([t.q for t in plan.targets])
    P = truth.error_model.evaluate(truth.x_true, truth.error_model.bind(
        Dataset(q=Q, tracker_p_smr=np.zeros((len(Q), 3)))), False)[0]
    return model, plan, truth, P


def _sample(plan, P, i, offset=(0.0, 0.0, 0.0), rng=None, verdict=None) -> Sample:
    t = plan.targets[i]
    rng = rng or np.random.default_rng(i)
    return Sample(point_index=i, q=np.array(t.q), pose_id=t.label, set_name=t.set,
                  tracker_p_smr=P[i] + rng.normal(0, SIGMA, 3) + np.asarray(offset),
                  std_mm=np.full(3, SIGMA), n_averaged=10, t_s=1000.0 + i,
                  dirs=np.array([1, -1, 1, 0, -1, 1]),
                  verdict=verdict)


class ScriptedPoint:
    """A point context (the robot at ``q``) whose tracker returns the truth plus
    scripted offsets."""

    def __init__(self, truth, q, offsets):
        self.truth, self.offsets = truth, list(offsets)
        self.q = np.asarray(q, float)
        self.moves: list[tuple[str, np.ndarray]] = []
        self.rng = np.random.default_rng(0)

    def at(self, target):
        self.target = target
        return self

    def move_joints(self, q):
        self.q = np.asarray(q, float)
        self.moves.append(("joints", self.q))
        return self.read_joints()

    def move_entry(self):
        return None  # joint targets: no entry move

    def move_via(self):
        assert self.target.via is None, "no pre-positions here"
        return None

    def move_target(self):
        assert self.target.move == "joints", "no linear targets here"
        return self.move_joints(self.target.q)

    def read_joints(self):
        return JointReading(self.q.copy(), 1.0)

    def measure_at(self, jr):
        return self.read_joints(), self.measure()

    def measure(self):
        p = self.truth.error_model.evaluate(self.truth.x_true, self.truth.error_model.bind(
            Dataset(q=self.q[None], tracker_p_smr=np.zeros((1, 3)))), False)[0][0]
        xyz = p + self.rng.normal(0, SIGMA, 3) + np.asarray(self.offsets.pop(0), float)
        return Measurement(xyz, np.full(3, SIGMA), 10, 2000.0 + len(self.moves))


def _policy(model, plan, P, n_points=70, remeasure=2):
    running = RunningModel(model, plan)
    policy = Remeasure(running, plan, n=remeasure, retract_rad=0.01, limits=model.limits_rad())
    for i in range(n_points):
        policy.committed(policy.settle(plan.targets[i], _sample(plan, P, i), None))
    return policy


def test_warmup_is_twice_the_identifiable_parameters_and_then_a_model_judges(cell):
    model, plan, truth, P = cell
    policy = _policy(model, plan, P)
    running = policy.running
    assert running.n_identifiable == 25 and running.min_points == 50
    assert running.fit is not None and running.refits[0][0] == 50
    verdicts = [s.verdict for _, s in sorted(running.samples.items())]
    n_warm = verdicts.count("warmup")
    assert n_warm > 50 and set(verdicts[n_warm:]) == {"ok"}  # validation rows do not count
    assert running.judge(_sample(plan, P, 75)).suspect is False
    bad = running.judge(_sample(plan, P, 75, offset=(0.6, 0.0, 0.0)))
    assert bad.suspect and 0.5 < bad.residual_mm < 0.7 and bad.threshold_mm < 0.15


def test_a_suspect_reading_re_measured_after_a_retract_against_its_approach(cell):
    model, plan, truth, P = cell
    policy = _policy(model, plan, P)
    t = plan.targets[75]
    ctx = ScriptedPoint(truth, t.q, [(0.0, 0.0, 0.0)])
    settled = policy.settle(t, _sample(plan, P, 75, offset=(0.0, 2.0, 0.0)), ctx)
    s = settled.sample
    assert s.verdict == "remeasured" and s.remeasures == 1 and s.model_residual_mm < 0.1
    (rej,) = settled.rejected
    assert 1.9 < rej.sample.model_residual_mm < 2.1
    assert "a re-measurement agrees with the model" in rej.reason
    # away against the approach (dirs +1,-1,+1,0,-1,+1), then back to the target
    (_, away), (_, back) = ctx.moves
    np.testing.assert_allclose(away - np.array(t.q), -0.01 * np.array([1, -1, 1, 0, -1, 1]))
    np.testing.assert_array_equal(back, t.q)
    np.testing.assert_array_equal(s.dirs, [1, -1, 1, 0, -1, 1])  # approached as before
    assert not settled.revisited


def test_re_measurements_that_agree_with_each_other_and_not_the_model_are_accepted(cell):
    model, plan, truth, P = cell
    policy = _policy(model, plan, P)
    # the point really is 1.5 mm off
    ctx = ScriptedPoint(truth, plan.targets[75].q, [(0.0, 0.0, 1.5)])
    settled = policy.settle(plan.targets[75], _sample(plan, P, 75, offset=(0, 0, 1.5)), ctx)
    assert settled.sample.verdict == "model" and settled.sample.remeasures == 1
    (rej,) = settled.rejected
    assert "the model, not the reading, is off" in rej.reason


def test_readings_that_agree_with_nothing_keep_the_closest_to_the_model(cell):
    model, plan, truth, P = cell
    policy = _policy(model, plan, P)
    ctx = ScriptedPoint(truth, plan.targets[75].q, [(3.0, 0, 0), (0, -4.0, 0)])
    settled = policy.settle(plan.targets[75], _sample(plan, P, 75, offset=(0, 0, 1.0)), ctx)
    s = settled.sample
    assert s.verdict == "unresolved" and s.remeasures == 2
    assert 0.9 < s.model_residual_mm < 1.1  # the first reading, 1 mm off, was the closest
    assert len(settled.rejected) == 2 and len(ctx.moves) == 4
    assert all("no two readings agree" in r.reason for r in settled.rejected)


def test_warmup_blunders_are_revisited_with_the_next_point(cell):
    model, plan, truth, P = cell
    running = RunningModel(model, plan)
    policy = Remeasure(running, plan, n=2, retract_rad=0.01, limits=model.limits_rad())
    valid = [i for i, t in enumerate(plan.targets[:50]) if t.set == "valid"]
    bad = {3: (0, 2.5, 0), valid[0]: (1.2, 0, 0)}  # a calibration and a validation row
    for i in range(70):
        if running.fit is not None:
            break
        s = _sample(plan, P, i, offset=bad.get(i, (0, 0, 0)))
        policy.committed(policy.settle(plan.targets[i], s, None))
    assert policy.pending == sorted(bad)
    nxt = plan.targets[i]
    ctx = ScriptedPoint(truth, nxt.q, [(0, 0, 0)] * 2)
    settled = policy.settle(nxt, _sample(plan, P, i), ctx)
    assert settled.sample.verdict == "ok"
    assert [new.point_index for new, _ in settled.revisited] == sorted(bad)
    for new, (old,) in settled.revisited:
        assert new.verdict == "remeasured" and new.remeasures == 1
        assert old.reason.startswith("warm-up reading, judged once the model was fitted")
        np.testing.assert_array_equal(new.q, plan.targets[new.point_index].q)
    policy.committed(settled)
    assert policy.pending == []


# ------------------------------------------------------------------- store
def _schema5_store(tmp_path):
    """The committed schema-2 store brought to schema 5 by the frozen upgrade functions."""
    db = tmp_path / "cell.db"
    shutil.copy(DATA / "schema_v2" / "cell.db", db)
    con = sqlite3.connect(db)
    with con:
        for v in (2, 3, 4):
            UPGRADES[v](con)
        con.execute("PRAGMA user_version=5")
    con.close()
    return db


def test_upgrade_from_schema_5_adds_the_readings_and_keeps_every_sample(tmp_path, capsys):
    db = _schema5_store(tmp_path)
    con = sqlite3.connect(db)
    before = con.execute("SELECT * FROM samples ORDER BY id").fetchall()
    con.close()
    assert main(["export", "4", "--db", str(db), "--out", str(tmp_path / "before.csv")]) == 0
    with RunStore(db) as st:
        assert st.version == SCHEMA_VERSION
        s = st.samples(4)
        assert s.verdict == [None] * len(s) and not s.remeasures.any()
        assert st.readings(4) == []
        assert st.remeasure_counts(4)["suspects"] == 0
    con = sqlite3.connect(db)
    after = con.execute("SELECT * FROM samples ORDER BY id").fetchall()
    cols = [c[1] for c in con.execute("PRAGMA table_info(samples)")]
    con.close()
    assert [r[:len(before[0])] for r in after] == before  # the old columns as they were
    assert cols[len(before[0]):] == ["verdict", "remeasures", "model_residual_mm",
                                     "model_threshold_mm",  # schema 6, then schema 9's
                                     *(c.split()[0] for c in THERMAL_FULL_POSE_COLUMNS)]
    assert main(["export", "4", "--db", str(db), "--out", str(tmp_path / "after.csv")]) == 0
    assert (tmp_path / "after.csv").read_text() == (tmp_path / "before.csv").read_text()


def test_rejected_readings_are_stored_with_the_point_exported_on_request_and_listed(
        tmp_path, capsys, cell):
    model, plan, truth, P = cell
    db = tmp_path / "cell.db"
    with RunStore(db) as st:
        rid = st.create_run(plan, RunContext(routine="poses", model="ur10e",
                                             tool_mm=(0.0, 0.0, 60.0)))
        good = _sample(plan, P, 0, verdict="remeasured")
        good.remeasures = 1
        blunder = Reading(_sample(plan, P, 0, offset=(0, 2.0, 0)), "2.000 mm from the model")
        blunder.sample.t_s -= 10  # taken before the accepted one
        cov = np.diag([4e-4, 3e-4, 5e-4])  # what the tracker said of it, kept with it
        blunder.sample.reflector, blunder.sample.face, blunder.sample.cov_mm2 = "RRR", 2, cov
        assert st.add_sample(rid, good, [blunder]) is True
        # the same point again (a resumed run redoing a point that landed): nothing added
        assert st.add_sample(rid, good, [blunder]) is False
        st.add_sample(rid, _sample(plan, P, 1, verdict="ok"))
        # point 1 revisited while point 2 is done: its reading replaced, the old one kept
        new1 = _sample(plan, P, 1, rng=np.random.default_rng(99), verdict="remeasured")
        new1.remeasures, new1.t_s = 1, 1500.0
        st.add_sample(rid, _sample(plan, P, 2, verdict="ok"),
                      revisited=[(new1, [Reading(_sample(plan, P, 1), "warm-up: off")])])
        unresolved = _sample(plan, P, 3, offset=(0, 0, 1.0), verdict="unresolved")
        unresolved.remeasures = 2
        other = Reading(_sample(plan, P, 3, offset=(3.0, 0, 0)), "3.000 mm; no two readings "
                        "agree")
        other.sample.t_s -= 10
        st.add_sample(rid, unresolved, [other])
        s = st.samples(rid)
        assert len(s) == 4 and s.verdict == ["remeasured", "remeasured", "ok", "unresolved"]
        np.testing.assert_array_equal(s.tracker_p_smr[1], new1.tracker_p_smr)
        readings = st.readings(rid)
        assert [r.sample.point_index for r in readings] == [0, 1, 3]
        assert (readings[0].sample.reflector, readings[0].sample.face) == ("RRR", 2)
        np.testing.assert_array_equal(readings[0].sample.cov_mm2, cov)
        assert readings[1].sample.reflector is None and readings[1].sample.cov_mm2 is None
        assert st.remeasure_counts(rid) == {"judged": 4, "warmup": 0, "suspects": 3,
                                            "remeasurements": 4, "rejected": 3,
                                            "model_disagrees": 0, "unresolved": 1}
    accepted, every = tmp_path / "a.csv", tmp_path / "all.csv"
    assert main(["export", "--db", str(db), "--out", str(accepted)]) == 0
    assert main(["export", "--db", str(db), "--out", str(every), "--all-readings"]) == 0
    err = capsys.readouterr().err
    assert "run 1: 3/90 points written" in err and "1 unresolved point(s) left out" in err
    assert "3/90 points and 4 rejected readings" in err
    header, *rows = csv.reader(ln for ln in every.read_text().splitlines()
                               if not ln.startswith("#"))
    assert header[-2:] == ["reading", "reason"] and ",reading" not in accepted.read_text()
    ids = [t.label for t in plan.targets[:4]]
    assert [(r[0], r[-2]) for r in rows] == [
        (ids[0], "rejected"), (ids[0], "accepted"), (ids[1], "rejected"), (ids[1], "accepted"),
        (ids[2], "accepted"), (ids[3], "rejected"), (ids[3], "rejected")]
    assert rows[0][-1] == "2.000 mm from the model"
    assert rows[1][-1] == "re-measured: agrees with the model"
    assert rows[6][-1].startswith("unresolved: no two readings agree")
    # the reader leaves the rejected rows out: both files are the same data
    a, b = load_csv(accepted, model), load_csv(every, model)
    assert a.pose_id == b.pose_id
    np.testing.assert_array_equal(a.tracker_p_smr, b.tracker_p_smr)
    bad = tmp_path / "bad.csv"
    bad.write_text(every.read_text().replace(",rejected,", ",maybe,"))
    assert main(["calibrate", str(bad), "--model", "ur10e"]) == 2
    assert "column reading: 'maybe'" in capsys.readouterr().err
    assert main(["runs", "--db", str(db)]) == 0
    out = capsys.readouterr().out
    assert "remeasured" in out.splitlines()[0] and out.splitlines()[2].split()[-1] == "3"
    assert main(["runs", "1", "--db", str(db), "--json"]) == 0
    d = json.loads(capsys.readouterr().out)
    assert d["remeasure"]["suspects"] == 3
    assert [x["reason"] for x in d["rejected_readings"]] == [
        "2.000 mm from the model", "warm-up: off", "3.000 mm; no two readings agree"]


def test_remeasure_option_is_validated_and_0_disables_the_model(cell, tmp_path):
    model, plan, _, _ = cell
    with pytest.raises(ValueError):
        ExecutorOptions(remeasure=-1)
    with RunStore(tmp_path / "c.db") as st:
        rid = st.create_run(plan, RunContext(routine="poses"))
        assert Remeasure.for_run(st, rid, plan, model, ExecutorOptions(remeasure=0)) is None
        policy = Remeasure.for_run(st, rid, plan, model, ExecutorOptions())
        assert policy.n == 2 and policy.running.fit is None


def test_a_long_arms_retract_is_shortened_to_pass_the_motion_guard():
    """0.01 rad a joint moves an IRB 2600's tool up to 31 mm, beyond the guard's 25 mm for
    an adaptive move: the retract keeps its direction and moves the tool 20 mm."""
    model = load_model("irb2600_12_165")
    plan = make_plan("poses", model, count=150, seed=1)
    signs = np.random.default_rng(0).choice([-1, 1], size=(len(plan.targets), 6))
    guard = MotionGuard(model)
    bare, capped = (Remeasure(None, plan, n=1, retract_rad=0.01, limits=model.limits_rad(),
                              model=m) for m in (None, model))
    far_bare, far = [], []
    for t, dirs in zip(plan.targets, signs, strict=True):
        q = np.array(t.q)
        ref = Sample(point_index=t.index, q=q, tracker_p_smr=np.zeros(3),
                     std_mm=np.full(3, 0.01), n_averaged=1, t_s=0.0, dirs=dirs)
        a, b = bare.retract(t, ref), capped.retract(t, ref)
        p = tool_points(model, np.vstack([q, a, b]))
        far_bare.append(float(np.linalg.norm(p[1] - p[0])))
        far.append(float(np.linalg.norm(p[2] - p[0])))
        k = np.linalg.norm(b - q) / np.linalg.norm(a - q)
        np.testing.assert_allclose(b - q, k * (a - q), atol=1e-15)  # the same direction
        assert not guard.deviation_problems(b, q)
    assert max(far_bare) > 25.0  # the bare retract: the guard refuses these
    assert max(far) == pytest.approx(RETRACT_TOOL_MM, abs=0.05)  # scaled to first order
    assert np.all(np.array(far) <= np.minimum(far_bare, RETRACT_TOOL_MM + 0.05) + 1e-9)
