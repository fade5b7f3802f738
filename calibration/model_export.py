"""Model export (not the run export of ``cellcal export``): a calibrated model as the model
YAML (docs/formats.md §2) with the geometric deltas folded into the table and the identified
tool as ``tool``, and UR ``calibration.conf`` deltas (exact conversion to pure DH, see
:mod:`calibration.ur_conf`). The effects are applied by
:meth:`~calibration.error_model.ErrorModel.perturb`.

Only the robot's own kinematics go into these files: the base (the robot in the
tracker frame) is a property of the cell, and effects that are not fixed kinematic
parameters (compliance, harmonics, thermal...) cannot be expressed by a DH table;
they are named in the notes that the export functions return.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from .error_model import ErrorModel
from .files import write_atomic
from .robot_model import RobotModel
from .ur_conf import deltas_from_table, format_calibration_conf, model_from_table


def calibrated_table(error_model: ErrorModel, x: np.ndarray):
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
            notes.append(f"{e.label}: the 6-DoF target's orientation in the flange is not "
                         "part of the model files (params.json keeps it)")
        elif e.stage not in ("table", "tool"):
            notes.append(f"{e.label}: not a fixed kinematic parameter, not exported")
    table, tool = c.table, np.asarray(c.tool, float)
    return table, tool, notes


def calibrated_model(error_model: ErrorModel, x: np.ndarray, name: str | None = None):
    """(RobotModel, notes): the nominal model with the calibrated table and tool."""
    table, tool, notes = calibrated_table(error_model, x)
    m = model_from_table(error_model.model, table, tool=tool,
                         name=name or f"{error_model.model.name}_calibrated")
    return m, notes


def write_model_yaml(model: RobotModel, path: str | Path, notes: list[str] = ()) -> None:
    """Write a model YAML with a comment header (the notes)."""
    head = "".join(f"# {n}\n" for n in ["calibrated model exported by cellcal", *notes])
    write_atomic(path, head + model.to_yaml())


def ur_deltas(error_model: ErrorModel, x: np.ndarray, nominal: RobotModel | None = None):
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
