"""``cellcal compensate``: joints and corrected Cartesian targets that make the real robot
reach target points, from a calibration (params.json); exports of the calibrated model."""

from __future__ import annotations

import csv
import io
import math
import sys

from ..cli import UsageError, command_parser
from .common import check_outputs, fmt, input_paths, print_json, wrap_errors
from .compensate_exports import OUTPUTS, add_export_args, output_paths, run_exports


def register(sub) -> None:
    p = command_parser(
        sub, "compensate",
        help="compensate target points with a calibrated model",
        description="For target points of the tool in the robot base frame (CSV: x, y, z "
        "in mm required; optional pose_id, q1..qN nominal joints in deg, dir1..dirN "
        "approach directions, temp_c, payload_kg) compute the joints that reach them on "
        "the real robot and the corrected Cartesian targets (nominal FK of those joints) "
        "for a controller that only knows its nominal model. The nominal model is the "
        "calibration's, with the capture's tool (the controller's TCP). Optionally export "
        "the calibrated model (YAML) or UR deltas.\n\n"
        "Targets without nominal joints get them by inverse kinematics on the nominal "
        "model, from --start (default: a few standard postures, the first that reaches "
        "wins). Exit 0 when every target is reached, 1 otherwise, 2 for bad input "
        "(docs/formats.md §6).",
    )
    p.add_argument("targets", metavar="TARGETS.csv", nargs="?",
                   help="target points (omit to only export)")
    p.add_argument("--params", required=True, metavar="params.json",
                   help="the calibration (`cellcal calibrate --out`)")
    p.add_argument("--effect-file", action="append", default=[], metavar="FILE.py",
                   help="load user-defined effects from a Python file (needed when the "
                   "calibration used one; repeatable)")
    p.add_argument("--out", metavar="compensated.csv",
                   help="write the compensated targets (default: print them)")
    p.add_argument("--start", metavar="Q1,..,QN",
                   help="start configuration (deg) for targets without nominal joints")
    p.add_argument("--position-only", action="store_true",
                   help="minimum-norm position correction; do not hold the nominal "
                   "orientation")
    p.add_argument("--export-model", metavar="FILE.yaml",
                   help="write the calibrated kinematics as a model YAML")
    p.add_argument("--export-ur", metavar="calibration.conf",
                   help="write UR calibration.conf deltas (standard-DH models)")
    add_export_args(p)
    p.add_argument("--json", action="store_true", help="print one JSON object")
    p.set_defaults(func=run)


def _tool_notes(em, x, capture) -> list[str]:
    """A warning when the calibrated tool is far from the nominal one: a params.json from a
    CSV without the capture's tool (its corrections would include the tool offset)."""
    import numpy as np

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


def _parse_start(text, n):
    import numpy as np

    try:
        v = [float(s) for s in text.split(",")]
    except ValueError:
        raise UsageError(f"--start {text!r}: give {n} comma-separated angles in deg") from None
    if len(v) != n or not all(math.isfinite(a) for a in v):
        raise UsageError(f"--start needs {n} finite angles (deg), got {len(v)}")
    return np.radians(v)


def run(args) -> int:
    from calibration.compensation import compensate, load_targets
    from calibration.effects import load_effect_file
    from calibration.files import write_atomic
    from calibration.model_export import calibrated_model, write_model_yaml, write_ur_conf
    from calibration.params_io import capture_of, load_params

    if not args.targets and not (args.export_model or args.export_ur or output_paths(args)):
        raise UsageError("give TARGETS.csv, --export-model, --export-ur, --export-urdf, "
                         "--export-ur-yaml or --export-dh")
    check_outputs({"--out": args.out, "--export-model": args.export_model,
                   "--export-ur": args.export_ur,
                   **{"--" + dest.replace("_", "-"): getattr(args, dest, None)
                      for dest, _ in OUTPUTS}},
                  input_paths(args, "params", "targets", "effect_file"))
    for f in args.effect_file:
        wrap_errors(lambda f=f: load_effect_file(f))
    em, x, _ = wrap_errors(lambda: load_params(args.params))
    model = em.model
    capture = capture_of(args.params)
    doc = {"params_file": args.params, "model": model.name, "tool_mm": list(model.tool),
           "capture": capture.to_json() if capture.known else None,
           "notes": _tool_notes(em, x, capture)}
    if args.export_model:
        m, notes = calibrated_model(em, x)
        write_model_yaml(m, args.export_model, notes)
        doc["model_file"] = args.export_model
        doc["notes"] += notes
    if args.export_ur:
        try:
            notes = write_ur_conf(em, x, args.export_ur)
        except ValueError as e:
            raise UsageError(str(e)) from None
        doc["ur_conf_file"] = args.export_ur
        doc["notes"] += [n for n in notes if n not in doc["notes"]]
    export_lines = run_exports(args, em, x, doc)
    rc = 0
    if args.targets:
        t = wrap_errors(lambda: load_targets(args.targets, model))
        if "dirs" not in t.columns and any(e.family == "backlash" for e in em.effects):
            doc["notes"].append(
                "the calibration has backlash: give dir1..dirN in the targets (the direction "
                "each joint will approach from); without them they are derived from the "
                "targets' order")
        start = _parse_start(args.start, model.n_joints) if args.start else None
        c = compensate(em, x, t.base_p_tcp, t.q, q_start=start,
                       keep_orientation=not args.position_only, columns=t.columns)
        text = _csv(t, c)
        if args.out:
            write_atomic(args.out, text)
        doc.update({
            "n_targets": len(t.base_p_tcp),
            "n_reached": int(c.success.sum()),
            "n_orientation_kept": int(c.orientation_kept.sum()),
            "nominal_joints": "given" if t.q is not None else "computed",
            "correction_mm": {"mean": float(c.correction_mm.mean()),
                              "max": float(c.correction_mm.max())},
            "residual_mm_max": float(c.residual_mm.max()),
            "iterations": c.iterations,
            "reason": c.reason,
            "out_file": args.out,
        })
        rc = 0 if c.success.all() else 1
        if not args.json:
            where = (f" (capture run {capture.run}"
                     + (f" of {capture.store})" if capture.store else ")")
                     if capture.run is not None else "")
            print(f"model     {model.name}, tool {', '.join(f'{v:g}' for v in model.tool)} "
                  f"mm{where}")
            print(f"targets   {args.targets}: {len(t.base_p_tcp)}, reached "
                  f"{int(c.success.sum())}, orientation held {int(c.orientation_kept.sum())}")
            print(f"solver    {c.reason}; {c.iterations} iterations")
            print(f"correction of the Cartesian targets: mean {fmt(c.correction_mm.mean())} mm, "
                  f"max {fmt(c.correction_mm.max())} mm")
            for note in doc["notes"]:
                print(f"note      {note}")
            if args.out:
                print(f"written   {args.out}")
            else:
                print(text, end="")
    if args.json:
        print_json(doc)
    else:
        # beside compensated targets on stdout, the export report goes to stderr
        for line in export_lines:
            print(line, file=sys.stderr if args.targets and not args.out else sys.stdout)
    return rc


def _csv(t, c) -> str:
    import numpy as np

    from calibration.transforms import matrix_to_rotvec

    N = c.q.shape[1]
    head = (["pose_id", "x", "y", "z"] + [f"q{j + 1}" for j in range(N)]
            + ["cmd_x", "cmd_y", "cmd_z", "cmd_rx", "cmd_ry", "cmd_rz"]
            + [f"nom_q{j + 1}" for j in range(N)] + ["correction_mm", "residual_mm", "ok"])
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(head)
    qd, nd = np.degrees(c.q), np.degrees(c.q_nominal)
    for i in range(len(c.q)):
        rv = np.degrees(matrix_to_rotvec(c.cmd_R[i]))
        row = ([t.pose_id[i]] + list(c.target[i]) + list(qd[i]) + list(c.cmd_point[i])
               + list(rv) + list(nd[i]) + [c.correction_mm[i], c.residual_mm[i]])
        w.writerow([r if isinstance(r, str) else repr(float(r)) for r in row]
                   + [int(c.success[i])])
    return buf.getvalue()
