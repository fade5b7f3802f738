"""The runs of a run store for people (``cellcal runs``): the rows of the list, and one run
in detail (what, where, when, with what context; its summary and interruptions).

Everything is read from the runs' JSON documents (``cellcal runs --json``), so the text
and the JSON say the same; the caller lays the rows out as tables.
"""

from __future__ import annotations

import datetime as dt
import math

#: the list's columns, and those aligned left
RUNS_HEADER = ["run", "routine", "status", "points", "model", "robot", "started",
               "interruptions", "beam breaks", "skipped", "remeasured", "reason"]
RUNS_LEFT = (0, 1, 2, 4, 5, 6, 11)
#: the columns of a run's interruptions, and those aligned left
INTERRUPTIONS_HEADER = ["interruption", "point", "kind", "message"]
INTERRUPTIONS_LEFT = (0, 2, 3)


def local_time(t) -> str:
    """Local time, ISO 8601 (``2026-11-22 04:25:46``); ``-`` when unknown."""
    if t is None:
        return "-"
    return dt.datetime.fromtimestamp(t).isoformat(sep=" ", timespec="seconds")


def value_text(v) -> str:
    """A summary value for people: numbers to 4 decimals, lists comma-separated, a matrix
    row by row (``;``)."""
    if isinstance(v, bool) or v is None:
        return "-" if v is None else ("yes" if v else "no")
    if isinstance(v, float):
        return f"{v:.4f}".rstrip("0").rstrip(".") if math.isfinite(v) else str(v)
    if isinstance(v, (list, tuple)):
        sep = "; " if v and isinstance(v[0], (list, tuple)) else ", "
        return sep.join(value_text(x) for x in v)
    return str(v)


def flatten(d: dict, prefix: str = "") -> list[tuple[str, str]]:
    """Nested summary entries as (dotted key, value text) rows."""
    rows = []
    for k, v in d.items():
        if isinstance(v, dict):
            rows += flatten(v, f"{prefix}{k}.")
        else:
            rows.append((f"{prefix}{k}", value_text(v)))
    return rows


def runs_rows(runs: list[dict], kinds: list[list[str]]) -> list[list]:
    """One row per run (its JSON document) with its interruptions' kinds."""
    return [[str(d["run"]), d["routine"], d["status"], f"{d['samples']}/{d['points']}",
             d["model"] or "-", d["robot_id"] or "-", local_time(d["started"]), len(k),
             k.count("beam"), k.count("skipped"), d["remeasure"]["suspects"],
             (d["reason"] or "")[:60]] for d, k in zip(runs, kinds, strict=True)]


def run_lines(d: dict, executor_defaults: dict) -> list[str]:
    """A run's heading: status, model and tool, SMR, devices, times, plan, software,
    measurement frame, tracker checks, executor settings that differ from
    ``executor_defaults``, acquisition options."""
    from .run_outcome import check_line

    c = d["context"]
    lines = [f"run {d['run']} ({d['routine']}): {d['status']}, {d['samples']}/{d['points']} "
             "points stored" + (f"; {d['reason']}" if d["reason"] else "")]
    tool = ("" if c["tool_mm"] is None else
            ", tool " + ", ".join(f"{v:g}" for v in c["tool_mm"]) + " mm")
    lines.append(f"{'model':10s} {d['model'] or '-'}{tool}")
    if c["smr_radius_mm"] is not None or c["reflector"]:
        radius = c["smr_radius_mm"]
        lines.append(f"{'SMR':10s} " + ", ".join(x for x in (
            c["reflector"], None if radius is None else f"radius {radius:g} mm") if x))
    lines.append(f"{'robot':10s} {d['robot'] or '-'}"
                 + (f"  ({d['robot_desc']})" if d["robot_desc"] else ""))
    if d["robot_id"]:
        lines.append(f"{'robot id':10s} {d['robot_id']}")
    lines.append(f"{'tracker':10s} {d['tracker'] or '-'}"
                 + (f"  ({d['tracker_desc']})" if d["tracker_desc"] else ""))
    started, stopped = d["started"], d["stopped"]
    elapsed = f" ({stopped - started:.1f} s)" if started and stopped else ""
    if d["source_run"] is not None:
        lines.append(f"{'source':10s} the plan of run {d['source_run']} (resumed in another "
                     "cell)")
    lines.append(f"{'started':10s} {local_time(started)}, stopped {local_time(stopped)}"
                 f"{elapsed}")
    lines.append(f"{'plan':10s} {d['plan_hash'][:16]}, {d['points']} points"
                 + ("" if d["seed"] is None else f", seed {d['seed']}"))
    lines.append(f"{'software':10s} {d['software'] or '-'}")
    if c["frame_run"] is not None:
        lines.append(f"{'frame':10s} from run {c['frame_run']}: tracker_T_base (robot base in "
                     "the tracker frame, mm)")
        lines += [" " * 11 + "  ".join(f"{v:12.6f}" for v in row)
                  for row in c["tracker_T_base"][:3]]
    if c["tracker_check"] is not None:
        lines.append(f"{'checks':10s} tracker: {check_line(c['tracker_check'])}")
    diff = [f"{k} {value_text(v)}" for k, v in c["executor"].items()
            if v != executor_defaults[k]]
    lines.append(f"{'executor':10s} {', '.join(diff) if diff else 'defaults'}")
    if c["acquire"]:
        lines.append(f"{'acquire':10s} "
                     + ", ".join(f"{k} {value_text(v)}" for k, v in c["acquire"].items()))
    return lines


def summary_rows(d: dict) -> list[list[str]]:
    """A run's summary (with its measurement frame's figures) as (key, value) rows."""
    summary = dict(d["summary"] or {})
    if d["frame"]:
        summary = {**{k: v for k, v in d["frame"].items() if k != "tracker_T_base"}, **summary}
    return [list(kv) for kv in flatten(summary)]


def interruption_rows(interruptions: list[dict]) -> list[list[str]]:
    return [[local_time(i["t"]), "-" if i["point"] is None else str(i["point"]), i["kind"],
             i["message"]] for i in interruptions]


def rejected_lines(rejected: list[dict]) -> list[str]:
    """The readings the capture did not accept, one line each (none: no lines)."""
    if not rejected:
        return []
    return [f"rejected readings ({len(rejected)}):"] + [
        f"  {local_time(x['t'])}  point {x['point']} ({x['pose_id']}): {x['reason']}"
        for x in rejected]


def drift_lines(curves: list[dict]) -> list[str]:
    """The drift checks of a run (``drift_checks`` of its JSON document, one curve per
    reference pose): its drift from the first reading over time, flagged above the bound
    (none: no lines)."""
    lines = []
    for c in curves:
        flag = "  FLAGGED: above the bound" if c["flagged"] else ""
        lines.append(f"drift checks, reference {c['reference']}: max {c['max_mm']:.3f} mm "
                     f"(bound {c['bound_mm']:.3f} mm){flag}")
        temps = c.get("joint_temp_c")
        lines.append("   t (min)  drift (mm)" + ("  joints (°C, mean)" if temps else ""))
        for i, (t, d) in enumerate(zip(c["t_s"], c["drift_mm"], strict=True)):
            mark = "  !" if d > c["bound_mm"] else ""
            temp = f"  {temps[i]:17.2f}" if temps else ""
            lines.append(f"  {t / 60.0:8.2f}  {d:10.4f}{temp}{mark}")
    return lines
