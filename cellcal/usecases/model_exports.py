"""The file exports of ``compensate``: the calibrated model as a model YAML, UR
calibration.conf deltas, a URDF, the UR ROS driver's kinematics YAML and the DH/MDH table
as CSV, and the parity check of each: the written file is read back and its forward
kinematics compared with the calibrated model at 1000 random joint sets
(:func:`write_exports`)."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from calibration import ErrorModel
from calibration.exports.controller_export import (
    ExportError,
    ur_conf_parity,
    write_table_csv,
    write_ur_kinematics_yaml,
)
from calibration.exports.model_export import calibrated_model, write_model_yaml, write_ur_conf
from calibration.exports.parity import Parity, model_file_parity
from calibration.exports.urdf_export import mount_note, write_urdf

from ..errors import UsageError


@dataclass(frozen=True)
class ExportedFile:
    """A file written and its parity check; ``key`` names it in the JSON object
    (``model_file``, ``ur_conf_file``, ``urdf_file``, ``ur_yaml_file``, ``table_file``)."""

    key: str
    path: str
    parity: Parity


@dataclass
class Exports:
    """What :func:`write_exports` wrote: the files (in the order checked), the notes for
    the user (``notes``) and what the calibrated model holds that no file can
    (``not_exported``)."""

    files: list[ExportedFile] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)
    not_exported: list[str] = field(default_factory=list)


def write_exports(em: ErrorModel, x: np.ndarray, *, model_yaml: str | None = None,
                  ur_conf: str | None = None, urdf: str | None = None,
                  ur_yaml: str | None = None, dh_table: str | None = None,
                  known_notes: list[str] = ()) -> Exports | None:
    """Write the asked exports of the calibrated model (``em`` at ``x``) and check every
    one; None when none was asked. ``known_notes``: notes the user gets anyway (a UR note
    already among them is not repeated).

    Raises
    ------
    UsageError
        A model the asked format cannot hold (the message says why).
    """
    if not (model_yaml or ur_conf or urdf or ur_yaml or dh_table):
        return None
    out = Exports()
    if model_yaml:
        m, notes = calibrated_model(em, x)
        write_model_yaml(m, model_yaml, notes)
        out.notes += notes
    if ur_conf:
        try:
            notes = write_ur_conf(em, x, ur_conf)
        except ValueError as e:
            raise UsageError(str(e)) from None
        seen = [*known_notes, *out.notes]
        out.notes += [n for n in notes if n not in seen]
    model, notes = calibrated_model(em, x)
    file_notes = notes + mount_note(model)
    try:
        if urdf:
            out.files.append(ExportedFile("urdf_file", urdf,
                                          write_urdf(model, urdf, file_notes)))
        if ur_yaml:
            out.files.append(ExportedFile("ur_yaml_file", ur_yaml,
                                          write_ur_kinematics_yaml(model, ur_yaml, file_notes)))
        if dh_table:
            out.files.append(ExportedFile("table_file", dh_table,
                                          write_table_csv(model, dh_table, file_notes)))
        if model_yaml:
            out.files.append(ExportedFile("model_file", model_yaml,
                                          model_file_parity(model_yaml, model)))
        if ur_conf:
            out.files.append(ExportedFile("ur_conf_file", ur_conf,
                                          ur_conf_parity(ur_conf, model, em.model)))
    except ExportError as e:
        raise UsageError(str(e)) from None
    out.not_exported = notes
    return out

