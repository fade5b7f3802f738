"""``cellcal report``: one self-contained HTML page showing where the model fails and what
fixed it (uncalibrated → current model → current plus the recommended effect)."""

from __future__ import annotations

from pathlib import Path

from calibration.solvers import SOLVERS
from presentation.html_report import ReportError, build_report

from ..cli import UsageError
from .common import (
    add_current_model_args,
    add_model_args,
    check_data,
    check_outputs,
    current_model,
    input_paths,
    load_inputs,
    print_json,
    print_note,
    wrap_errors,
)


def register(sub) -> None:
    p = sub.add_parser(
        "report",
        help="write an HTML report with plots: where the model fails, what fixed it",
        description="Fit the uncalibrated robot (nominal kinematics, best-fit base and tool), "
        "the current model and, when the "
        "diagnosis finds a significant missing effect, the current model plus that effect; "
        "write one self-contained HTML page (plots embedded) with the before/after error "
        "statistics, residual plots, the candidate ranking and the parameters.",
    )
    add_model_args(p)
    add_current_model_args(p, "use these parameters (and their model) as the current model",
                           "identification method (default lm)")
    p.add_argument("--title", default=None, help="the page's heading")
    p.add_argument("--out", default="report.html", metavar="FILE.html",
                   help="where to write the page (default report.html)")
    p.set_defaults(func=run)


def run(args) -> int:
    if args.solver not in SOLVERS:
        raise UsageError(f"unknown solver {args.solver!r}; available: {', '.join(SOLVERS)}")
    out = Path(args.out)
    check_outputs({"--out": args.out},
                  input_paths(args, "data", "params", "model", "effect_file"))
    model, data = load_inputs(args)
    em, params, notes = current_model(args, model)
    for n in notes + check_data(em, data):
        print_note(n)
    rep = wrap_errors(lambda: build_report(data, model, args.effects, params,
                                           solver=args.solver, title=args.title), ReportError)
    rep.write(out)
    size = out.stat().st_size
    if args.json:
        print_json({
            "out": str(out),
            "bytes": size,
            "figures": [f for f, _ in rep.figures],
            "stages": [{"label": s.label, "effects": s.fit.error_model.labels,
                        "calib": s.fit.calib, "valid": s.fit.valid} for s in rep.stages],
            "noise_floor_mm": rep.diagnosis.noise_floor_mm,
            "recommendation": rep.diagnosis.recommendation(),
            "next_effects": rep.diagnosis.next_effects(),
            "timings_s": rep.timings,
        })
        return 0
    for s in rep.stages:
        v = s.fit.valid
        print(f"{s.label:<30} RMS {s.fit.calib['rms_mm']:.4f} mm calibration"
              + (f", {v['rms_mm']:.4f} mm validation" if v else "")
              + f"  ({','.join(s.fit.error_model.labels)})")
    print(rep.diagnosis.recommendation())
    print(f"wrote {out}: {len(rep.figures)} figures, {size / 1e6:.2f} MB "
          f"in {rep.timings['total_s']:.1f} s")
    return 0
