"""The whole cell on the simulator, from capture to a more accurate robot.

:func:`run_demo` starts the simulated cell (a UR10e with realistic hidden errors and one
hidden physical effect, or with ``robot="abb"`` an IRB 2600 behind an ABB controller)
behind its wire protocols on loopback, connects the real drivers (the Modbus TCP robot or
the ABB one over Robot Web Services; the line-protocol tracker over TCP), sets up the
measurement frame, captures calibration and validation poses into a SQLite run store, exports the
measurement CSV, calibrates the default model, diagnoses, lets the automatic diagnosis
add the missing effects one at a time, and writes the HTML report, which tells that story
step by step. With ``cold_start`` the robot warms up while it is captured, with drift
checks, and the story is its drift (:mod:`.demo_cold_start`). :func:`demo` is the use case
of ``cellcal demo``: its :class:`DemoRequest` checked, then :func:`run_demo`.
"""

from __future__ import annotations

import json
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from pydantic import Field

from calibration import load_csv
from calibration.diagnosis.auto_diagnosis import auto_diagnose
from calibration.diagnosis.diagnosis import diagnose
from calibration.exports.params_io import save_params
from calibration.files import write_atomic
from calibration.workflow import UNCALIBRATED_LABEL, AutoStory, staged_fit
from daq.run_data import dataset_from_run
from daq.service import CaptureRequest, plan_run, start_run
from daq.store import RunStore, RunSummary
from drivers.urls import open_robot, open_tracker
from presentation.demo_text import before_after
from presentation.html_report import render_report, story_stages
from presentation.provenance import Provenance
from sim_drivers.model_truth import ModelTruth
from sim_drivers.serve import ServeConfig, SimStack

from ..request import Request
from . import demo_cold_start as cold_start_demo
from .demo_folder import MANIFEST_KEY, DemoFolderError, check_demo_folder

#: hidden effects the demo draws from (by seed): each 0.05-0.5 mm at the tool
DEMO_EFFECTS = ("compliance:3", "compliance:2", "harmonic:1", "backlash:2", "scale:3",
                "coupling:5")


#: the demo's robots: their controller, how its URL begins, the arm (a built-in model, its
#: name in words) and the hidden effects the seed draws from
DEMO_ROBOTS = {
    "modbus": ("a PLC-style controller over Modbus TCP", "modbus+tcp://", "ur10e", "UR10e",
               DEMO_EFFECTS),
    # the built-in IRB 2600 has no link masses: no gravity-driven effect to hide
    "abb": ("an ABB IRC5 over Robot Web Services", "abb://", "irb2600_12_165",
            "ABB IRB 2600-12/1.65", ("harmonic:1", "backlash:2", "scale:3", "coupling:5")),
}

#: where the demo's user says the tracker stands (mm, robot base frame): roughly where the
#: simulated cell puts it (:data:`~sim_drivers.model_truth.DEFAULT_TRACKER_AT_MM`)
TRACKER_AT_MM = (2500.0, 0.0, 500.0)

#: a progress reporter per capture: called with (done, total, last_error), then closed
ProgressFactory = Callable[[], Any]


@dataclass
class DemoResult:
    """What the demo did and found (also written as ``demo.json``)."""

    out: Path
    hidden: str
    found: str | None
    noise_floor_mm: float
    rms: dict[str, float] = field(default_factory=dict)  # stage label -> validation RMS
    frame: dict | None = None
    seconds: float = 0.0
    files: dict[str, str] = field(default_factory=dict)

    def to_json(self) -> dict:
        return {"hidden": self.hidden, "found": self.found,
                "noise_floor_mm": self.noise_floor_mm, "valid_rms_mm": self.rms,
                "seconds": self.seconds, "files": self.files,
                "frame": None if self.frame is None else {
                    k: self.frame[k] for k in ("orthogonality_deg",) if k in self.frame}}


def pick_hidden(seed: int, robot: str = "modbus") -> str:
    """The hidden effect of the demo of ``seed`` on ``robot`` (of :data:`DEMO_ROBOTS`)."""
    effects = DEMO_ROBOTS[robot][4]
    return effects[seed % len(effects)]


def run_demo(out: str | Path = "cellcal-demo", *, seed: int = 1, hidden: str | None = None,
             poses: int = 300, valid: int = 150, progress: ProgressFactory | None = None,
             say: Callable[[str], None] | None = None, force: bool = False,
             cold_start: bool = False, robot: str = "modbus") -> DemoResult:
    """Run the demo; returns what it measured. ``say`` receives the step-by-step text, line
    by line; ``progress()`` makes each capture's progress reporter (None: none);
    ``cold_start``: the robot starts cold (no physical effect hidden unless ``hidden``);
    ``robot``: the robot's controller, one of :data:`DEMO_ROBOTS` (``abb``: an ABB IRC5
    moved over Robot Web Services through the RAPID server module).

    :class:`DemoFolderError` for a folder holding other files (see
    :func:`check_demo_folder`; ``force`` writes there anyway, never over a foreign store).
    """
    t_start = time.perf_counter()
    out = Path(out)
    check_demo_folder(out, force)
    out.mkdir(parents=True, exist_ok=True)
    controller, scheme, arm, arm_words, _ = DEMO_ROBOTS[robot]
    options = cold_start_demo.capture_options() if cold_start else {}
    hidden = hidden or (None if cold_start else pick_hidden(seed, robot))
    db_path, csv_path = out / "cell.db", out / "capture.csv"
    params_path, report_path = out / "params.json", out / "report.html"
    # the manifest first: the store about to be made is the demo's, whatever happens next
    write_atomic(out / "demo.json", json.dumps(
        {MANIFEST_KEY: 1, "status": "running", "files": {"store": str(db_path)}}) + "\n")
    for name in ("cell.db", "cell.db-wal", "cell.db-shm", "cell.db-journal"):
        (out / name).unlink(missing_ok=True)

    if say is None:
        def say(text: str) -> None:
            pass

    truth = ModelTruth.from_spec(arm, hidden, seed)
    model = truth.model  # what the controller knows: the nominal arm, SMR on a 60 mm holder
    say(f"cellcal demo (seed {seed}): a simulated {arm_words} with realistic hidden errors and "
        + ("a cold start (it warms up while it is captured)" if cold_start else
           "one hidden physical effect") + ", measured by a simulated laser tracker")
    config = ServeConfig(seed=seed, hidden=hidden, pty=False,
                         ports={"modbus": 0, "line_robot": 0, "tracker": 0, "abb": 0},
                         thermal="cold" if cold_start else None, abb=robot == "abb")
    result = DemoResult(out, cold_start_demo.HIDDEN if cold_start else hidden, None,
                        float("nan"))
    with SimStack(config, truth_factory=lambda s, h: truth) as stack:
        robot_url = next(u for u in stack.urls if u.startswith(scheme))
        tracker_url = next(u for u in stack.urls if u.startswith("tracker+tcp://"))
        served = "" if robot == "modbus" else f" ({controller})"
        say(f"[1/7] cell served on loopback: robot {robot_url}{served}, tracker {tracker_url}")
        robot, tracker = open_robot(robot_url), open_tracker(tracker_url)
        try:
            robot.connect(5.0)
            tracker.connect(5.0)
            with RunStore(db_path) as store:
                # the frame from a start the tracker sees (the routine picks it), then poses
                # planned for the tracker the frame measured
                frame_run = _capture(store, "frame", {}, model, robot, tracker,
                                     (robot_url, tracker_url), progress, seed,
                                     tracker_at=TRACKER_AT_MM)
                frame = store.run(frame_run).frame
                result.frame = frame
                say(f"[2/7] measurement frame: joint-1 circle rms {frame['circle']['rms_mm']:.4f}"
                    f" mm, x line rms {frame['line']['rms_mm']:.4f} mm, x line "
                    f"{frame['orthogonality_deg']:.3f} deg off perpendicular to joint 1")
                count = poses + valid
                say(f"[3/7] capturing {poses} calibration + {valid} validation poses "
                    f"into {db_path}" + (cold_start_demo.CAPTURE_NOTE if cold_start else ""))
                run_id = _capture(store, "poses", {"count": count, "seed": seed,
                                                   "valid_fraction": valid / count,
                                                   "floor_z_mm": 0.0},
                                  model, robot, tracker, (robot_url, tracker_url), progress,
                                  seed, **options)
                if cold_start:
                    say(cold_start_demo.drift_story(store, run_id))
                dataset_from_run(store, run_id).to_csv(csv_path)
                n_int = len(store.interruptions(run_id))
                n_samples = store.n_samples(run_id)
                summary = store.run(run_id).summary or RunSummary()
            broken = (f", {summary.beam_breaks} beam breaks, "
                      f"{len(summary.skipped_points or ())} points replaced"
                      if summary.beam_breaks else "")
            say(f"      {n_samples} samples stored"
                f"{f', {n_int} interruptions recovered' if n_int else ''}{broken}; "
                f"exported {csv_path}")
        finally:
            robot.close()
            tracker.close()

    data = load_csv(csv_path, model)  # through the interchange format, as a user would
    floor = data.noise_floor_mm()
    result.noise_floor_mm = floor
    sf = staged_fit(data, model, refit=False)
    fit, diag = sf.current, sf.diagnosis
    say(f"[4/7] calibrated {','.join(fit.error_model.labels)}: RMS {fit.calib['rms_mm']:.4f} "
        f"mm on the {fit.calib['n']} calibration poses, {fit.valid['rms_mm']:.4f} mm on the "
        f"{fit.valid['n']} validation poses (uncalibrated {sf.uncalibrated.valid['rms_mm']:.3f}"
        f" mm, noise floor {floor:.4f} mm)")
    say(f"[5/7] diagnosis ({diag.n_screened} candidates): {diag.recommendation()}")
    auto = auto_diagnose(fit, data)
    story = AutoStory.from_auto(auto, sf.uncalibrated)
    stages = story_stages(sf.uncalibrated, story, ",".join(fit.error_model.labels),
                          UNCALIBRATED_LABEL)
    final = story.final.fit
    added = [s.effect for s in story.added]
    if added:
        result.found = (cold_start_demo.drift_found(added) if cold_start else
                        hidden if hidden in added else added[0])
        say(f"[6/7] calibrated --effects {','.join(final.error_model.labels)}: RMS "
            f"{final.calib['rms_mm']:.4f} mm calibration, {final.valid['rms_mm']:.4f} mm "
            "validation")
        diag = diagnose(final, data)
    else:
        say("[6/7] nothing to add")
    save_params(final, params_path, auto=auto, capture=data.capture)
    render_report(diag, stages, title=f"cellcal demo, seed {seed}", story=story, data=data,
                  provenance=Provenance.of(model.name, csv_path, data)).write(report_path)
    say(f"[7/7] wrote {params_path}, {report_path} and {out / 'demo.json'} (what was hidden "
        "and found, the RMS of each stage)")

    result.rms = {s.label: s.fit.valid["rms_mm"] for s in stages}
    result.seconds = time.perf_counter() - t_start
    result.files = {"store": str(db_path), "csv": str(csv_path), "params": str(params_path),
                    "report": str(report_path)}
    write_atomic(out / "demo.json",
                 json.dumps({MANIFEST_KEY: 1, **result.to_json()}, indent=1) + "\n")
    say("")
    say(before_after(result))
    return result


def _capture(store, routine, params, model, robot, tracker, urls, progress, seed,
             tracker_at=None, **options) -> int:
    """Plan (for the tracker at ``tracker_at``, else where the store's frame run measured
    it), dry-run and execute one routine (:mod:`daq.service`) with further ``options`` of
    the request; returns the run id (raises on failure)."""
    request = CaptureRequest(routine=routine, model=model.name, params=params, seed=seed,
                             tracker_at=tracker_at, **options)
    planned = plan_run(request, model=model, db=store.path)
    prog = progress() if progress else None
    try:
        out = start_run(store, planned, robot_url=urls[0], tracker_url=urls[1],
                        devices=(robot, tracker), progress=prog)
    finally:
        if prog is not None:
            prog.close()
    if out.status != "completed":
        raise RuntimeError(f"{routine} run {out.run_id} {out.status}: {out.reason}")
    return out.run_id


class DemoRequest(Request):
    """The demo's cell (``seed``, ``hidden``: default chosen by the seed), its folder
    (``force``: one holding other files), and the calibration and validation poses."""

    seed: int = Field(1, alias="--seed")
    hidden: str | None = Field(None, alias="--hidden")
    out: str = Field("cellcal-demo", alias="--out")
    poses: int = Field(300, ge=50, alias="--poses")
    valid: int = Field(150, ge=20, alias="--valid")
    force: bool = Field(False, alias="--force")
    cold_start: bool = Field(False, alias="--cold-start")
    robot: str = Field("modbus", alias="--robot")


def demo(req: DemoRequest, *, say: Callable[[str], None] | None = None,
         progress: ProgressFactory | None = None) -> DemoResult:
    """Check the request (the hidden effect, the folder: UsageError), then
    :func:`run_demo`."""
    from calibration.effects import EffectError, parse_effect
    from calibration.model.model_loading import load_model

    from ..errors import UsageError

    if req.hidden:
        try:
            parse_effect(req.hidden, load_model(DEMO_ROBOTS[req.robot][2]))
        except EffectError as e:
            raise UsageError(f"--hidden {req.hidden!r}: {e}") from None
    try:
        check_demo_folder(Path(req.out), req.force)
    except DemoFolderError as e:
        raise UsageError(str(e)) from None
    return run_demo(req.out, seed=req.seed, hidden=req.hidden, poses=req.poses,
                    valid=req.valid, progress=progress, say=say, force=req.force,
                    cold_start=req.cold_start, robot=req.robot)
