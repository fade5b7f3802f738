"""``validate``: a program's waypoints (or a targets CSV) run on the cell as written,
compensated and with the calibrated DH table alone, measured by the tracker, stored as a
run of the ``validate`` routine (:mod:`daq.routines.validate`: resumable, nothing lost).

:class:`ValidateRequest` is what the command was asked; :func:`validate` reads the
calibration and the waypoints, computes the joints each controller ends at
(:func:`cellcal.programs.compensate.solve`,
:mod:`calibration.compensation.controller_joints`), plans
and dry-runs the run with the capture service and, unless a dry run, runs it. The errors
are measured in the calibration's base frame when it identified one (the frame its
targets live in: a tracker calibration cannot tell joint 1's zero from the base's turn
about it, so the frame run's frame differs from it by such a turn), else in the frame
run's; a store without a frame run is refused (exit 2).
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from pydantic import Field

from calibration.compensation.compensation import load_targets
from calibration.compensation.controller_joints import controller_joints
from calibration.compensation.pose_compensation import NominalTcpFK, as_poses
from calibration.effects import load_effect_file
from calibration.exports.params_io import read_params
from calibration.fit.envelope import outside_envelope, refuse_outside
from calibration.fit.thermal_state import target_state
from daq.sight import frame_from_store

from ..errors import UsageError
from ..programs import compensate as program_filter
from ..programs.targets import ProgramError
from ..request import Request
from .capture import CaptureArgs, capture
from .program_inputs import program_options
from .target_checks import no_envelope_note


class ValidateRequest(Request):
    """The flags of ``cellcal validate`` beside the capture's (:class:`CaptureArgs`)."""

    params: str = Field(alias="--params")
    program: str | None = Field(None, alias="--program")
    targets: str | None = Field(None, alias="TARGETS.csv")
    effect_file: tuple[str, ...] = Field((), alias="--effect-file")
    language: str | None = Field(None, alias="--language")
    frames: str | None = Field(None, alias="--frames")
    start: str | None = Field(None, alias="--start")
    temp_c: float | None = Field(None, alias="--temp-c")
    payload_kg: float | None = Field(None, alias="--payload-kg")
    strict_range: bool = Field(False, alias="--strict-range")


@dataclass
class Validation:
    """What :func:`validate` did: the capture (a
    :class:`~cellcal.usecases.capture.CaptureResult`), the calibration's validation RMS
    (None when params.json has none), the waypoints planned, notes (waypoints left out,
    the frame used) and the waypoints beyond the calibrated envelope (``outside_range``:
    ``{"label": "L12", "outside_range": ["q2"]}`` each)."""

    result: Any
    valid_rms_mm: float | None
    n_waypoints: int
    notes: list[str] = field(default_factory=list)
    outside_range: list[dict] = field(default_factory=list)


def _waypoints_of_program(request: ValidateRequest, em, x, variants, thermal):
    dialect = program_filter.language_of(request.program, request.language)
    program = program_filter.read_program(request.program, dialect)
    if program.compensated_at is not None:  # its "compensated" variant: compensated twice
        raise ProgramError(f"{request.program}: line {program.compensated_at}: this program "
                           "was compensated already (a 'cellcal:' comment); validate the "
                           "original: it runs it as written and compensated")
    options = program_options(em, frames=request.frames, start_deg=request.start,
                              temp_c=request.temp_c, payload_kg=request.payload_kg,
                              thermal=thermal)
    solved = program_filter.solve(program, dialect, em, x, options,
                                  geometric="geometric" in variants)
    notes = [f"not run: {r}" for r in program.refusals + solved.refusals]
    notes += _thermal_notes(solved.thermal)
    if solved.joints is None:
        return [], notes
    labels = [f"L{t.line}" + (f".{k}" if sum(u.line == t.line for u in solved.targets) > 1
                              else "")
              for k, t in enumerate(solved.targets)]
    smr = _smr_targets(em, x, solved.joints.compensation.target, solved.tcp, solved.measured)
    return _rows(solved.joints, labels, [t.line for t in solved.targets], variants,
                 smr), notes


def _smr_targets(em, x, target, tcp, measured) -> np.ndarray:
    """Where the SMR must be (n, 3) when the program's TCP is at its target: the target's
    point for the measured TCP, else the identified SMR point carried by the flange the
    target implies (the tracker measures the SMR, whatever the program's TCP)."""
    flange = target @ np.linalg.inv(tcp)
    p_smr = np.asarray(em.perturb(x).tool, float)
    return np.where(measured[:, None], target[:, :3, 3],
                    flange[:, :3, :3] @ p_smr + flange[:, :3, 3])


def _waypoints_of_csv(request: ValidateRequest, em, x, variants, thermal):
    t = load_targets(request.targets, em.model)
    if t.q is None:
        raise UsageError(f"{request.targets}: validate needs q1..q{em.model.n_joints} (the "
                         "nominal joints of each target: where the controller's solution is)")
    r = NominalTcpFK(em.model, em.model.tool_mm()).chain(t.q)
    pose = as_poses(t.base_p_tcp, r.base_R_flange)
    columns, state = target_state(em, thermal, t.columns, len(t.q))
    cj = controller_joints(em, x, t.q, pose=pose, is_pose=np.ones(len(t.q), bool),
                           measured=True, columns=columns,
                           geometric="geometric" in variants)
    return _rows(cj, list(t.pose_id), [None] * len(t.q), variants,
                 cj.compensation.target[:, :3, 3]), _thermal_notes(state)


def _thermal_notes(state: dict | None) -> list[str]:
    """The thermal state compensated for (a model with drift effects), as a note."""
    if state is None:
        return []
    from presentation.thermal_text import state_line

    return [f"thermal: compensated for {state_line(state)}"]


def _rows(cj, labels, lines, variants, smr) -> list[dict]:
    """The plan's waypoints (``smr``: where the SMR must be, (n, 3) mm): those every
    variant reaches (the others are noted)."""
    ok = np.all([cj.success[v] for v in variants], axis=0)
    return [{"label": labels[i], "line": lines[i], "xyz_mm": smr[i].tolist(),
             "joints_deg": {v: np.degrees(cj.joints[v][i]).tolist() for v in variants},
             "reached": bool(ok[i])} for i in range(len(labels))]


def validate(request: ValidateRequest, capture_args: CaptureArgs, **run_options
             ) -> Validation:
    """Plan and (unless ``capture_args.dry_run``) run the validation; ``run_options`` go to
    :func:`~cellcal.usecases.capture.capture` (progress, on_started, confirm).

    Raises
    ------
    UsageError
        Neither or both of ``--program`` and TARGETS.csv, a program that does not parse,
        no frame run in the store, no waypoint left to run (exit 2).
    """
    if (request.program is None) == (request.targets is None):
        raise UsageError("give --program PROGRAM or TARGETS.csv (one of them)")
    for f in request.effect_file:
        load_effect_file(f)
    loaded = read_params(request.params)
    em, x = loaded.error_model, loaded.values
    frame_T, frame_run = frame_from_store(capture_args.db, capture_args.frame_run)
    if frame_T is None:
        raise UsageError(f"--db {capture_args.db}: no measurement frame (validate measures "
                         "where the tool went in the robot base frame): run `cellcal capture "
                         "frame` into it first, or give --frame-run RUN")
    variants = capture_args.params["variants"]
    rows, notes = (_waypoints_of_program if request.program else _waypoints_of_csv)(
        request, em, x, variants, loaded.thermal)
    notes += [f"not run: {w['label']}: a controller variant does not reach it"
              for w in rows if not w["reached"]]
    rows = [{k: v for k, v in w.items() if k != "reached"} for w in rows if w["reached"]]
    if not rows:
        raise UsageError(f"{request.program or request.targets}: no waypoint to run"
                         + (f" ({'; '.join(notes)})" if notes else ""))
    outside = waypoints_outside(loaded.envelope, rows, request.temp_c)
    if request.strict_range:
        if loaded.envelope is None:
            raise UsageError(f"--strict-range: {no_envelope_note(request.params)}")
        refuse_outside(outside, [w["label"] for w in rows], "waypoints",
                       request.program or request.targets)
    if loaded.envelope is None:
        notes.append(no_envelope_note(request.params))
    beyond = [(w["label"], names) for w, names in zip(rows, outside, strict=True) if names]
    if beyond:
        notes.append(f"{len(beyond)} of {len(rows)} waypoints lie beyond the calibrated "
                     "envelope (the calibration did not measure there): "
                     + "; ".join(f"{lab} ({', '.join(n)})" for lab, n in beyond[:10])
                     + (f"; and {len(beyond) - 10} more" if len(beyond) > 10 else ""))
    frame, note = _eval_frame(em, x, frame_T, frame_run, rows)
    notes.append(note)
    source = {"program" if request.program else "targets": request.program or request.targets,
              "params": request.params}
    args = capture_args.model_copy(update={
        "params": {**capture_args.params, "waypoints": rows, "frame": frame, "source": source},
        "model": em.model.name, "tool_mm": tuple(em.model.tool_mm())})
    result = capture(args, model=em.model, **run_options)
    valid = (loaded_stats(request.params) or {}).get("rms_mm")
    return Validation(result, valid, len(rows), notes,
                      [{"label": lab, "outside_range": n} for lab, n in beyond])


def waypoints_outside(envelope, rows: list[dict], temp_c: float | None) -> list[list[str]]:
    """Per waypoint, the quantities beyond the calibrated envelope in any variant's joints
    (and the air temperature ``--temp-c``), in the envelope's order."""
    if not rows:
        return []
    per = [set() for _ in rows]
    order: list[str] = []
    columns = {} if temp_c is None else {"temp_c": np.full(len(rows), float(temp_c))}
    for v in rows[0]["joints_deg"]:
        q = np.radians([w["joints_deg"][v] for w in rows])
        for i, names in enumerate(outside_envelope(envelope, q, columns)):
            per[i].update(names)
            order += [n for n in names if n not in order]
    return [[n for n in order if n in p] for p in per]


def _eval_frame(em, x, frame_T, frame_run, rows) -> tuple[dict | None, str]:
    """The frame the errors are measured in, and a note saying which: the calibration's
    base when it has one (with how far the frame run's is from it at the waypoints)."""
    if "base" not in em.labels:
        return None, f"errors in the measurement frame of frame run {frame_run}"
    R, t = em.perturb(x).tracker_T_base
    T = np.eye(4)
    T[:3, :3], T[:3, 3] = R, t
    p = np.array([w["xyz_mm"] for w in rows])
    apart = np.linalg.norm((p @ T[:3, :3].T + T[:3, 3]) - (p @ frame_T[:3, :3].T
                                                           + frame_T[:3, 3]), axis=1)
    return ({"tracker_T_base": T.tolist(), "source": "the calibration's base frame"},
            f"errors in the calibration's base frame (frame run {frame_run}'s is up to "
            f"{apart.max():.3f} mm from it at the waypoints)")


def loaded_stats(path: str) -> dict | None:
    """The validation statistics a params.json keeps (``stats.valid``), or None."""
    try:
        with open(path, encoding="utf-8") as f:
            return json.load(f).get("stats", {}).get("valid")
    except (OSError, ValueError, AttributeError):
        return None

