"""``cellcal report``: one self-contained HTML page showing where the model fails and what
fixed it (uncalibrated → current model → current plus the recommended effect, or with
``--auto`` every step of the automatic diagnosis), with its provenance (software, date,
data file and SHA-256, capture run, model)."""

from __future__ import annotations

import math
from pathlib import Path

from ..cli import UsageError, command_parser
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
    p = command_parser(
        sub, "report",
        help="write an HTML report with plots: where the model fails, what fixed it",
        description="Fit the uncalibrated robot (nominal kinematics, best-fit base and tool), "
        "the current model and, when the diagnosis finds a significant missing effect, the "
        "current model plus that effect; write one self-contained HTML page (plots "
        "embedded) with the before/after error statistics, residual plots, the blunders "
        "left out, the candidate ranking and the parameters. Prints one line per model "
        "(RMS on the calibration and validation rows), the recommendation and the file "
        "written. With --auto, the automatic diagnosis (as `diagnose --auto`) adds effects "
        "one at a time and the page shows the error falling step by step; a --params file "
        "written by `diagnose --auto --out` shows its recorded steps.",
    )
    add_model_args(p)
    add_current_model_args(p, "use these parameters (and their model) as the current model")
    p.add_argument("--auto", action="store_true",
                   help="run the automatic diagnosis from the current model and show every "
                   "step (as `cellcal diagnose --auto`)")
    p.add_argument("--max-steps", type=int, default=12, metavar="N",
                   help="with --auto: add at most N effects (default 12)")
    p.add_argument("--budget-s", type=float, default=None, metavar="S",
                   help="with --auto: stop after S seconds, keeping the steps accepted")
    p.add_argument("--title", default=None, help="the page's heading")
    p.add_argument("--out", default="report.html", metavar="FILE.html",
                   help="where to write the page (default report.html)")
    p.set_defaults(func=run)


def run(args) -> int:
    from presentation.html_report import ReportError, build_report
    from presentation.provenance import Provenance

    if not args.auto and (args.max_steps != 12 or args.budget_s is not None):
        raise UsageError("--max-steps and --budget-s need --auto")
    if args.max_steps < 1:
        raise UsageError("--max-steps must be at least 1")
    if args.budget_s is not None and not (args.budget_s > 0 and math.isfinite(args.budget_s)):
        raise UsageError("--budget-s must be a positive number of seconds")
    out = Path(args.out)
    check_outputs({"--out": args.out},
                  input_paths(args, "data", "params", "model", "effect_file"))
    model, data = load_inputs(args)
    em, _, notes = current_model(args, model)
    for n in notes + check_data(em, data):
        print_note(n)
    prov = wrap_errors(lambda: Provenance.of(model.name, args.data, data, args.params),
                       OSError)
    rep = wrap_errors(lambda: build_report(data, model, args.effects, args.params,
                                           solver=args.solver, title=args.title,
                                           auto=args.auto, max_steps=args.max_steps,
                                           budget_s=args.budget_s, provenance=prov),
                      ReportError)
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
            "provenance": prov.to_json(),
            "outliers": _outliers(rep),
            **({"steps": _steps(rep.story)} if rep.story is not None else {}),
        })
        return 0
    for s in rep.stages:
        v = s.fit.valid
        print(f"{s.label:<30} RMS {s.fit.calib['rms_mm']:.4f} mm calibration"
              + (f", {v['rms_mm']:.4f} mm validation" if v else "")
              + f"  ({','.join(s.fit.error_model.labels)})")
    if rep.story is not None:
        print(f"automatic diagnosis: {rep.story.stop_reason}")
    print(rep.diagnosis.recommendation())
    print(f"wrote {out}: {len(rep.figures)} figures, {size / 1e6:.2f} MB "
          f"in {rep.timings['total_s']:.1f} s")
    return 0


def _steps(story) -> dict:
    return {"recorded": story.recorded, "heldout_method": story.heldout_method,
            "stop_reason": story.stop_reason,
            "steps": [{"effect": s.effect, "n_params": s.n_params,
                       "calib_rms_mm": s.calib_rms_mm, "heldout_rms_mm": s.heldout_rms_mm}
                      for s in story.steps]}


def _outliers(rep) -> list[dict]:
    """The blunders any shown fit left out (FORMATS.md §4 ``outliers`` entries)."""
    seen, out = set(), []
    for sc in [s.fit.outliers for s in rep.stages] + [rep.diagnosis.outliers]:
        for o in (sc.to_json() if sc is not None else []):
            if o["pose_id"] not in seen:
                seen.add(o["pose_id"])
                out.append(o)
    return out
