"""Model export (not the run export of ``cellcal export``): a calibrated model as the model
YAML (docs/formats.md §2) with the geometric deltas folded into the table and the identified
tool as ``tool``, and UR ``calibration.conf`` deltas (exact conversion to pure DH, see
:mod:`calibration.exports.ur_conf`). The effects are applied by
:meth:`~calibration.fit.error_model.ErrorModel.perturb`.

Only the robot's own kinematics go into these files: the base (the robot in the
tracker frame) is a property of the cell, and effects that are not fixed kinematic
parameters (compliance, harmonics, thermal...) cannot be expressed by a DH table;
they are named in the notes that the export functions return.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import numpy as np

from ..files import write_atomic
from ..fit.error_model import ErrorModel
from ..model.dh_conversion import urdf_rpy
from ..model.robot_model import RobotModel
from ..model.transforms import rotvec_to_matrix
from .ur_conf import deltas_from_table, format_calibration_conf, model_from_table


def calibrated_table(error_model: ErrorModel,
                     x: np.ndarray) -> tuple[np.ndarray, np.ndarray, list[str]]:
    """The calibrated chain as a table and a tool.

    Returns
    -------
    table : (N, 5) theta_offset, d, a, alpha, beta (rad, mm), nominal + geometric deltas
    tool : (3,) tool point in the flange frame, mm (identified, else nominal)
    notes : effects that are not part of the table (named, with why)
    """
    c = error_model.perturb(x)
    notes = []
    for e in error_model.effects:
        if e.stage == "base":
            notes.append("base: the robot's pose in the tracker frame is not part of the model")
        elif e.stage == "target":
            notes.append(f"{e.label}: the tool frame's orientation in the flange is written "
                         "as the model YAML's tool_rpy_deg and the URDF's tcp_joint rpy; a UR "
                         "controller takes its TCP (position and orientation) from the "
                         "installation, not from calibration.conf or the kinematics YAML")
        elif e.stage not in ("table", "tool"):
            notes.append(f"{e.label}: not a fixed kinematic parameter, not exported")
    table, tool = c.table, np.asarray(c.tool, float)
    return table, tool, notes


def calibrated_tool_rpy_deg(error_model: ErrorModel,
                            x: np.ndarray) -> tuple[float, ...] | None:
    """The identified tool frame's orientation in the flange frame as URDF roll, pitch,
    yaw (deg; ``tool_rotation``'s ``flange_R_target``), None without that effect."""
    for e, sl in zip(error_model.effects, error_model.slices, strict=True):
        if e.stage == "target":
            return tuple(float(v) for v in np.degrees(urdf_rpy(rotvec_to_matrix(x[sl]))))
    return None


def calibrated_model(error_model: ErrorModel, x: np.ndarray,
                     name: str | None = None) -> tuple[RobotModel, list[str]]:
    """(RobotModel, notes): the nominal model with the calibrated table and tool (its
    point, and its orientation when ``tool_rotation`` was identified)."""
    table, tool, notes = calibrated_table(error_model, x)
    m = model_from_table(error_model.model, table, tool=tool,
                         name=name or f"{error_model.model.name}_calibrated")
    rpy = calibrated_tool_rpy_deg(error_model, x)
    if rpy is not None:
        m = m.with_changes(tool_rpy_deg=rpy)
    return m, notes


def write_model_yaml(model: RobotModel, path: str | Path, notes: Sequence[str] = ()) -> None:
    """Write a model YAML with a comment header (the notes)."""
    head = "".join(f"# {n}\n" for n in ["calibrated model exported by cellcal", *notes])
    write_atomic(path, head + model.to_yaml())


def ur_deltas(error_model: ErrorModel, x: np.ndarray, nominal: RobotModel | None = None
              ) -> tuple[dict[str, np.ndarray], list[str]]:
    """(deltas, notes): UR calibration.conf deltas (rad, m) of the calibrated chain.

    ``nominal`` is the controller's nominal model (default: the error model's own, which
    must be pure standard DH).
    """
    nominal = nominal or error_model.model
    if error_model.model.convention != "dh" or nominal.convention != "dh":
        raise ValueError("UR deltas need a standard-DH (convention: dh) model")
    table, _, notes = calibrated_table(error_model, x)
    nominal_table = nominal.dh_table()
    if error_model.model.urdf is not None:  # a URDF's own frames: as the controller's DH
        from .controller_export import ur_table

        table = ur_table(calibrated_model(error_model, x)[0])[0]
        nominal_table = ur_table(nominal)[0]
    return deltas_from_table(table, nominal_table), notes


def write_ur_conf(error_model: ErrorModel, x: np.ndarray, path: str | Path,
                  nominal: RobotModel | None = None) -> list[str]:
    deltas, notes = ur_deltas(error_model, x, nominal)
    head = "".join(f"# {n}\n" for n in notes)
    write_atomic(path, head + format_calibration_conf(deltas))
    return notes
