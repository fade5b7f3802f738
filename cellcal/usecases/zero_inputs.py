"""The inputs of the zero-point recalibration (``cellcal zero``): the postures (a CSV, or a
zero20 run of the store with the run as a data set), the chain to recalibrate, the joints
as a calibration's joint effects make them, and a previous result's offsets (fine pass).
"""

from __future__ import annotations

import json
import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np

from calibration import load_model
from calibration.data.dataset import Dataset
from calibration.zero_point import Postures

from ..errors import UsageError
from .input_errors import wrap_errors
from .stores import open_store


@dataclass(frozen=True)
class ZeroInputs:
    """The model (with the capture's tool), the postures, where they came from (``source``
    as the output says it) and, from a run, its id and the run as a data set (approach
    directions, temperature)."""

    model: Any
    postures: Postures
    source: str
    run_id: int | None = None
    data: Dataset | None = None


def from_csv(path: str, model_name: str | None) -> ZeroInputs:
    """A postures CSV, with the model ``model_name`` or the one its ``# model:`` line names
    (and the tool its ``# tool_mm:`` line records)."""
    from calibration.data.capture_meta import CaptureMeta
    from calibration.data.dataset import read_meta
    from calibration.zero_point import load_postures

    meta = read_meta(path)
    name = model_name or meta.get("model")
    if not name:
        raise UsageError(f"give --model: {path} names no model (no `# model:` line)")
    model = wrap_errors(lambda: load_model(name))
    postures = wrap_errors(lambda: load_postures(path, model))
    capture = wrap_errors(lambda: CaptureMeta.from_meta(meta, path))
    return ZeroInputs(capture.with_tool(model), postures, path)


def from_store(db: str, run: int | None, robot_id: str | None, model_name: str | None,
               *, to_base: bool) -> ZeroInputs:
    """A zero20 run of the store (default: the latest completed one, of ``robot_id`` when
    given), the model the run names (or ``model_name``) with the run's tool. ``to_base``:
    the measured tips in the base frame (else in the tracker frame: a calibration's base
    pose puts them there)."""
    from daq.run_data import dataset_from_run, postures_from_run
    from daq.store import StoreError, display_address

    try:
        with open_store(db, read_only=True) as store:
            postures, r = postures_from_run(store, run, to_base=to_base, robot_id=robot_id)
            data = dataset_from_run(store, r.id)  # approach directions, temperature
    except StoreError as e:
        raise UsageError(str(e)) from None
    if r.context.acquire.get("approach_rad", 0) > 0:
        # the closed loop approached every posture from below on every joint: the
        # executor's recorded directions are those of its move into the posture
        data.dirs = np.ones_like(data.q, dtype=int)
    name = model_name or r.model
    if not name:
        raise UsageError(f"run {r.id} records no model: give --model")
    model = wrap_errors(lambda: load_model(name))
    if r.context.tool_mm is not None:
        model = model.with_changes(tool=tuple(float(v) for v in r.context.tool_mm))
    if postures.q.shape[1] != model.n_joints:
        raise UsageError(f"run {r.id} has {postures.q.shape[1]} joints, model {model.name} "
                         f"has {model.n_joints}")
    return ZeroInputs(model, postures, f"{display_address(db)} run {r.id}", r.id, data)


def chain(model, params_path: str | None, note: Callable[[str], None]):
    """The chain to recalibrate and the base transform (R, t) or None; the notes on the
    params file go to ``note``."""
    if model.prismatic_mask() is not None:
        raise UsageError(f"model {model.name} has a prismatic joint: the zero-point "
                         "recalibration handles revolute joints only")
    from calibration.exports.params_io import read_params
    from calibration.model.inverse import ChainFK

    if not params_path:
        return ChainFK.from_model(model), None
    p = read_params(params_path, model=model)
    for n in p.notes:
        note(n)
    c = p.error_model.perturb(p.values)
    tool = c.tool if "tool" in c.applied else model.tool_mm()
    return ChainFK(model.convention, c.table, tool), c.tracker_T_base


def joints_as_calibrated(params_path: str, inputs: ZeroInputs, notes: list[str]) -> Postures:
    """The postures with the joints the calibration's joint effects (backlash, compliance,
    ...) make of the readings, so the offsets found are changes of the zeros alone (not
    the backlash of the side the postures were approached from, say). Needs the run's
    approach directions (``--db``); a CSV's postures are used as read, with a note."""
    from calibration.exports.params_io import load_params

    postures = inputs.postures
    em, x, _ = wrap_errors(lambda: load_params(params_path))
    joint = [e.label for e in em.effects if e.stage == "joint"]
    if not joint:
        return postures
    if inputs.data is None:
        notes.append(f"{params_path} has {', '.join(joint)}: the postures CSV has no approach "
                     "directions, so the offsets include what those effects do at the postures")
        return postures
    q = em.perturb(x, em.bind(inputs.data)).q
    notes.append(f"joints corrected by {', '.join(joint)} of {params_path} (the run's approach "
                 "directions): the offsets are changes of the zeros alone")
    return Postures(q, postures.plane, postures.pose_id, base_p_tip=postures.base_p_tip,
                    tracker_p_tip=postures.tracker_p_tip, source=postures.source,
                    lines=postures.lines)


def replay_start(path: str, n_joints: int) -> np.ndarray:
    """The offsets (rad) of a previous ``zero --json`` result: ``offsets_deg`` (null for
    an undetermined joint, read as 0) or ``offsets_rad``; one finite number per joint."""
    from calibration.files import read_text

    text = read_text(path, UsageError, "zero --json result", 50 << 20)
    try:
        doc = json.loads(text)
    except json.JSONDecodeError as e:
        raise UsageError(f"{path}: not valid JSON: line {e.lineno}: {e.msg}") from None
    except RecursionError:
        raise UsageError(f"{path}: not a `cellcal zero --json` result") from None
    if not isinstance(doc, dict):
        raise UsageError(f"{path}: not a `cellcal zero --json` result (a JSON object with "
                         "offsets_deg expected)")
    key = "offsets_rad" if "offsets_rad" in doc else "offsets_deg"
    values = doc.get(key)
    if values is None:
        raise UsageError(f"{path}: no offsets_deg: not a `cellcal zero --json` result")
    limit = math.pi if key == "offsets_rad" else 180.0
    if not isinstance(values, list) or len(values) != n_joints or not all(
            v is None or (isinstance(v, (int, float)) and not isinstance(v, bool)
                          and math.isfinite(v) and abs(v) <= limit) for v in values):
        raise UsageError(f"{path}: {key} must be {n_joints} numbers (or null) within "
                         f"±{limit:g}, one per joint of the model")
    off = np.array([0.0 if v is None else float(v) for v in values])
    return off if key == "offsets_rad" else np.radians(off)
