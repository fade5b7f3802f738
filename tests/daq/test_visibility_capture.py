"""Plans the tracker sees, in a short order, captured on the honest simulator: the line of
sight end to end (plans, dry run, exit codes, the executor's skip/replace policy, counts)."""

from __future__ import annotations

import json

import numpy as np
import pytest

from calibration.cell.cell import CellSpec, cell_from_dict
from calibration.cell.visibility import assess, sample_visible, smr_pose
from cellcal.cli import main
from daq.errors import NotEnoughVisible
from daq.plans import path_time, shortest_order
from daq.routines import make_plan
from daq.run_context import ExecutorOptions
from daq.store import RunStore
from sim_drivers.model_truth import ModelTruth

from .capture_helpers import connected, rough_cell, run_plan, served_cell, ur10e_controller_model

#: tracker placements (mm, robot base frame) the capture tests use
BESIDE = (0.0, 2600.0, 400.0)
BEHIND = (-2400.0, 300.0, 700.0)
FAST = ExecutorOptions(measure_s=0.01, backoff_s=0.001, backoff_max_s=0.002)


def _truth_at(tracker_at):
    def factory(seed, hidden=None):
        return ModelTruth.from_spec("ur10e", hidden, seed, tracker_at=tracker_at)
    return factory


def _joint_travel(plan) -> tuple[float, float]:
    """Joint travel (rad) of the plan's order and the mean of 20 random orders (no spares)."""
    q = np.array([t.q for t in plan.targets if not t.spare])
    rng = np.random.default_rng(0)
    return path_time(q, 1.0), float(np.mean([path_time(q[rng.permutation(len(q))], 1.0)
                                             for _ in range(20)]))


# ------------------------------------------------------------------ order
def test_shortest_order_is_short_and_keeps_both_sets_interleaved():
    model = ur10e_controller_model()
    q = sample_visible(model, rough_cell(), 120, np.random.default_rng(0))
    sets = np.array(["calib"] * 90 + ["valid"] * 30)
    order = shortest_order(q, 0.5, sets)
    assert sorted(order.tolist()) == list(range(120))
    rng = np.random.default_rng(1)
    random = np.mean([path_time(q[rng.permutation(120)], 0.5) for _ in range(20)])
    assert path_time(q[order], 0.5) < 0.6 * random
    # a run stopped early still has both kinds, in roughly their shares
    s = sets[order]
    assert "valid" in s[:8] and "calib" in s[:8]
    for k in (30, 60, 90):
        assert 0.1 < np.mean(s[:k] == "valid") < 0.45


# ------------------------------------------------------------------ plans
@pytest.mark.parametrize("tracker_at", [BESIDE, BEHIND])
def test_steps_zero20_frame_and_iso9283_plans_stay_visible(tracker_at):
    model = ur10e_controller_model()
    cell = rough_cell(tracker_at)
    truth_cell = CellSpec().with_tracker(tracker_at, "truth")
    d = np.asarray(tracker_at[:2]) / np.linalg.norm(tracker_at[:2])
    plans = [make_plan("steps", model, step_mm=30.0, count=6, cell=cell),
             make_plan("zero20", model, target_xyz=[*(700 * d), 300.0], cell=cell),
             make_plan("frame", model, cell=cell),
             make_plan("iso9283", model, cycles=2, cell=cell)]
    for plan in plans:
        q = np.array([t.q for t in plan.targets])
        # seen with the plan's margins from where the plan thinks the tracker is, and
        # without margins from where it really is
        assert assess(model, q, cell).visible.all(), plan.routine
        assert assess(model, q, truth_cell, margins=False).visible.all(), plan.routine
        assert plan.params["visibility"]["tracker_source"] == "--tracker-at"
    frame = plans[2].params
    assert frame["circle_to_deg"] - frame["circle_from_deg"] >= 30.0


def test_a_routine_that_cannot_see_enough_says_what_to_change():
    model = ur10e_controller_model()
    # a start posture with the tool pointing down: the tracker 2.5 m away cannot see it
    with pytest.raises(NotEnoughVisible, match="faces .* deg away") as e:
        make_plan("steps", model, start_deg=[0, -60, 90, -120, -90, 0], cell=rough_cell())
    assert "change:" in str(e.value) and e.value.exit_code == 3
    # the tracker behind a wall: no pose has a clear beam
    walled = cell_from_dict({"fixtures": [{"name": "wall", "box": {
        "centre": [1800, 0, 0], "size": [100, 8000, 8000]}}]}).with_tracker(
            (2500, 0, 500), "--tracker-at")
    with pytest.raises(NotEnoughVisible, match="only 0 of 20 poses") as e:
        make_plan("poses", model, count=20, cell=walled)
    assert "move the tracker" in str(e.value)


# ---------------------------------------------------------------- command
def test_dry_run_lists_hidden_points_and_estimates_time(tmp_path, capsys):
    db = str(tmp_path / "c.db")
    common = ["--model", "ur10e", "--tool-mm", "0,0,60", "--robot", "sim://robot",
              "--tracker", "sim://tracker", "--db", db, "--tracker-at", "2500,0,500",
              "--dry-run"]
    # planned without the line of sight, then predicted: most poses hidden, with reasons
    assert main(["capture", "poses", "--count", "30", "--no-visibility", *common]) == 0
    out = capsys.readouterr().out
    assert "not visible: point" in out and "deg away from the tracker" in out
    assert "estimated capture time" in out and "in a random order" in out
    # planned for it: every pose visible; the JSON carries the prediction and the estimate
    assert main(["capture", "poses", "--count", "30", "--json", *common,
                 "--plot", str(tmp_path / "plan.png")]) == 0
    doc = json.loads(capsys.readouterr().out)
    assert doc["sight"]["checked"] and doc["sight"]["visible"] == doc["points"] + doc["spares"]
    assert doc["estimated_capture_s"] < 0.8 * doc["estimated_capture_random_order_s"]
    assert (tmp_path / "plan.png").read_bytes()[:4] == b"\x89PNG"
    # a start the tracker cannot see: exit 3 with the points and reasons
    rc = main(["capture", "steps", "--start-deg", "0,-60,90,-120,-90,0", *common])
    err = capsys.readouterr().err
    assert rc == 3 and "would not see" in err and "change:" in err
    # a bad cell file: exit 2, naming the file and the field
    bad = tmp_path / "cell.yaml"
    bad.write_text("smr: {reflector: RRR 9in}\n")
    assert main(["capture", "poses", "--cell", str(bad), *common]) == 2
    assert f"{bad}: smr: unknown reflector" in capsys.readouterr().err
    # unknown tracker: refused, naming the three ways to give it (issue 29) ...
    common_no_tracker = [c for c in common if c not in ("--tracker-at", "2500,0,500")]
    assert main(["capture", "poses", "--count", "5", *common_no_tracker]) == 2
    err = capsys.readouterr().err
    assert all(w in err for w in ("--tracker-at", "frame run", "--cell", "--no-visibility"))
    # ... or planned as before when the line of sight is waived, and said so
    assert main(["capture", "poses", "--count", "5", "--no-visibility", *common_no_tracker]) == 0
    assert "tracker position is unknown" in capsys.readouterr().out
    assert not (tmp_path / "c.db").exists()


# ---------------------------------------------------------------- capture
def _capture(tmp_path, tracker_at, method, count, seed):
    model = ur10e_controller_model()
    plan = make_plan("poses", model, count=count, seed=seed, method=method,
                     valid_fraction=0.0 if method == "optimal" else 0.2,
                     cell=rough_cell(tracker_at))
    with served_cell(_truth_at(tracker_at), seed=seed) as stack, \
            RunStore(tmp_path / f"{method}.db") as store:
        with connected(stack.urls[1], stack.urls[2]) as (robot, tracker):
            run_id, status = run_plan(store, plan, robot, tracker, options=FAST)
        samples = store.samples(run_id)
        summary = store.run(run_id).summary
    assert status == "completed"
    regular = {t.index for t in plan.targets if not t.spare}
    measured = len(regular & set(samples.point_index.tolist())) / len(regular)
    travel, random = _joint_travel(plan)
    print(f"\n{method} {count} tracker at {tracker_at}: measured {measured:.3f} of the "
          f"planned, {summary['beam_breaks']} beam breaks, skipped "
          f"{summary['skipped_points']}, travel {travel / random:.2f} of a random order")
    assert measured >= 0.98
    assert summary["beam_breaks"] <= 0.02 * count
    assert travel <= 0.6 * random
    assert len(samples.point_index) == count  # spares made up for any skipped point


def test_capture_of_visible_random_poses_beside(tmp_path):
    _capture(tmp_path, BESIDE, "random", 40, 11)


@pytest.mark.slow
@pytest.mark.parametrize("tracker_at", [BESIDE, BEHIND], ids=["beside", "behind"])
@pytest.mark.parametrize("method,count", [("optimal", 150), ("random", 100)])
def test_capture_of_planned_poses_is_measured(tmp_path, tracker_at, method, count):
    _capture(tmp_path, tracker_at, method, count, 5)


def test_persistent_beam_breaks_are_skipped_and_replaced_by_spares(tmp_path, capsys):
    """A pillar the plan does not know about hides a few planned poses: each is retried,
    then skipped and replaced by a spare; the run completes and counts them."""
    model = ur10e_controller_model()
    plan = make_plan("poses", model, count=40, seed=4, cell=rough_cell(), spares=12)
    q = np.array([t.q for t in plan.targets])
    p, _ = smr_pose(model, q, (0, 0, 1))
    tracker = np.asarray(rough_cell().tracker_mm)
    # a slim pillar on the beam of point 3, 1.2 m from the tracker
    k = 3
    c = tracker + 1200.0 * (p[k] - tracker) / np.linalg.norm(p[k] - tracker)
    pillar = cell_from_dict({"fixtures": [{"name": "pillar", "cylinder": {
        "start": [c[0], c[1], -1000.0], "end": [c[0], c[1], 2500.0], "radius": 40.0}}]})
    hidden = ~assess(model, q, pillar.with_tracker(tracker, "x"), margins=False).visible
    regular = np.array([not t.spare for t in plan.targets])
    assert 1 <= (hidden & regular).sum() <= 6 and (~hidden & ~regular).sum() >= 6
    db = tmp_path / "c.db"
    with served_cell(_truth_at(tuple(tracker)), seed=4, cell=pillar) as stack, \
            RunStore(db) as store:
        with connected(stack.urls[1], stack.urls[2]) as (robot, tracker_drv):
            run_id, status = run_plan(store, plan, robot, tracker_drv, options=FAST)
        s = store.samples(run_id)
        summary = store.run(run_id).summary
        kinds = [(i, kind, msg) for i, _, kind, msg in store.interruptions(run_id)]
    assert status == "completed"
    skipped = sorted(i for i, kind, _ in kinds if kind == "skipped")
    assert summary["skipped_points"] == skipped
    # every regular point the pillar hides is skipped, nothing else
    assert [i for i in skipped if regular[i]] == np.flatnonzero(hidden & regular).tolist()
    assert all("fixture pillar in the beam" in m for i, kind, m in kinds if kind == "skipped")
    assert summary["beam_breaks"] == sum(kind == "beam" for _, kind, _ in kinds)
    assert summary["beam_breaks"] == 4 * len(skipped)  # BEAM_RETRIES + 1 each
    # the spares made up for them: 40 points measured
    assert len(s.point_index) == 40 and summary["spares_measured"] == (hidden & regular).sum()
    assert main(["runs", "--db", str(db)]) == 0
    out = capsys.readouterr().out
    assert "beam breaks" in out and "skipped" in out
    row = out.strip().splitlines()[-1].split()
    assert row[2] == "completed" and row[3] == "40/40"
