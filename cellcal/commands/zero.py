"""``cellcal zero``: zero-point recalibration from 20 postures on one fixed point.

The postures come from a postures CSV (docs/formats.md §1) or straight from the run
store (``--db cell.db [--run N]``: a ``zero20`` capture, default the latest
completed one; planes from the plan, joints as read, tips as measured).

Two-pass flow of the seed method (a second, fine pass after a manual adjustment)::

    cellcal capture zero20 --target-xyz X,Y,Z ... --db cell.db      # run 1
    cellcal zero --db cell.db --params params.json --json > first_pass.json   # first pass
    # apply first_pass.json's offsets at the controller (its joint zeros)
    cellcal capture zero20 --replay 1 ... --db cell.db              # the same 20 postures
    cellcal zero --db cell.db --params params.json --replay first_pass.json   # fine pass

The fine pass starts from the first pass's offsets and reports what remains to
correct relative to the adjusted controller's readings: about 0 when the
adjustment took.

Exit codes (docs/formats.md §6): 0 the recalibration is decided (within tolerance),
3 the data are too poor to decide (an offset that matters is undetermined, the
uncertainty exceeds the tolerance, the residual is far above the tip scatter, or no
convergence), 2 bad input.
"""

from __future__ import annotations

import json
import math
from pathlib import Path

from ..cli import UsageError, command_parser
from .common import (
    check_outputs,
    fmt,
    input_paths,
    open_store,
    positive_float,
    positive_int,
    print_json,
    print_note,
    seed_int,
    table,
    wrap_errors,
)

#: tip scatter per axis of taught postures, mm (:data:`calibration.zero_point.DEFAULT_SIGMA_MM`,
#: kept equal by tests/cellcal/test_cli_help.py)
DEFAULT_SIGMA_MM = 0.02

_EPILOG = """two-pass flow (seed method: a second, fine pass after a manual adjustment):

  cellcal capture zero20 --target-xyz X,Y,Z ... --db cell.db    # run 1
  cellcal zero --db cell.db --params params.json --json > first_pass.json
  (apply first_pass.json's offsets to the controller's joint zeros)
  cellcal capture zero20 --replay 1 ... --db cell.db            # same postures, loop again
  cellcal zero --db cell.db --params params.json --replay first_pass.json   # remaining ~0
"""


def register(sub) -> None:
    p = command_parser(
        sub, "zero",
        help="recalibrate joint zero offsets from 20 postures on one point",
        description="Estimate joint zero corrections (true = reported + offset) from "
        "postures that all put the tool tip on one fixed point (a zero-point postures CSV, "
        "docs/formats.md §1, or a zero20 run in the store with --db): the published seed "
        "method and a rigorous least-squares method.\n\n"
        "The measured tips make joint 1 and the last joint determinable only in the robot "
        "base frame: give --params from a calibration of the same cell (its base pose); "
        "without it they stay undetermined and, when they matter, the status is poor (exit "
        "3). The nominal tool is the capture's (the run's --tool-mm, or the CSV's `# "
        "tool_mm:` line).\n\n"
        "Exit 0 when decided, 3 when the data are too poor to decide, 2 for bad input "
        "(docs/formats.md §6).",
        epilog=_EPILOG,
    )
    p.add_argument("postures", metavar="POSTURES.csv", nargs="?", default=None,
                   help="zero-point postures CSV (or --db)")
    p.add_argument("--db", metavar="cell.db|URL",
                   help="read the postures from a zero20 run in this run store (a SQLite file "
                   "or a postgresql:// URL) instead of a CSV")
    p.add_argument("--run", type=positive_int, default=None, metavar="N",
                   help="with --db: the zero20 run (default: the latest completed one)")
    p.add_argument("--robot-id", metavar="NAME", default=None,
                   help="with --db: the latest completed zero20 run of this robot")
    p.add_argument("--model", default=None, metavar="NAME|PATH",
                   help="built-in model name or a model YAML file (default: the run's model, "
                   "or the CSV's `# model:` line)")
    p.add_argument("--params", metavar="params.json",
                   help="a calibration of the cell (geometric deltas; its base pose puts the "
                   "measured tips in the robot base frame)")
    p.add_argument("--effect-file", action="append", default=[], metavar="FILE.py",
                   help="load user-defined effects from a Python file (needed when the "
                   "calibration in --params used one; repeatable)")
    p.add_argument("--method", choices=("seed", "rigorous", "both"), default="both",
                   help="seed (published), rigorous, or both compared (default; the "
                   "rigorous result is reported)")
    p.add_argument("--tolerance-deg", type=positive_float, default=0.01, metavar="T",
                   help="a joint changed when |offset| > T; decided when 2 sigma < T "
                   "(default 0.01)")
    p.add_argument("--sigma", type=positive_float, default=DEFAULT_SIGMA_MM, metavar="MM",
                   help=f"tip scatter per axis (teaching repeatability), mm "
                   f"(default {DEFAULT_SIGMA_MM})")
    p.add_argument("--replay", metavar="previous.json",
                   help="fine pass: start from a previous `zero --json` result (after "
                   "applying its offsets at the controller and recapturing the same postures "
                   "with `capture zero20 --replay RUN`, the result is the remaining "
                   "correction, about 0)")
    p.add_argument("--keep-outliers", action="store_true",
                   help="do not leave out postures with improbable residuals")
    p.add_argument("--seed", type=seed_int, default=0,
                   help="random seed of the seed method's resampling (default 0: the same "
                   "result every time)")
    p.add_argument("--out", metavar="FILE",
                   help="write the updated model (.yaml) or params (.json, needs --params); "
                   "never the input file")
    p.add_argument("--json", action="store_true", help="print one JSON object")
    p.set_defaults(func=run)


def _chain(model, params_path):
    """The chain to recalibrate and the base transform (R, t) or None."""
    if model.prismatic_mask() is not None:
        raise UsageError(f"model {model.name} has a prismatic joint: the zero-point "
                         "recalibration handles revolute joints only")
    from calibration.inverse import ChainFK
    from calibration.params_io import read_params

    if not params_path:
        return ChainFK.from_model(model), None
    p = read_params(params_path, model=model)
    for n in p.notes:
        print_note(n)
    em, x = p.error_model, p.values
    c = em.perturb(x)
    tool = c.tool if "tool" in c.applied else model.tool_mm()
    return ChainFK(model.convention, c.table, tool), c.tracker_T_base


def _joints_as_calibrated(params_path, postures, notes: list[str]):
    """The postures with the joints the calibration's joint effects (backlash, compliance,
    ...) make of the readings, so the offsets found are changes of the zeros alone (not
    the backlash of the side the postures were approached from, say). Needs the run's
    approach directions (``--db``); a CSV's postures are used as read, with a note."""
    from calibration.params_io import load_params

    em, x, _ = wrap_errors(lambda: load_params(params_path))
    joint = [e.label for e in em.effects if e.stage == "joint"]
    if not joint:
        return postures
    data = getattr(postures, "data", None)
    if data is None:
        notes.append(f"{params_path} has {', '.join(joint)}: the postures CSV has no approach "
                     "directions, so the offsets include what those effects do at the postures")
        return postures
    q = em.perturb(x, em.bind(data)).q
    out = type(postures)(q, postures.plane, postures.pose_id, base_p_tip=postures.base_p_tip,
                         tracker_p_tip=postures.tracker_p_tip, source=postures.source,
                         lines=postures.lines)
    out.run_id = postures.run_id
    notes.append(f"joints corrected by {', '.join(joint)} of {params_path} (the run's approach "
                 "directions): the offsets are changes of the zeros alone")
    return out


def _replay_start(path, n_joints):
    """The offsets (rad) of a previous ``zero --json`` result: ``offsets_deg`` (null for
    an undetermined joint, read as 0) or ``offsets_rad``; one finite number per joint."""
    import numpy as np

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


def _check_out(args) -> Path:
    check_outputs({"--out": args.out},
                  input_paths(args, "model", "params", "postures", "replay", "db",
                              "effect_file"))
    path = Path(args.out)
    if path.suffix not in (".yaml", ".yml", ".json"):
        raise UsageError(f"--out {args.out}: give a .yaml (model) or .json (params) file")
    return path


def run(args) -> int:
    import numpy as np

    from calibration import load_model
    from calibration.dataset import read_meta
    from calibration.effects import load_effect_file
    from calibration.zero_point import load_postures, rigorous_method, seed_method
    from presentation.summaries import zero_summary

    if (args.postures is None) == (args.db is None):
        raise UsageError("give a postures CSV or --db cell.db (not both)")
    if (args.run is not None or args.robot_id is not None) and args.db is None:
        raise UsageError("--run and --robot-id need --db")
    out = _check_out(args) if args.out else None
    if out is not None and out.suffix == ".json" and not args.params:
        raise UsageError("--out *.json updates a params file: give --params")
    for f in args.effect_file:
        wrap_errors(lambda f=f: load_effect_file(f))
    notes = []
    if args.db is not None:
        from daq.store import display_address

        model, postures = _from_store(args)
        source = f"{display_address(args.db)} run {postures.run_id}"
    else:
        meta = read_meta(args.postures)
        name = args.model or meta.get("model")
        if not name:
            raise UsageError(f"give --model: {args.postures} names no model (no `# model:` "
                             "line)")
        model = wrap_errors(lambda: load_model(name))
        postures = wrap_errors(lambda: load_postures(args.postures, model))
        model = _with_capture_tool(model, meta, args.postures)
        source = args.postures
    fk, base = _chain(model, args.params)
    if args.params:
        postures = _joints_as_calibrated(args.params, postures, notes)
    offsets0 = _replay_start(args.replay, model.n_joints) if args.replay else None
    measured = postures.base_p_tip
    if postures.tracker_p_tip is not None:
        if base is not None:  # the calibrated model's base: tracker_T_base
            measured = postures.tips_in_base(*base).base_p_tip
        else:
            notes.append("measured tips are in the tracker frame and the base pose is unknown "
                         + ("(no base in --params)" if args.params else
                            "(no frame run, no --params)") + ": not used")
    results = {}
    if args.method in ("seed", "both"):
        results["seed"] = seed_method(fk, postures, offsets0=offsets0,
                                      rng=np.random.default_rng(args.seed), sigma_mm=args.sigma)
    if args.method in ("rigorous", "both"):
        results["rigorous"] = rigorous_method(fk, postures, offsets0=offsets0,
                                              measured_base=measured, sigma_mm=args.sigma,
                                              reject_outliers=not args.keep_outliers)
    main = results.get("rigorous", results.get("seed"))
    doc = zero_summary(main, model.name, postures.n, tolerance_deg=args.tolerance_deg,
                  sigma_mm=args.sigma, measured=measured is not None and main.method != "seed")
    if "seed" in results and main is not results["seed"]:
        s = results["seed"]
        sdoc = zero_summary(s, model.name, postures.n, tolerance_deg=args.tolerance_deg,
                       sigma_mm=args.sigma)
        doc["seed"] = {k: sdoc[k] for k in ("offsets_deg", "tool_mm", "target_mm", "rms_mm",
                                            "status", "reasons", "converged", "reason",
                                            "iterations", "solve_s")}
        both = main.determined & s.determined
        diff = np.degrees(np.abs(main.offsets - s.offsets))[both]
        doc["max_difference_deg"] = float(diff.max()) if diff.size else None
    doc["pose_ids"] = postures.pose_id
    doc["residuals_mm"] = [round(float(v), 6) for v in np.linalg.norm(main.residuals, axis=1)]
    doc["source"] = source
    doc["notes"] = notes
    doc["out_file"] = None
    if out is not None and doc["status"] == "ok":
        _write_out(out, model, args.params, main)
        doc["out_file"] = str(out)
    if args.json:
        print_json(doc)
    else:
        _print(doc, main, results, args, out)
    return 0 if doc["status"] == "ok" else 3


def _with_capture_tool(model, meta: dict, source: str):
    """``model`` with the tool the capture recorded (``# tool_mm:``), if any."""
    from calibration.capture_meta import CaptureMeta

    return wrap_errors(lambda: CaptureMeta.from_meta(meta, source)).with_tool(model)


def _from_store(args):
    """(model, postures) of a zero20 run in the store (the model with the run's tool);
    ``postures.run_id`` and ``postures.data`` (the run as a data set) set."""
    import numpy as np

    from calibration import load_model
    from daq.run_data import dataset_from_run, postures_from_run
    from daq.store import StoreError

    try:
        with open_store(args.db, read_only=True) as store:
            # tips stay in the tracker frame when --params gives the base pose
            postures, r = postures_from_run(store, args.run, to_base=not args.params,
                                            robot_id=args.robot_id)
            data = dataset_from_run(store, r.id)  # approach directions, temperature
    except StoreError as e:
        raise UsageError(str(e)) from None
    if r.context.acquire.get("approach_rad", 0) > 0:
        # the closed loop approached every posture from below on every joint: the
        # executor's recorded directions are those of its move into the posture
        data.dirs = np.ones_like(data.q, dtype=int)
    postures.data = data
    name = args.model or r.model
    if not name:
        raise UsageError(f"run {r.id} records no model: give --model")
    model = wrap_errors(lambda: load_model(name))
    if r.context.tool_mm is not None:
        model = model.with_changes(tool=tuple(float(v) for v in r.context.tool_mm))
    if postures.q.shape[1] != model.n_joints:
        raise UsageError(f"run {r.id} has {postures.q.shape[1]} joints, model {model.name} "
                         f"has {model.n_joints}")
    postures.run_id = r.id
    return model, postures


def _write_out(out: Path, model, params_path, result) -> None:
    import numpy as np

    from calibration.files import read_text, write_atomic

    off = np.where(result.determined, result.offsets, 0.0)
    if out.suffix == ".json":
        doc = json.loads(read_text(params_path, UsageError, "params file"))
        rows = {r["name"]: r for r in doc["parameters"]}
        for j, v in enumerate(off):
            name = f"geometric.j{j + 1}.theta"
            if name not in rows:
                raise UsageError(f"{params_path}: no parameter {name} (no geometric effect); "
                                 "write a model YAML instead")
            rows[name]["value"] = rows[name]["value"] + math.degrees(v)
        doc.setdefault("history", []).append(
            {"zero_point": {"offsets_deg": [math.degrees(v) for v in off]}})
        write_atomic(out, json.dumps(doc, indent=1) + "\n")
        return
    joints = [j.model_dump() for j in model.joints]
    for j, v in enumerate(off):
        joints[j]["theta_offset"] = joints[j]["theta_offset"] + math.degrees(v)
    write_atomic(out, model.with_changes(joints=joints).to_yaml())


def _print(doc, main, results, args, out) -> None:
    print(f"postures  {doc['source']}: {doc['n_poses']} postures; model {doc['model']}")
    for name, r in results.items():
        print(f"{name:9s} {r.reason}; rms {r.rms_mm:.4f} mm; {r.solve_s * 1000:.1f} ms")
    if main.outliers:
        print(f"outliers  {', '.join(main.outliers)} (left out)")
    print()
    rows = []
    seed = results.get("seed")
    for j in range(len(main.offsets)):
        det = bool(main.determined[j])
        rows.append([
            f"j{j + 1}",
            fmt(math.degrees(main.offsets[j]), 4) if det else "undetermined",
            fmt(math.degrees(main.std[j]), 4) if det else "-",
            fmt(math.degrees(seed.offsets[j]), 4) if seed is not None and det else "-",
            "yes" if f"j{j + 1}" in doc["changed"] else "",
        ])
    print(table(rows, ["joint", "offset deg", "std deg", "seed deg", "changed"]))
    print()
    print(f"tool      {', '.join(f'{v:.3f}' for v in main.tool)} mm (flange frame)")
    print(f"target    {', '.join(f'{v:.3f}' for v in main.target)} mm (base frame)")
    for name, why in main.fixed.items():
        print(f"note      {name}: {why}")
    for why in doc["notes"]:
        print(f"note      {why}")
    print(f"status    {doc['status']}" + (": " + "; ".join(doc["reasons"]) if doc["reasons"]
                                           else ""))
    if out is not None:
        print(f"written   {out}" if doc["out_file"] else f"not written ({out}): status poor")
