"""The file exports of ``cellcal compensate`` beyond the model YAML: a calibrated URDF, the
UR ROS driver's kinematics YAML, the DH/MDH table as CSV, and the parity check of each
(and of ``--export-model`` and ``--export-ur``): the written file is read back and its
forward kinematics compared with the calibrated model at 1000 random joint sets."""

from __future__ import annotations

from pathlib import Path

from ..cli import UsageError

#: (option dest, JSON key) of the outputs this module writes
OUTPUTS = (("export_urdf", "urdf_file"), ("export_ur_yaml", "ur_yaml_file"),
           ("export_dh", "table_file"))


def add_export_args(p) -> None:
    p.add_argument("--export-urdf", metavar="FILE.urdf",
                   help="write the calibrated kinematics as a URDF ending in a link 'tcp' at "
                   "the measured point (checked by loading it with yourdfpy)")
    p.add_argument("--export-ur-yaml", metavar="FILE.yaml",
                   help="write the UR ROS driver's kinematics YAML (ur_description "
                   "kinematics_params_file, with its hash)")
    p.add_argument("--export-dh", metavar="FILE.csv",
                   help="write the calibrated DH/MDH table as CSV (units in the header)")


def output_paths(args) -> list[str]:
    return [getattr(args, dest) for dest, _ in OUTPUTS if getattr(args, dest, None)]


def run_exports(args, em, x, doc: dict) -> list[str]:
    """Write the asked exports and check every one; returns the lines to print and fills
    ``doc`` (``*_file`` keys, ``parity`` list, ``not_exported``)."""
    if not (output_paths(args) or args.export_ur or args.export_model):
        return []
    from calibration.controller_export import (
        ExportError,
        ur_conf_parity,
        write_table_csv,
        write_ur_kinematics_yaml,
    )
    from calibration.model_export import calibrated_model
    from calibration.parity import model_file_parity
    from calibration.urdf_export import mount_note, write_urdf

    model, notes = calibrated_model(em, x)
    file_notes = notes + mount_note(model)
    checks = []
    try:
        if args.export_urdf:
            checks.append(("urdf_file", args.export_urdf,
                           write_urdf(model, args.export_urdf, file_notes)))
        if args.export_ur_yaml:
            checks.append(("ur_yaml_file", args.export_ur_yaml,
                           write_ur_kinematics_yaml(model, args.export_ur_yaml, file_notes)))
        if args.export_dh:
            checks.append(("table_file", args.export_dh,
                           write_table_csv(model, args.export_dh, file_notes)))
        if args.export_model:  # written by the caller; its parity here
            checks.append(("model_file", args.export_model,
                           model_file_parity(args.export_model, model)))
        if args.export_ur:  # written by the caller; its parity here
            checks.append(("ur_conf_file", args.export_ur,
                           ur_conf_parity(args.export_ur, model, em.model)))
    except ExportError as e:
        raise UsageError(str(e)) from None
    lines = []
    for key, path, parity in checks:
        doc[key] = str(Path(path))
        lines.append(f"written   {path}")
        lines.append(parity.line())
    doc["parity"] = [p.as_dict() for _, _, p in checks]
    doc["not_exported"] = notes
    lines += [f"not exported: {n}" for n in notes]
    return lines
