"""Issue 29's capture seams: a plan made blind is refused before anything opens, a run
that skipped most of its points ends ``incomplete`` (exit 3; ``runs`` and ``resume`` say
what is missing), no visible pose names its cause, the documented minimum circle plans."""

from __future__ import annotations

import json

import pytest

from calibration import load_model
from calibration.cell.cell import CellSpec, Smr
from cellcal.cli import main
from daq.completeness import MISSING_SHARE, end_status
from daq.errors import NotEnoughVisible, TrackerUnknown
from daq.plans import Plan, Target
from daq.routines import make_plan
from daq.routines.frame import MIN_CIRCLE_SPAN_DEG
from daq.service import CaptureRequest, plan_run
from daq.store import RunStatus

SIM = ["--robot", "sim://robot?model=ur10e&name=seams", "--tracker",
       "sim://tracker?name=seams"]
TRACKER = (2500.0, 0.0, 500.0)


def _request(**kw) -> CaptureRequest:
    return CaptureRequest(routine="poses", model="ur10e", params={"count": 3},
                          tool_mm=(0.0, 0.0, 60.0), **kw)


def test_a_plan_without_the_trackers_position_is_refused_unless_waived():
    with pytest.raises(TrackerUnknown) as e:
        plan_run(_request())
    assert e.value.exit_code == 2
    assert all(w in str(e.value) for w in ("--tracker-at", "frame run", "--cell",
                                           "--no-visibility"))
    assert not plan_run(_request(visibility=False)).sight.checked  # waived: planned blind
    # a reflector that accepts every direction needs no tracker position
    assert plan_run(_request(cell=CellSpec(smr=Smr(reflector="360")))).plan.n_planned == 3
    assert plan_run(_request(tracker_at=TRACKER)).sight.checked


def _plan(n: int, spares: int = 0) -> Plan:
    targets = tuple(Target(i, "joints", q=[0.0] * 6, label=f"p{i}",
                           info={"spare": True} if i >= n else {}) for i in range(n + spares))
    return Plan("poses", {}, targets, model="ur10e")


def test_a_run_missing_more_than_a_tenth_of_its_points_ends_incomplete():
    plan = _plan(20, spares=2)
    assert plan.n_planned == 20 and MISSING_SHARE == 0.10
    def skipped_after(n):
        return set(range(n, 20))

    assert end_status(plan, set(range(20)), set()) == (RunStatus.COMPLETED, None)
    assert end_status(plan, set(range(18)), skipped_after(18))[0] == RunStatus.COMPLETED
    # 4 skipped, 2 spares measured in their place: 2 missing, completed
    assert end_status(plan, set(range(16)) | {20, 21},
                      skipped_after(16))[0] == RunStatus.COMPLETED
    # a routine that reached its goal early (a settled warm-up) skipped nothing
    assert end_status(plan, set(range(5)), set()) == (RunStatus.COMPLETED, None)
    status, reason = end_status(plan, set(range(17)), skipped_after(17))
    assert status == RunStatus.INCOMPLETE
    assert "3 of 20 planned points missing" in reason and "[17, 18, 19]" in reason
    assert "without the tracker's line of sight" in reason  # the plan recorded no cell


def test_a_blind_run_that_measures_almost_nothing_says_so(tmp_path, capsys):
    db = str(tmp_path / "c.db")
    rc = main(["capture", "poses", "--count", "4", "--seed", "3", "--model", "ur10e",
               "--tool-mm", "0,0,60", "--no-visibility", *SIM, "--db", db, "--json",
               "--measure-s", "0.01"])
    out = json.loads(capsys.readouterr().out)
    assert rc == 3 and out["status"] == "incomplete" and out["samples"] == 0
    assert "4 of 4 planned points missing" in out["reason"]
    assert main(["runs", "--db", db, "--json"]) == 0
    (run,) = json.loads(capsys.readouterr().out)
    assert run["status"] == "incomplete" and run["reason"] == out["reason"]
    assert main(["resume", "--db", db]) == 3  # not resumed: the skipped points named
    err = capsys.readouterr().err
    assert "is incomplete (0/4 points), nothing to resume" in err and "[0, 1, 2, 3]" in err


def test_no_visible_pose_names_its_cause():
    bare = load_model("ur10e")  # the SMR at the flange centre: inside the wrist
    cell = CellSpec().with_tracker(TRACKER, "--tracker-at")
    for routine, params in (("poses", {"count": 5}), ("frame", {})):
        with pytest.raises(NotEnoughVisible, match=r"inside the wrist.*--tool-mm X,Y,Z"):
            make_plan(routine, bare, cell=cell, **params)
    # something else in every beam: the constraint that hides the most is named
    walled = CellSpec.model_validate({"fixtures": [{"name": "wall", "box": {
        "centre": [1800, 0, 0], "size": [100, 8000, 8000]}}]}).with_tracker(TRACKER, "t")
    with pytest.raises(NotEnoughVisible, match=r"the cause: fixture wall is in the beam"):
        make_plan("poses", bare.with_changes(tool=(0.0, 0.0, 60.0)), count=5, cell=walled)


def test_the_documented_minimum_circle_plans_and_less_is_refused_naming_it(capsys):
    model = load_model("ur10e").with_changes(tool=(0.0, 0.0, 60.0))
    cell = CellSpec().with_tracker(TRACKER, "--tracker-at")
    plan = make_plan("frame", model, circle_span_deg=MIN_CIRCLE_SPAN_DEG, cell=cell)
    assert plan.params["circle_to_deg"] - plan.params["circle_from_deg"] == pytest.approx(
        MIN_CIRCLE_SPAN_DEG, abs=1e-6)
    rc = main(["capture", "frame", "--model", "ur10e", "--circle-span-deg", "29.9", *SIM,
               "--db", "never.db"])
    assert rc == 2 and "--circle-span-deg: 29.9 is below the minimum 30 deg" in \
        capsys.readouterr().err


@pytest.mark.parametrize("argv, flag", [
    (["capture", "frame", "--start-deg", "0,-60,nan,-120,-90,0"], "--start-deg"),
    (["capture", "steps", "--start-xyz", "600,inf,500"], "--start-xyz"),
    (["resume", "--meteo", "20,nan,45"], "--meteo"),
])
def test_a_nan_in_a_list_option_is_refused_before_anything_opens(argv, flag, tmp_path, capsys):
    db = tmp_path / "c.db"
    extra = [] if argv[0] == "resume" else ["--model", "ur10e", *SIM]
    assert main([*argv, *extra, "--db", str(db)]) == 2
    err = capsys.readouterr().err
    assert f"{flag}: expected" in err and "finite numbers" in err
    assert not db.exists()
