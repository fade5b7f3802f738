"""``compensate``: the joints and corrected Cartesian targets that make the real robot
reach target points, from a calibration (params.json), and the exports of the calibrated
model (:mod:`.model_exports`).

:class:`CompensateRequest` is what the command was asked; :func:`compensate_targets`
writes the exports, compensates the targets and writes the compensated CSV; it returns a
:class:`Compensated`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from pydantic import Field

from calibration import ErrorModel, RobotModel
from calibration.compensation.compensation import Compensation, Targets, compensate, load_targets
from calibration.data.capture_meta import CaptureMeta
from calibration.effects import load_effect_file
from calibration.exports.params_io import capture_of, read_params
from calibration.files import write_atomic
from calibration.fit.thermal_state import target_state
from calibration.numerics.memory import check_memory
from presentation.compensation_text import compensated_csv

from ..errors import UsageError
from ..request import Request
from .model_exports import Exports, write_exports
from .outputs import check_outputs, existing_paths
from .target_checks import (
    JOINTS_TOLERANCE_MM,
    check_joints_reach,
    no_envelope_note,
    outside_envelope,
    refuse_outside,
)


class CompensateRequest(Request):
    """The flags of ``cellcal compensate`` (defaults as the parser's)."""

    targets: str | None = Field(None, alias="TARGETS.csv")
    params: str = Field(alias="--params")
    effect_file: tuple[str, ...] = Field((), alias="--effect-file")
    out: str | None = Field(None, alias="--out")
    start: str | None = Field(None, alias="--start")
    position_only: bool = Field(False, alias="--position-only")
    joints_tolerance_mm: float = Field(JOINTS_TOLERANCE_MM, gt=0, allow_inf_nan=False,
                                       alias="--joints-tolerance-mm")
    export_model: str | None = Field(None, alias="--export-model")
    export_ur: str | None = Field(None, alias="--export-ur")
    export_urdf: str | None = Field(None, alias="--export-urdf")
    export_ur_yaml: str | None = Field(None, alias="--export-ur-yaml")
    export_dh: str | None = Field(None, alias="--export-dh")
    strict_range: bool = Field(False, alias="--strict-range")

    def outputs(self) -> dict[str, str | None]:
        """Every output, by flag."""
        return {"--out": self.out, "--export-model": self.export_model,
                "--export-ur": self.export_ur, "--export-urdf": self.export_urdf,
                "--export-ur-yaml": self.export_ur_yaml, "--export-dh": self.export_dh}


@dataclass
class Compensated:
    """What :func:`compensate_targets` did.

    Attributes
    ----------
    model : the calibration's nominal model (with the capture's tool)
    capture : what the calibration's data said about their capture
    notes : remarks for the user (a far tool, export limits, backlash without directions)
    exports : the files exported (None: none asked)
    targets, result : the targets read and their compensation (None without targets)
    csv_text : the compensated CSV (written to ``--out`` when given)
    thermal : the thermal state compensated for (a model with drift effects:
        :func:`calibration.fit.thermal_state.target_state`), else None
    outside : per target, the quantities beyond the calibrated envelope (``q2``,
        ``joint_temp3``...; empty inside), None without targets
    """

    model: RobotModel
    capture: CaptureMeta
    notes: list[str] = field(default_factory=list)
    exports: Exports | None = None
    targets: Targets | None = None
    result: Compensation | None = None
    csv_text: str | None = None
    thermal: dict | None = None
    outside: list[list[str]] | None = None


def compensate_targets(request: CompensateRequest) -> Compensated:
    """Export the calibrated model and compensate the targets, as ``request`` asks.

    Raises
    ------
    UsageError, calibration.errors.InputError
        Bad input (exit 2); TooLarge: more targets than the memory left holds (exit 3).
    calibration.errors.OutsideEnvelope
        ``--strict-range`` and a target beyond the calibrated envelope (exit 3); nothing
        is written.
    """
    if not request.targets and not any(v for k, v in request.outputs().items()
                                       if k != "--out"):
        raise UsageError("give TARGETS.csv, --export-model, --export-ur, --export-urdf, "
                         "--export-ur-yaml or --export-dh")
    check_outputs(request.outputs(),
                  existing_paths(request.params, request.targets, request.effect_file))
    for f in request.effect_file:
        load_effect_file(f)
    loaded = read_params(request.params)
    em, x = loaded.error_model, loaded.values
    done = Compensated(em.model, capture_of(request.params), notes=_tool_notes(em, x))
    t = start = columns = None
    if request.targets:  # every input checked before anything is written
        t = load_targets(request.targets, em.model)
        check_memory("compensate", "compensate", len(t.base_p_tcp), em.n_params)
        check_joints_reach(t, em.model, request.joints_tolerance_mm, request.targets)
        start = _parse_start(request.start, em.model.n_joints) if request.start else None
        columns, done.thermal = target_state(em, loaded.thermal, t.columns,
                                             len(t.base_p_tcp))
    if request.strict_range and loaded.envelope is None:
        raise UsageError(f"--strict-range: {no_envelope_note(request.params)}")
    c = None
    if t is not None:  # compensated (and checked against the envelope) before any write
        c = compensate(em, x, t.base_p_tcp, t.q, q_start=start,
                       keep_orientation=not request.position_only, columns=columns)
        done.outside = outside_envelope(loaded.envelope, c.q, t.columns)
        if request.strict_range:
            refuse_outside(done.outside, list(t.pose_id), "targets", request.targets)
    done.exports = write_exports(em, x, model_yaml=request.export_model,
                                 ur_conf=request.export_ur, urdf=request.export_urdf,
                                 ur_yaml=request.export_ur_yaml, dh_table=request.export_dh,
                                 known_notes=done.notes)
    if done.exports is not None:
        done.notes += done.exports.notes
    if t is None:
        return done
    if "dirs" not in t.columns and any(e.family == "backlash" for e in em.effects):
        done.notes.append(
            "the calibration has backlash: give dir1..dirN in the targets (the direction "
            "each joint will approach from); without them they are derived from the "
            "targets' order")
    if loaded.envelope is None:
        done.notes.append(no_envelope_note(request.params))
    done.targets, done.result = t, c
    done.csv_text = compensated_csv(t, c, done.outside)
    if request.out:
        write_atomic(request.out, done.csv_text)
    return done


def _tool_notes(em: ErrorModel, x: np.ndarray) -> list[str]:
    """A warning when the calibrated tool is far from the nominal one: a params.json from a
    CSV without the capture's tool (its corrections would include the tool offset)."""
    if "tool.x" not in em.names:
        return []
    k = em.index("tool.x")
    tool, nominal = np.asarray(x[k:k + 3]), em.model.tool_mm()
    if np.linalg.norm(tool - nominal) <= 5.0:
        return []
    return [f"the calibrated tool ({', '.join(f'{v:.1f}' for v in tool)} mm) is "
            f"{np.linalg.norm(tool - nominal):.0f} mm from the nominal tool "
            f"({', '.join(f'{v:g}' for v in nominal)} mm) the controller is assumed to use: "
            "the corrections include that difference. Calibrate from a CSV that `cellcal "
            "export` wrote (its `# tool_mm:` line), or with --model set to the controller's "
            "tool"]


def _parse_start(text: str, n: int) -> np.ndarray:
    """``--start``: n comma-separated angles, deg, as radians."""
    try:
        v = [float(s) for s in text.split(",")]
    except ValueError:
        raise UsageError(f"--start {text!r}: give {n} comma-separated angles in deg") from None
    if len(v) != n or not all(math.isfinite(a) for a in v):
        raise UsageError(f"--start needs {n} finite angles (deg), got {len(v)}")
    return np.radians(v)
