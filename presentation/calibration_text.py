"""The text ``cellcal calibrate`` prints for a fit: data, model, solver, the error table
before and after, the parameters with their uncertainties, what the data cannot
determine, the ridge and Monte-Carlo details; and two pieces the diagnosis shares, the
nominal tool's line (:func:`tool_text`) and the blunder verdict (:func:`blunder_lines`).

Every function returns text (lines joined by newlines) and prints nothing.
"""

from __future__ import annotations

from calibration.data.dataset import Dataset
from calibration.fit.envelope import Envelope, split_stats
from calibration.fit.identify import Fit
from calibration.fit.outliers import BlunderScreen
from calibration.fit.uncertainty import MonteCarlo, correlations
from calibration.model.robot_model import RobotModel
from calibration.workflow import UNCALIBRATED_LABEL

from .orientation_text import orientation_lines
from .text_table import fmt, table


def tool_text(model: RobotModel, data: Dataset, params: str | None = None) -> str:
    """``tool 0, 0, 60 mm (capture run 2)``: the nominal tool and where it came from
    (``params``: the params.json it was read from)."""
    cap = data.capture
    if params:
        where = params
    elif cap.tool_mm is not None:
        where = "capture" + (f" run {cap.run}" if cap.run is not None else "")
    else:
        where = "model"
    return "tool " + ", ".join(f"{v:g}" for v in model.tool) + f" mm ({where})"


def blunder_lines(screen: BlunderScreen | None, context: str = "fit") -> list[str]:
    """The blunder verdict: one sentence, and a table of the blunders (none when the
    cloud is clean)."""
    if screen is None or (screen.clean_cloud and not screen.blunders):
        return []
    lines = [f"blunders  {screen.message(context, list_points=False)}"]
    if screen.blunders:
        rows = [[b.pose_id, b.line or "-", fmt(b.residual_mm), fmt(b.ratio, 1),
                 {True: "along", False: "across", None: "-"}[b.along_beam],
                 fmt(b.angle_deg, 0)] for b in screen.blunders]
        lines.append(table(rows, ["pose", "line", "residual mm", "x threshold", "beam",
                                  "angle deg"]))
    return lines


def calibration_text(fit: Fit, baseline: Fit, out_path: str | None = None,
                     mc: MonteCarlo | None = None, ridge_plot: str | None = None) -> str:
    """What ``cellcal calibrate`` prints: ``fit`` against the uncalibrated ``baseline``;
    ``out_path``, ``ridge_plot``: the files written; ``mc``: a Monte-Carlo check."""
    em = fit.error_model
    d = fit.data
    left_out = len(fit.outliers.blunders) if fit.outliers and fit.outliers.excluded else 0
    ident = fit.identifiability
    lines = [
        f"data      {d.source}: {d.n + left_out} calibration poses"
        + (f" ({left_out} left out as blunders)" if left_out else "")
        + (f", {fit.valid['n']} validation poses" if fit.valid else ""),
        f"model     {em.model.name} ({em.model.convention}), {tool_text(em.model, d)}, "
        f"effects {','.join(em.labels)}",
        f"params    {em.n_params}, identifiable {ident.n_identifiable}; "
        f"condition number {ident.condition_number:.3g}, "
        f"observability index {ident.observability_index:.3g}",
        f"solver    {fit.solver}: {'converged' if fit.converged else 'NOT converged'} "
        f"({fit.reason}) after {fit.iterations} iterations, {fit.solve_s * 1000:.1f} ms",
    ]
    lines += [f"note      {note}" for note in fit.notes]
    lines += blunder_lines(fit.outliers)
    lines += ["", _error_table(fit, baseline), *envelope_lines(fit)]
    floor = fit.noise_floor_mm
    if floor:
        ref = fit.valid or fit.calib
        lines.append(f"noise floor sqrt(3)*sigma = {floor:.4f} mm; "
                     f"{'validation' if fit.valid else 'calibration'} RMS is "
                     f"{ref['rms_mm'] / floor:.2f} x the floor")
    lines += orientation_lines(fit)
    lines += ["", *_parameter_lines(fit)]
    if fit.solver == "ridge":
        lines += ["", *_ridge_lines(fit.info, ridge_plot)]
    if mc is not None:
        lines += ["", *_monte_carlo_lines(mc, fit)]
    if out_path:
        lines += ["", f"parameters written to {out_path}"]
    return "\n".join(lines)


def _error_table(fit: Fit, baseline: Fit) -> str:
    rows = []
    for label, f in ((UNCALIBRATED_LABEL, baseline), ("calibrated", fit)):
        for part in ("calib", "valid"):
            s = getattr(f, part)
            if s:
                rows.append([f"{label}, {part}", s["n"], fmt(s["rms_mm"]), fmt(s["mean_mm"]),
                             fmt(s["p95_mm"]), fmt(s["max_mm"])])
    if fit.valid:
        split = split_stats(Envelope.of_fit(fit), fit.valid_data, fit.valid_residuals)
        rows += split_rows(split, "valid ")
    return table(rows, ["position error", "n", "rms mm", "mean mm", "p95 mm", "max mm"])


def split_rows(split: dict, prefix: str = "") -> list[list]:
    """The error table's two rows of :func:`~calibration.fit.envelope.split_stats`: the
    poses inside the calibrated envelope and those beyond it (``prefix``: ``"valid "``)."""
    rows = []
    for where in ("inside", "outside"):
        s = split[where]
        rows.append([f"  {prefix}{where} the envelope", s["n"], fmt(s["rms_mm"]),
                     fmt(s["mean_mm"]), fmt(s["p95_mm"]), fmt(s["max_mm"])])
    return rows


def beyond_line(outside: dict, n: int, what: str) -> str | None:
    """``outside   2 of 100 validation poses lie beyond the envelope (q4: 1, q5: 1): ...``
    from the ``outside`` part of :func:`~calibration.fit.envelope.split_stats` (None when
    no pose lies beyond it); ``n`` the poses, ``what`` their name."""
    if not outside["n"]:
        return None
    return (f"outside   {outside['n']} of {n} {what} lie beyond the envelope ("
            + ", ".join(f"{k}: {v}" for k, v in outside["by_quantity"].items())
            + "): the calibration did not measure there")


def envelope_lines(fit: Fit) -> list[str]:
    """The calibrated envelope (the ranges the calibration rows covered) and the
    validation poses beyond it, by quantity."""
    env = Envelope.of_fit(fit)
    lines = [f"envelope  {line}" if k == 0 else f"          {line}"
             for k, line in enumerate(env.lines())]
    if fit.valid:
        by = split_stats(env, fit.valid_data, fit.valid_residuals)["outside"]
        line = beyond_line(by, fit.valid["n"], "validation poses")
        if line is not None:
            lines.append(line)
    return lines


def _parameter_lines(fit: Fit) -> list[str]:
    rows = []
    for r in fit.parameter_rows():
        std = "fixed" if not r["identifiable"] else fmt(r["std"], 4)
        rows.append([r["name"], fmt(r["value"], 4), std, r["unit"],
                     f"weak: {r['weak']}" if r["weak"] else ""])
    lines = [table(rows, ["parameter", "value", "std", "unit", "note"], left=(0, 4))]
    weak = fit.weakly_identified()
    if weak:
        lines.append(f"weakly identified: {len(weak)} parameter(s) whose std is as large as "
                     "the value or that the data cannot tell from another (|r| >= 0.999)")
    fixed = fit.identifiability.fixed
    if fixed:
        lines += ["", "fixed at their start value (the data cannot determine them):"]
        lines += [f"  {name}: {why}" for name, why in fixed.items()]
    strongest = correlations(fit)["strongest"]
    if strongest:
        lines += ["", "strongest correlations:"]
        lines += [f"  {c['a']:<24} {c['b']:<24} {c['r']:+.3f}" for c in strongest]
    return lines


def _ridge_lines(i: dict, ridge_plot: str | None) -> list[str]:
    lines = [f"ridge     xi {i['xi']:.3g} ({i['xi_method']}) on the equilibrated normal "
             f"matrix; condition number {i['condition_number']:.3g} "
             f"({i['condition_class']} ill-conditioning)"]
    if i.get("robust", True):
        lines += [f"IGG3      k0 {i['k0']}, k1 {i['k1']}, scale {i['scale_mm']:.4f} mm; "
                  f"rejected {len(i['rejected'])}, down-weighted {len(i['downweighted'])} "
                  "poses",
                  f"  rejected: {', '.join(i['rejected']) or 'none'}",
                  f"  down-weighted: {', '.join(i['downweighted']) or 'none'}"]
    if i.get("refixed"):
        lines.append(f"  held after weighting: {', '.join(i['refixed'])}")
    if ridge_plot:
        lines.append(f"  L-curve, GCV and ridge trace saved to {ridge_plot}")
    return lines


def _monte_carlo_lines(mc: MonteCarlo, fit: Fit) -> list[str]:
    rows = [[r["name"], fmt(r["std_analytic"], 5), fmt(r["std_mc"], 5), fmt(r["ratio"], 2),
             r["unit"]] for r in mc.rows(fit)]
    return [
        f"Monte-Carlo: {mc.samples.shape[0]} re-identifications, sigma {mc.sigma_mm:.4f} mm"
        + (f", {mc.n_failed} did not converge" if mc.n_failed else ""),
        table(rows, ["parameter", "std analytic", "std MC", "MC/analytic", "unit"]),
        f"position uncertainty (1 sigma, 3-D, robot base frame, "
        f"{mc.position['n_poses']} random poses): analytic mean "
        f"{mc.position['mean_mm']:.4f} mm, max {mc.position['max_mm']:.4f} mm; "
        f"Monte-Carlo mean {mc.position_mc['mean_mm']:.4f} mm, "
        f"max {mc.position_mc['max_mm']:.4f} mm",
    ]


def recorded_line(recorded: dict | None, db: str) -> str:
    """Whether ``calibrate --db`` recorded the fit (``recorded``: its ``calibration``
    JSON object, None for a fit that did not converge)."""
    if recorded is None:
        return f"not recorded in {db}: the fit did not converge"
    return (f"{'recorded' if recorded['new'] else 'already recorded'} as calibration "
            f"{recorded['id']} of robot {recorded['robot_id']} in {recorded['db']}")
