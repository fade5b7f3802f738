"""``cellcal history ROBOT --db STORE``: a robot's calibrations over time.

Reads the calibrations recorded with ``cellcal calibrate ... --db STORE --robot-id ROBOT``
and prints: the calibrations (when their data were measured, UTC; source; effects;
RMS), one line per parameter (first and last value ± std, net change, the largest
change between consecutive calibrations in combined standard uncertainties, a trend
line), every change larger than ``--sigma`` (default 3) combined sigma
(sqrt(σ1² + σ2²), :mod:`calibration.history`), and the value over time with its
uncertainty of the parameters that changed (or of those named with ``--param``).
``--plot FILE.html|FILE.png`` draws the trends; ``--json`` prints one object
(docs/formats.md §4).

Exit codes (docs/formats.md §6): 0 done (whether or not a change was flagged), 2 bad
input (no such store or robot).
"""

from __future__ import annotations

import datetime as dt
import fnmatch
import math
from pathlib import Path

from ..cli import UsageError, command_parser
from .common import positive_float

_SPARK = "▁▂▃▄▅▆▇█"
#: flag a change larger than this many combined sigma (:data:`calibration.history.DEFAULT_SIGMA`,
#: kept equal by tests/cellcal/test_cli_help.py)
DEFAULT_SIGMA = 3.0


def register(sub) -> None:
    from .common import DB_HELP

    p = command_parser(
        sub, "history", help="a robot's calibrations over time: drift and changes",
        description="A robot's calibrations, recorded with `cellcal calibrate ... --db STORE "
        "--robot-id ROBOT`, over time: the calibrations (when their data were measured, "
        "UTC; source; effects; RMS), one line per parameter (first and last value ± std, "
        "net change, the largest change between consecutive calibrations in combined "
        "standard uncertainties, a trend line), every change larger than --sigma combined "
        "sigma (sqrt(σ1² + σ2²)), and the value over time of the parameters that changed "
        "(or of those named with --param). The store is opened read-only (docs/history.md)."
        "\n\nExit codes: 0 done (whether or not a change was flagged), 2 bad input (no "
        "such store or robot); docs/formats.md §6.")
    p.add_argument("robot_id", metavar="ROBOT", help="the robot (as given with --robot-id)")
    p.add_argument("--db", required=True, metavar="cell.db|URL", help=DB_HELP)
    p.add_argument("--param", action="append", default=[], metavar="GLOB",
                   help="print the value over time of these parameters (repeatable; "
                   "shell-style patterns, e.g. 'geometric.j2.*'; default: those that changed)")
    p.add_argument("--sigma", type=positive_float, default=DEFAULT_SIGMA, metavar="K",
                   help=f"flag a change larger than K combined sigma (default {DEFAULT_SIGMA:g})")
    p.add_argument("--plot", metavar="FILE.html|FILE.png",
                   help="draw the trends of the parameters printed (all when none)")
    p.add_argument("--json", action="store_true", help="print one JSON object")
    p.set_defaults(func=run)


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
    import numpy as np

    lo, hi = float(np.min(values)), float(np.max(values))
    if not hi > lo:
        return _SPARK[3] * len(values)
    k = np.rint((values - lo) / (hi - lo) * (len(_SPARK) - 1)).astype(int)
    return "".join(_SPARK[i] for i in k)


def _load(args):
    from daq.store import StoreError

    from .common import open_store

    store = open_store(args.db, read_only=True)
    try:
        cals = store.calibrations(args.robot_id)
        robots = store.robots()
    except StoreError as e:
        raise UsageError(str(e)) from None
    finally:
        store.close()
    if not cals:
        known = ", ".join(r for r, _ in robots) or "none"
        raise UsageError(f"{store.address}: no calibrations of robot {args.robot_id!r} "
                         f"(robots with calibrations: {known})")
    return store.address, cals


def history_json(robot_id: str, cals, summaries, histories, threshold: float) -> dict:
    """The ``history --json`` object (docs/formats.md §4)."""
    ids = [c.id for c in cals]
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
            {"id": c.id, "t": c.t, "time": dt.datetime.fromtimestamp(c.t, dt.UTC).isoformat(
                timespec="seconds").replace("+00:00", "Z"), "recorded": c.recorded,
             "source_file": c.source_file, "source_run": c.source_run, "software": c.software,
             "model": s.model, "effects": list(s.effects), "calib_rms_mm": s.calib_rms_mm,
             "valid_rms_mm": s.valid_rms_mm}
            for c, s in zip(cals, summaries, strict=True)],
        "parameters": params, "flagged": flagged}


def run(args) -> int:
    import numpy as np

    from calibration.history import CalibrationSummary, parameter_histories

    from .common import check_outputs, print_json, table

    if args.plot and Path(args.plot).suffix.lower() not in (".html", ".htm", ".png"):
        raise UsageError(f"--plot {args.plot}: give a .html or .png file")
    check_outputs({"--plot": args.plot}, [args.db])
    address, cals = _load(args)
    docs = [c.params for c in cals]
    summaries = [CalibrationSummary.of(d) for d in docs]
    histories = parameter_histories(docs, args.sigma)
    times = np.array([c.t for c in cals])
    ids = [c.id for c in cals]
    shown = [h for h in histories
             if any(fnmatch.fnmatchcase(h.name, g) for g in args.param)] if args.param else \
        [h for h in histories if h.flagged.any()]
    if args.param and not shown:
        raise UsageError(f"no parameter matches {', '.join(args.param)}")
    flagged_rows = [[h.name, f"{ids[h.index[k]]} ({utc(times[h.index[k]])})",
                     f"{ids[h.index[k + 1]]} ({utc(times[h.index[k + 1]])})",
                     f"{_num(h.change[k], h.decimals(), sign=True)} {h.unit}",
                     f"{h.z[k]:.1f}"]
                    for h in histories for k in np.flatnonzero(h.flagged)]
    if args.plot:
        from presentation.history_plot import write_history_plot

        write_history_plot(args.plot, shown or histories, times,
                           f"calibration history of {args.robot_id}", flagged_rows)
    if args.json:
        out = history_json(args.robot_id, cals, summaries, histories, args.sigma)
        if args.plot:
            out["plot"] = args.plot
        print_json(out)
        return 0

    print(f"robot {args.robot_id}: {len(cals)} calibrations from {utc(times[0])} to "
          f"{utc(times[-1])} UTC in {address}")
    print()
    rows = []
    for c, s, prev in zip(cals, summaries, [None, *summaries[:-1]], strict=True):
        effects = ",".join(s.effects)
        if prev is not None and prev.effects != s.effects:
            effects += " (effects changed)"
        rows.append([str(c.id), utc(c.t), Path(c.source_file).name if c.source_file else "-",
                     effects, _num(s.calib_rms_mm), _num(s.valid_rms_mm)])
    print(table(rows, ["calibration", "measured (UTC)", "source", "effects", "calib rms mm",
                       "valid rms mm"]))
    print()
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
    print(table(rows, ["parameter", "unit", "first", "last", "net change", "largest step",
                       "trend"]))
    fixed = [h.name for h in histories if not h.determined]
    if fixed:
        print(f"held fixed, not identifiable: {', '.join(fixed)}")
    print()
    if flagged_rows:
        print(f"{len(flagged_rows)} change(s) larger than {args.sigma:g} combined sigma:")
        for name, a, b, change, z in flagged_rows:
            print(f"  {name}: calibration {a} -> {b}: {change}, {z} sigma")
    else:
        print(f"no change larger than {args.sigma:g} combined sigma")
    for h in shown:
        print()
        print(f"{h.name} ({h.unit})")
        rows = []
        d = h.decimals()
        for j, i in enumerate(h.index):
            change = sigma = z = ""
            if j:
                change = _num(h.change[j - 1], d, sign=True)
                sigma = _num(h.sigma[j - 1], d)
                z = "-" if not math.isfinite(h.z[j - 1]) else f"{h.z[j - 1]:.1f}" + (
                    " !" if h.flagged[j - 1] else "")
            rows.append([str(ids[i]), utc(times[i]), _num(h.value[j], d), _num(h.std[j], d),
                         change, sigma, z])
        print(table(rows, ["calibration", "measured (UTC)", "value", "std", "change",
                           "combined std", "change/std"]))
    if args.plot:
        print()
        print(f"trends drawn in {args.plot}")
    return 0
