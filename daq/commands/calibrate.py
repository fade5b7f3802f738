"""``cellcal calibrate``: identify a robot's error parameters from a measurement CSV."""

from __future__ import annotations

import json
from pathlib import Path

from calibration import DEFAULT_EFFECTS, ErrorModel, identify, load_csv
from calibration.params_io import fit_to_dict, load_params
from calibration.solvers import SOLVERS

from ..cli import UsageError
from .common import add_model_args, fmt, load_inputs, print_json, table, wrap_errors


def register(sub) -> None:
    p = sub.add_parser(
        "calibrate",
        help="identify error parameters from measured poses",
        description="Fit the robot's error model to a measurement CSV and report the "
        "parameters, their uncertainties and the remaining error.",
    )
    add_model_args(p)
    p.add_argument("--effects", default=DEFAULT_EFFECTS, metavar="LIST",
                   help=f"comma-separated effects (default {DEFAULT_EFFECTS})")
    p.add_argument("--solver", default="lm", help="identification method (default lm)")
    p.add_argument("--valid", metavar="FILE", help="validation CSV (besides set=valid rows)")
    p.add_argument("--params", metavar="params.json", help="start from these parameters")
    p.add_argument("--out", metavar="params.json", help="write the parameters here")
    p.set_defaults(func=run)


def calibrate(args):
    """Run a calibration from parsed arguments; returns (fit, baseline fit)."""
    model, data = load_inputs(args)
    if args.solver not in SOLVERS:
        raise UsageError(f"unknown solver {args.solver!r}; available: {', '.join(SOLVERS)}")
    em = wrap_errors(lambda: ErrorModel(model, args.effects))
    valid = wrap_errors(lambda: load_csv(args.valid, model)) if args.valid else None
    x0 = None
    if args.params:
        em_p, x_p, _ = wrap_errors(lambda: load_params(args.params))
        x0 = em.initial(em.bind(data.calib() if data.is_valid.any() else data))
        for k, name in enumerate(em_p.names):
            if name in em.names:
                x0[em.index(name)] = x_p[k]
    baseline = identify(ErrorModel(model, "base"), data, valid=valid)
    fit = wrap_errors(lambda: identify(em, data, args.solver, valid=valid, x0=x0))
    return fit, baseline


def run(args) -> int:
    fit, baseline = calibrate(args)
    if args.out:
        Path(args.out).write_text(
            json.dumps(fit_to_dict(fit, args.effect_file), indent=1) + "\n"
        )
    if args.json:
        out = fit.summary()
        out["params_file"] = args.out
        out["uncalibrated"] = {"calib": baseline.calib, "valid": baseline.valid}
        print_json(out)
        return 0 if fit.converged else 1
    print_report(fit, baseline, args.out)
    return 0 if fit.converged else 1


def print_report(fit, baseline, out_path=None) -> None:
    em = fit.error_model
    d = fit.data
    print(f"data      {d.source}: {d.n} calibration poses"
          + (f", {fit.valid['n']} validation poses" if fit.valid else ""))
    print(f"model     {em.model.name} ({em.model.convention}), effects {','.join(em.labels)}")
    ident = fit.identifiability
    print(f"params    {em.n_params}, identifiable {ident.n_identifiable}; "
          f"condition number {ident.condition_number:.3g}, "
          f"observability index {ident.observability_index:.3g}")
    print(f"solver    {fit.solver}: {'converged' if fit.converged else 'NOT converged'} "
          f"({fit.reason}) after {fit.iterations} iterations, {fit.solve_s * 1000:.1f} ms")
    for note in fit.notes:
        print(f"note      {note}")
    print()
    rows = []
    for label, f in (("uncalibrated (best-fit base)", baseline), ("calibrated", fit)):
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
        rows.append([r["name"], fmt(r["value"], 4), std, r["unit"]])
    print(table(rows, ["parameter", "value", "std", "unit"]))
    if ident.fixed:
        print()
        print("fixed at their start value (the data cannot determine them):")
        for name, why in ident.fixed.items():
            print(f"  {name}: {why}")
    if out_path:
        print()
        print(f"parameters written to {out_path}")
