"""``cellcal calibrate``: identify a robot's error parameters from a measurement CSV."""

from __future__ import annotations

import contextlib
from pathlib import Path

from ..cli import UsageError, command_parser
from .choices import DEFAULT_EFFECTS, OUTLIER_MODES, SOLVERS, solver_help
from .common import (
    add_model_args,
    bounded_int,
    check_data,
    check_outputs,
    error_model_of,
    fmt,
    input_paths,
    load_inputs,
    print_json,
    print_note,
    print_outliers,
    seed_int,
    table,
    tool_text,
    wrap_errors,
)


def register(sub) -> None:
    p = command_parser(
        sub, "calibrate",
        help="identify error parameters from measured poses",
        description="Fit the robot's error model to a measurement CSV and report the "
        "parameters, their uncertainties and the remaining error, on the calibration rows "
        "and on the validation rows (set=valid, or --valid FILE).\n\n"
        "The nominal tool is the capture's (the CSV's `# tool_mm:` line, written by "
        "`cellcal export` from the capture's --tool-mm), so params.json describes the "
        "robot as its controller knows it; --out keeps the capture's metadata with the "
        "parameters (params.json `capture`). Exit 0 converged, 1 not converged, 2 bad "
        "input, 3 data too poor to fit (docs/formats.md §6).",
    )
    add_model_args(p)
    p.add_argument("--effects", default=DEFAULT_EFFECTS, metavar="LIST",
                   help=f"comma-separated effects (default {DEFAULT_EFFECTS}; names in "
                   "docs/formats.md §3, e.g. geometric,base,tool,compliance:2)")
    p.add_argument("--solver", default="lm", choices=list(SOLVERS), metavar="SOLVER",
                   help=solver_help())
    p.add_argument("--valid", metavar="FILE", help="validation CSV (besides set=valid rows)")
    p.add_argument("--params", metavar="params.json",
                   help="start from these parameters (those of the same name)")
    p.add_argument("--out", metavar="params.json", help="write the parameters here")
    p.add_argument("--seed", type=seed_int, default=None,
                   help="random seed of the besa/sa solvers and of --monte-carlo (default 0)")
    p.add_argument("--monte-carlo", type=bounded_int(0, 100_000), default=0, metavar="N",
                   help="re-identify N times from the calibrated model plus instrument noise "
                   "(sigma from the data or --sigma) and report the parameter spread and the "
                   "position uncertainty over the workspace")
    p.add_argument("--outliers", choices=OUTLIER_MODES, default="exclude",
                   help="measurements far out of line with the rest (blunders): exclude them "
                   "from the fit and name them (default), flag: fit every point but name "
                   "them, keep: fit every point, no test")
    p.add_argument("--ridge-plot", metavar="FILE.png",
                   help="with --solver ridge: save the L-curve, GCV and ridge trace here")
    p.add_argument("--db", metavar="cell.db|URL",
                   help="record the calibration (its params.json) in this run store, a SQLite "
                   "file or a postgresql:// URL, for `cellcal history` (needs --robot-id "
                   "unless the data name their robot)")
    p.add_argument("--robot-id", metavar="NAME",
                   help="the robot calibrated (default with --db: the robot_id the data were "
                   "exported with)")
    p.set_defaults(func=run)


def check_calibrate_outputs(args) -> None:
    """--out and --ridge-plot: never an input, a run store, a directory (exit 2)."""
    check_outputs({"--out": args.out, "--ridge-plot": getattr(args, "ridge_plot", None)},
                  input_paths(args, "data", "valid", "params", "model", "effect_file"))


def calibrate(args):
    """Run a calibration from parsed arguments; returns (fit, baseline fit)."""
    import numpy as np

    from calibration import identify, load_csv
    from calibration.params_io import read_params
    from calibration.workflow import fit_uncalibrated

    model, data = load_inputs(args)
    em = error_model_of(model, args.effects)
    valid = wrap_errors(lambda: load_csv(args.valid, model)) if args.valid else None
    x0 = None
    notes = []
    if args.params:
        start = read_params(args.params, model=model)
        notes += start.notes
    notes += check_data(em, data)
    if args.params:
        x0 = em.initial(em.bind(data.calib() if data.is_valid.any() else data))
        for k, name in enumerate(start.error_model.names):
            if name in em.names:
                x0[em.index(name)] = start.values[k]
    for n in notes:
        print_note(n)
    opts = {}
    if getattr(args, "seed", None) is not None and args.solver in ("besa", "sa", "besa+lm"):
        opts["seed"] = args.seed
    fit = wrap_errors(lambda: identify(em, data, args.solver, valid=valid, x0=x0,
                                       solver_options=opts or None,
                                       outliers=getattr(args, "outliers", "exclude")))
    # the uncalibrated reference on the same points (without the blunders the fit left out)
    if fit.outliers is not None and fit.outliers.excluded:
        data = data.subset(~np.isin(data.pose_id, fit.outliers.ids))
    baseline = fit_uncalibrated(model, data, valid=valid, outliers="keep")
    return fit, baseline


def run(args) -> int:
    ridge_plot = getattr(args, "ridge_plot", None)
    if ridge_plot and args.solver != "ridge":
        raise UsageError("--ridge-plot needs --solver ridge")
    n_mc = getattr(args, "monte_carlo", 0) or 0
    if n_mc and n_mc < 2:
        raise UsageError("--monte-carlo needs N >= 2")
    if getattr(args, "robot_id", None) and not getattr(args, "db", None):
        raise UsageError("--robot-id needs --db (where the calibration is recorded)")
    check_calibrate_outputs(args)
    store = _open_history_store(args) if getattr(args, "db", None) else None
    try:
        fit, baseline = calibrate(args)
        recorded = _record(store, args, fit) if store is not None else None
    finally:
        if store is not None:
            store.close()
    return _report(args, fit, baseline, ridge_plot, n_mc, recorded)


def _open_history_store(args):
    from daq.store import StoreError, open_store

    try:
        return open_store(args.db)
    except (StoreError, OSError) as e:
        raise UsageError(str(e)) from None


def _record(store, args, fit) -> dict | None:
    """Record the calibration in the store: ``{"id", "robot_id", "new", "db"}``, or None
    for a fit that did not converge (not recorded). Its time is when the data were
    measured (the latest ``t_s``, when those are epoch times), else now."""
    import numpy as np

    from calibration.params_io import fit_to_dict
    from daq.store import StoreError

    data = fit.data
    robot_id = args.robot_id or data.meta.get("robot_id")
    if not robot_id:
        raise UsageError(f"{args.data}: the data name no robot: give --robot-id")
    if not fit.converged:
        return None
    t = None
    if data.t_s is not None and np.isfinite(data.t_s).any() and np.nanmax(data.t_s) > 1e9:
        t = float(np.nanmax(data.t_s))  # epoch times (not seconds from a start)
    source_run = None
    if data.meta.get("run", "").isdigit():  # exported from a run: of this store?
        with contextlib.suppress(StoreError):
            run = store.run(int(data.meta["run"]))
            if run.plan_hash == data.meta.get("plan_hash"):
                source_run = run.id
    cal_id, new = store.add_calibration(
        robot_id, fit_to_dict(fit, args.effect_file, capture=data.capture), t=t,
        source_file=str(Path(args.data).resolve()), source_run=source_run)
    return {"id": cal_id, "robot_id": robot_id, "new": new, "db": store.address}


def _report(args, fit, baseline, ridge_plot, n_mc, recorded) -> int:
    from calibration.params_io import params_by_name, save_params, solver_summary
    from calibration.uncertainty import correlations, monte_carlo
    from presentation.summaries import fit_summary

    if ridge_plot:
        from presentation.ridge_plot import plot_ridge

        plot_ridge(fit.info, ridge_plot, f"{fit.data.source}: ridge solver")
    mc = None
    if n_mc:
        seed = args.seed if getattr(args, "seed", None) is not None else 0
        mc = monte_carlo(fit, n_mc, seed=seed)
    if args.out:
        save_params(fit, args.out, args.effect_file, capture=fit.data.capture)
    if args.json:
        out = fit_summary(fit)
        out["params_file"] = args.out
        out["params"] = params_by_name(fit)
        out["weakly_identified"] = fit.weakly_identified()
        out["outliers"] = fit.outliers.to_json() if fit.outliers else []
        if fit.outliers:
            out["outlier_check"] = fit.outliers.check_json()
        out["uncalibrated"] = {"calib": baseline.calib, "valid": baseline.valid}
        out["strongest_correlations"] = correlations(fit)["strongest"]
        info = solver_summary(fit)
        if info:
            out["solver_info"] = info
        if mc is not None:
            out["monte_carlo"] = mc_summary(mc, fit)
        if ridge_plot:
            out["ridge_plot"] = ridge_plot
        if getattr(args, "db", None):
            out["calibration"] = recorded
        print_json(out)
        return 0 if fit.converged else 1
    print_report(fit, baseline, args.out, mc, ridge_plot)
    if getattr(args, "db", None):
        print()
        if recorded is None:
            print(f"not recorded in {args.db}: the fit did not converge")
        else:
            print(f"{'recorded' if recorded['new'] else 'already recorded'} as calibration "
                  f"{recorded['id']} of robot {recorded['robot_id']} in {recorded['db']}")
    return 0 if fit.converged else 1


def mc_summary(mc, fit) -> dict:
    """The ``monte_carlo`` object of ``calibrate --json``."""
    return {
        "n": int(mc.samples.shape[0]), "sigma_mm": mc.sigma_mm, "n_failed": mc.n_failed,
        "parameters": mc.rows(fit),
        "position_uncertainty_mm": {k: mc.position[k] for k in ("mean_mm", "max_mm")},
        "position_uncertainty_mc_mm": {k: mc.position_mc[k] for k in ("mean_mm", "max_mm")},
    }


def print_report(fit, baseline, out_path=None, mc=None, ridge_plot=None) -> None:
    from calibration.uncertainty import correlations
    from calibration.workflow import UNCALIBRATED_LABEL

    em = fit.error_model
    d = fit.data
    left_out = len(fit.outliers.blunders) if fit.outliers and fit.outliers.excluded else 0
    print(f"data      {d.source}: {d.n + left_out} calibration poses"
          + (f" ({left_out} left out as blunders)" if left_out else "")
          + (f", {fit.valid['n']} validation poses" if fit.valid else ""))
    print(f"model     {em.model.name} ({em.model.convention}), {tool_text(em.model, d)}, "
          f"effects {','.join(em.labels)}")
    ident = fit.identifiability
    print(f"params    {em.n_params}, identifiable {ident.n_identifiable}; "
          f"condition number {ident.condition_number:.3g}, "
          f"observability index {ident.observability_index:.3g}")
    print(f"solver    {fit.solver}: {'converged' if fit.converged else 'NOT converged'} "
          f"({fit.reason}) after {fit.iterations} iterations, {fit.solve_s * 1000:.1f} ms")
    for note in fit.notes:
        print(f"note      {note}")
    print_outliers(fit.outliers)
    print()
    rows = []
    for label, f in ((UNCALIBRATED_LABEL, baseline), ("calibrated", fit)):
        for part in ("calib", "valid"):
            s = getattr(f, part)
            if s:
                rows.append([f"{label}, {part}", s["n"], fmt(s["rms_mm"]), fmt(s["mean_mm"]),
                             fmt(s["p95_mm"]), fmt(s["max_mm"])])
    print(table(rows, ["position error", "n", "rms mm", "mean mm", "p95 mm", "max mm"]))
    floor = fit.noise_floor_mm
    if floor:
        ref = fit.valid or fit.calib
        print(f"noise floor sqrt(3)*sigma = {floor:.4f} mm; "
              f"{'validation' if fit.valid else 'calibration'} RMS is "
              f"{ref['rms_mm'] / floor:.2f} x the floor")
    print()
    rows = []
    for r in fit.parameter_rows():
        std = "fixed" if not r["identifiable"] else fmt(r["std"], 4)
        rows.append([r["name"], fmt(r["value"], 4), std, r["unit"],
                     f"weak: {r['weak']}" if r["weak"] else ""])
    print(table(rows, ["parameter", "value", "std", "unit", "note"], left=(0, 4)))
    weak = fit.weakly_identified()
    if weak:
        print(f"weakly identified: {len(weak)} parameter(s) whose std is as large as the "
              "value or that the data cannot tell from another (|r| >= 0.999)")
    if ident.fixed:
        print()
        print("fixed at their start value (the data cannot determine them):")
        for name, why in ident.fixed.items():
            print(f"  {name}: {why}")
    strongest = correlations(fit)["strongest"]
    if strongest:
        print()
        print("strongest correlations:")
        for c in strongest:
            print(f"  {c['a']:<24} {c['b']:<24} {c['r']:+.3f}")
    if fit.solver == "ridge":
        i = fit.info
        print()
        print(f"ridge     xi {i['xi']:.3g} ({i['xi_method']}) on the equilibrated normal "
              f"matrix; condition number {i['condition_number']:.3g} "
              f"({i['condition_class']} ill-conditioning)")
        if i.get("robust", True):
            print(f"IGG3      k0 {i['k0']}, k1 {i['k1']}, scale {i['scale_mm']:.4f} mm; "
                  f"rejected {len(i['rejected'])}, down-weighted {len(i['downweighted'])} poses")
            print(f"  rejected: {', '.join(i['rejected']) or 'none'}")
            print(f"  down-weighted: {', '.join(i['downweighted']) or 'none'}")
        if i.get("refixed"):
            print(f"  held after weighting: {', '.join(i['refixed'])}")
        if ridge_plot:
            print(f"  L-curve, GCV and ridge trace saved to {ridge_plot}")
    if mc is not None:
        print()
        print(f"Monte-Carlo: {mc.samples.shape[0]} re-identifications, sigma {mc.sigma_mm:.4f} mm"
              + (f", {mc.n_failed} did not converge" if mc.n_failed else ""))
        rows = [[r["name"], fmt(r["std_analytic"], 5), fmt(r["std_mc"], 5), fmt(r["ratio"], 2),
                 r["unit"]] for r in mc.rows(fit)]
        print(table(rows, ["parameter", "std analytic", "std MC", "MC/analytic", "unit"]))
        print(f"position uncertainty (1 sigma, 3-D, robot base frame, "
              f"{mc.position['n_poses']} random poses): analytic mean "
              f"{mc.position['mean_mm']:.4f} mm, max {mc.position['max_mm']:.4f} mm; "
              f"Monte-Carlo mean {mc.position_mc['mean_mm']:.4f} mm, "
              f"max {mc.position_mc['max_mm']:.4f} mm")
    if out_path:
        print()
        print(f"parameters written to {out_path}")
