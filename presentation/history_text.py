"""What ``cellcal history`` prints about a robot's calibrations over time: the tables
(:func:`history_text`), the changes flagged (:func:`flagged_rows`, shared with the plot),
the robot's accuracy on new poses (its checks: :func:`checks_text`) and the ``--json``
object (:func:`history_summary`, docs/formats.md §4).

``calibrations`` are the store's records (``id``, ``t`` epoch seconds, ``recorded``,
``source_file``, ``source_run``, ``software``); every function returns text or a
JSON-ready mapping and prints nothing.
"""

from __future__ import annotations

import datetime as dt
import math
from pathlib import Path

import numpy as np

from calibration.diagnosis.history import CalibrationSummary, ParameterHistory

from .text_table import table

_SPARK = "▁▂▃▄▅▆▇█"


def utc(t: float) -> str:
    """``YYYY-MM-DD HH:MM`` (UTC) of epoch seconds."""
    return dt.datetime.fromtimestamp(float(t), dt.UTC).strftime("%Y-%m-%d %H:%M")


def _num(v, digits: int = 4, sign: bool = False) -> str:
    if v is None or (isinstance(v, float) and not math.isfinite(v)):
        return "-"
    return f"{v:+.{digits}f}" if sign else f"{v:.{digits}f}"


def _pm(v, s, digits: int) -> str:
    return (f"{_num(v, digits)} ± {_num(s, digits)}" if s is not None and math.isfinite(s)
            else _num(v, digits))


def _z(z: float) -> str:
    return f"{z:.1f}σ" if math.isfinite(z) else "-"


def spark(values) -> str:
    """The values as a line of block characters (lowest ▁, highest █)."""
    lo, hi = float(np.min(values)), float(np.max(values))
    if not hi > lo:
        return _SPARK[3] * len(values)
    k = np.rint((values - lo) / (hi - lo) * (len(_SPARK) - 1)).astype(int)
    return "".join(_SPARK[i] for i in k)


def flagged_rows(calibrations, histories: list[ParameterHistory]) -> list[list[str]]:
    """One row per flagged change: parameter, from (id and time), to, change with its
    unit, change in combined sigma."""
    times = [c.t for c in calibrations]
    ids = [c.id for c in calibrations]
    return [[h.name, f"{ids[h.index[k]]} ({utc(times[h.index[k]])})",
             f"{ids[h.index[k + 1]]} ({utc(times[h.index[k + 1]])})",
             f"{_num(h.change[k], h.decimals(), sign=True)} {h.unit}",
             f"{h.z[k]:.1f}"]
            for h in histories for k in np.flatnonzero(h.flagged)]


def _iso(t: float) -> str:
    return dt.datetime.fromtimestamp(t, dt.UTC).isoformat(timespec="seconds").replace(
        "+00:00", "Z")


def checks_summary(checks) -> list[dict]:
    """The ``checks`` list of ``history --json``: each check of a calibration on new poses
    (``cellcal check --db``), oldest first."""
    return [{"id": c.id, "t": c.t, "time": _iso(c.t), "recorded": c.recorded,
             "calibration": c.calibration_id, "params_sha256": c.params_sha256, "n": c.n,
             "rms_mm": c.rms_mm, "mean_mm": c.mean_mm, "p95_mm": c.p95_mm, "max_mm": c.max_mm,
             "tolerance_mm": c.tolerance_mm, "within_tolerance": c.within_tolerance,
             "refitted": list(c.refitted), "source_file": c.source_file,
             "source_run": c.source_run, "software": c.software} for c in checks]


def history_summary(robot_id: str, calibrations, summaries: list[CalibrationSummary],
                    histories: list[ParameterHistory], threshold: float,
                    checks=()) -> dict:
    """The ``history --json`` object (docs/formats.md §4); ``checks``: the robot's checks
    on new poses (``checks``, :func:`checks_summary`)."""
    ids = [c.id for c in calibrations]
    flagged = []
    params = []
    for h in histories:
        changes = []
        for k in range(h.change.size):
            a, b = ids[h.index[k]], ids[h.index[k + 1]]
            sigma = float(h.sigma[k]) if math.isfinite(h.sigma[k]) else None
            z = float(h.z[k]) if sigma else None
            change = {"from": a, "to": b, "change": float(h.change[k]), "sigma": sigma,
                      "z": z, "flagged": bool(h.flagged[k])}
            changes.append(change)
            if h.flagged[k]:
                flagged.append({"parameter": h.name, "unit": h.unit,
                                **{k2: change[k2] for k2 in ("from", "to", "change", "sigma",
                                                             "z")}})
        params.append({"name": h.name, "unit": h.unit, "values": [
            {"calibration": ids[i], "value": float(v),
             "std": float(s) if math.isfinite(s) else None}
            for i, v, s in zip(h.index, h.value, h.std, strict=True)], "changes": changes})
    return {
        "robot_id": robot_id, "threshold_sigma": threshold,
        "calibrations": [
            {"id": c.id, "t": c.t, "time": _iso(c.t), "recorded": c.recorded,
             "source_file": c.source_file, "source_run": c.source_run, "software": c.software,
             "model": s.model, "effects": list(s.effects), "calib_rms_mm": s.calib_rms_mm,
             "valid_rms_mm": s.valid_rms_mm}
            for c, s in zip(calibrations, summaries, strict=True)],
        "parameters": params, "flagged": flagged, "checks": checks_summary(checks)}


def checks_text(checks) -> list[str]:
    """The robot's accuracy over time: its checks on new poses (``cellcal check --db``),
    one row each, and the trend of their RMS."""
    rows = []
    for c in checks:
        verdict = "-"
        if c.tolerance_mm is not None:
            verdict = f"{c.tolerance_mm:g}: " + ("within" if c.within_tolerance else "BEYOND")
        rows.append([str(c.id), utc(c.t), "-" if c.calibration_id is None
                     else str(c.calibration_id),
                     Path(c.source_file).name if c.source_file else "-", str(c.n),
                     _num(c.rms_mm), _num(c.max_mm), ",".join(c.refitted) or "-", verdict])
    lines = ["accuracy on new poses (`cellcal check`):",
             table(rows, ["check", "measured (UTC)", "calibration", "source", "n", "rms mm",
                          "max mm", "refitted", "tolerance mm"])]
    rms = np.array([c.rms_mm for c in checks if c.rms_mm is not None], float)
    if rms.size >= 2:
        lines.append(f"RMS over the checks: {spark(rms)}  {_num(rms[0])} -> {_num(rms[-1])} mm")
    return lines


def history_text(robot_id: str, address: str, calibrations,
                 summaries: list[CalibrationSummary], histories: list[ParameterHistory],
                 shown: list[ParameterHistory], threshold: float, checks=()) -> str:
    """The calibrations, one line per parameter (first and last value, net change,
    largest step, trend), the changes flagged, the value over time of the ``shown``
    parameters, and the robot's accuracy on new poses (``checks``)."""
    checks = list(checks)
    if not calibrations:
        times = np.array([c.t for c in checks])
        return "\n".join([f"robot {robot_id}: no calibrations, {len(checks)} check(s) from "
                          f"{utc(times[0])} to {utc(times[-1])} UTC in {address}", "",
                          *checks_text(checks)])
    times = np.array([c.t for c in calibrations])
    lines = [f"robot {robot_id}: {len(calibrations)} calibrations from {utc(times[0])} to "
             f"{utc(times[-1])} UTC in {address}", ""]
    rows = []
    for c, s, prev in zip(calibrations, summaries, [None, *summaries[:-1]], strict=True):
        effects = ",".join(s.effects)
        if prev is not None and prev.effects != s.effects:
            effects += " (effects changed)"
        rows.append([str(c.id), utc(c.t), Path(c.source_file).name if c.source_file else "-",
                     effects, _num(s.calib_rms_mm), _num(s.valid_rms_mm)])
    lines += [table(rows, ["calibration", "measured (UTC)", "source", "effects",
                           "calib rms mm", "valid rms mm"]), "", _parameter_table(histories)]
    fixed = [h.name for h in histories if not h.determined]
    if fixed:
        lines.append(f"held fixed, not identifiable: {', '.join(fixed)}")
    lines.append("")
    flagged = flagged_rows(calibrations, histories)
    if flagged:
        lines.append(f"{len(flagged)} change(s) larger than {threshold:g} combined sigma:")
        lines += [f"  {name}: calibration {a} -> {b}: {change}, {z} sigma"
                  for name, a, b, change, z in flagged]
    else:
        lines.append(f"no change larger than {threshold:g} combined sigma")
    for h in shown:
        lines += ["", f"{h.name} ({h.unit})", _values_table(h, calibrations)]
    if checks:
        lines += ["", *checks_text(checks)]
    return "\n".join(lines)


def _parameter_table(histories: list[ParameterHistory]) -> str:
    rows = []
    for h in histories:
        if not h.determined:
            continue
        d = h.decimals()
        k = h.largest_step()
        step = "-" if k is None else (f"{_num(h.change[k], d, sign=True)} ({_z(h.z[k])})"
                                      + (" !" if h.flagged[k] else ""))
        rows.append([h.name, h.unit, _pm(h.value[0], h.std[0], d),
                     _pm(h.value[-1], h.std[-1], d),
                     f"{_num(h.net_change, d, sign=True)} ({_z(h.net_z)})", step,
                     spark(h.value)])
    return table(rows, ["parameter", "unit", "first", "last", "net change", "largest step",
                        "trend"])


def _values_table(h: ParameterHistory, calibrations) -> str:
    rows = []
    d = h.decimals()
    for j, i in enumerate(h.index):
        change = sigma = z = ""
        if j:
            change = _num(h.change[j - 1], d, sign=True)
            sigma = _num(h.sigma[j - 1], d)
            z = "-" if not math.isfinite(h.z[j - 1]) else f"{h.z[j - 1]:.1f}" + (
                " !" if h.flagged[j - 1] else "")
        c = calibrations[i]
        rows.append([str(c.id), utc(c.t), _num(h.value[j], d), _num(h.std[j], d),
                     change, sigma, z])
    return table(rows, ["calibration", "measured (UTC)", "value", "std", "change",
                        "combined std", "change/std"])
