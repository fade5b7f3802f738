"""``cellcal diagnose --auto``: add missing effects one at a time while the held-out error
falls (:func:`calibration.auto_diagnosis.auto_diagnose`), print the steps, write params.json."""

from __future__ import annotations

import json
import math
from typing import TYPE_CHECKING

from ..cli import UsageError
from .common import (
    check_outputs,
    fmt,
    input_paths,
    positive_float,
    positive_int,
    print_json,
    print_outliers,
    table,
)

if TYPE_CHECKING:  # the calibration core is imported when a run needs it (fast --help)
    from calibration.auto_diagnosis import AutoDiagnosis, AutoStep


def add_auto_args(p) -> None:
    g = p.add_argument_group("automatic diagnosis")
    g.add_argument("--auto", action="store_true",
                   help="add the best candidate, refit, and repeat while the held-out error "
                   "(validation rows, else cross-validation) falls by more than its "
                   "standard error; print the steps and why it stopped")
    g.add_argument("--max-steps", type=positive_int, default=12, metavar="N",
                   help="with --auto: add at most N effects (default 12)")
    g.add_argument("--budget-s", type=positive_float, default=None, metavar="S",
                   help="with --auto: stop after S seconds, keeping the steps accepted")
    g.add_argument("--out", metavar="params.json",
                   help="with --auto: write the final model's parameters here (as calibrate)")


def check_auto_args(args) -> None:
    if not args.auto:
        given = [f for f, v in (("--out", args.out), ("--budget-s", args.budget_s),
                                ("--max-steps", args.max_steps != 12)) if v]
        if given:
            raise UsageError(f"{', '.join(given)} need(s) --auto")
        return
    if args.max_steps < 1:
        raise UsageError("--max-steps must be at least 1")
    if args.budget_s is not None and not (args.budget_s > 0 and math.isfinite(args.budget_s)):
        raise UsageError("--budget-s must be a positive number of seconds")
    check_outputs({"--out": args.out},
                  input_paths(args, "data", "params", "model", "effect_file"))


def run_auto(args, fit, data) -> int:
    from calibration.auto_diagnosis import auto_diagnose
    from calibration.params_io import fit_to_dict

    quiet = args.json
    if not quiet:
        print_header(fit, data)
        print_outliers(fit.outliers, "ranking")

    def progress(step: AutoStep) -> None:
        if not quiet:
            print(f"step {len(progress.steps) + 1:>2}  {step.effect:<14} held-out RMS "
                  f"{step.heldout_rms_mm:.4f} mm  ({step.seconds:.1f} s)", flush=True)
        progress.steps.append(step)

    progress.steps = []
    result = auto_diagnose(fit, data, max_steps=args.max_steps, budget_s=args.budget_s,
                           progress=progress)
    if args.out:
        from calibration.files import write_atomic

        write_atomic(args.out, json.dumps(fit_to_dict(result.fit, args.effect_file,
                                                      auto=result), indent=1) + "\n")
    if quiet:
        print_json(result.to_json(args.out))
        return 0
    print()
    print_auto(result, args.out)
    return 0


def print_header(fit, data) -> None:
    em = fit.error_model
    calib_n = fit.data.n
    valid_n = fit.valid["n"] if fit.valid else 0
    print(f"model     {em.model.name}, start effects {','.join(em.labels)}")
    print(f"data      {calib_n} calibration poses" + (f", {valid_n} validation poses"
                                                      if valid_n else ""))
    floor = fit.data.noise_floor_mm()
    print("floor     " + (f"noise floor {floor:.4f} mm" if floor
                          else "noise floor unknown (--sigma)"))


def print_auto(result: AutoDiagnosis, out: str | None) -> None:
    start = result.start
    rows = [[" 0 (start) " + ",".join(start.error_model.labels), "",
             fmt(start.calib["rms_mm"], 4), fmt(result.start_heldout_rms_mm, 4), ""]]
    for i, s in enumerate(result.steps, 1):
        rows.append([f"{i:>2} {s.effect}", str(s.n_params), fmt(s.calib_rms_mm, 4),
                     fmt(s.heldout_rms_mm, 4), f"{s.seconds:.1f}"])
    print(table(rows, ["step, effect added", "params", "calib rms mm", "held-out rms mm",
                       "time s"]))
    print(f"held-out error: {result.heldout_method}")
    if result.steps:
        print()
        for i, s in enumerate(result.steps, 1):
            print(f"{i:>2}. {s.effect}: {s.explanation}")
    print()
    print(f"stopped   {result.stop_reason}")
    if result.rejected:
        print("          last tried: " + ", ".join(f"{e} (held-out {h:.4f} mm)"
                                                   for e, h in result.rejected))
    floor = result.noise_floor_mm
    final = result.steps[-1].heldout_rms_mm if result.steps else result.start_heldout_rms_mm
    if floor:
        print(f"          held-out RMS {final:.4f} mm is {final / floor:.2f} x the noise floor")
    print(f"effects   {','.join(result.effects)}")
    print(f"time      {result.total_s:.1f} s")
    if out:
        print(f"wrote     {out}")
    for note in result.notes:
        print(f"note: {note}")
