"""How a capture run ended, for people: the lines ``cellcal capture`` and ``resume`` print
for a run outcome (its ``--json`` document, ``RunOutcome.to_json()``), the exit code it
means, and one line of what the tracker's checks found."""

from __future__ import annotations

import signal


def outcome_lines(out: dict) -> list[str]:
    """The run, its status and counts; why it stopped, the re-measures, the measurement
    frame, the tracker's checks, the line of sight, how a warm-up ended and its drift
    curve; how to resume it."""
    lines = [f"run {out['run']} ({out['routine']}): {out['status']}, "
             f"{out['samples']}/{out['points']} points stored, {out['faults']} faults, "
             f"{out['elapsed_s']:.1f} s  [{out['db']}]"]
    if out.get("reason"):
        lines.append(f"  reason: {out['reason']}")
    rm = (out.get("summary") or {}).get("remeasure")
    if rm and (rm["suspects"] or rm["rejected"] or rm["unresolved"]):
        lines.append(f"  re-measured {rm['suspects']} points ({rm['remeasurements']} "
                     f"re-measurements, {rm['rejected']} readings rejected, "
                     f"{rm['model_disagrees']} where the model disagrees, {rm['unresolved']} "
                     f"unresolved); the first {rm['warmup']} points before the model")
    if "frame" in out:
        f = out["frame"]
        lines.append(f"  frame: circle rms {f['circle']['rms_mm']:.4f} mm, line rms "
                     f"{f['line']['rms_mm']:.4f} mm, non-orthogonality "
                     f"{f['orthogonality_deg']:.4f} deg")
        lines.append("  tracker_T_base (robot base in the tracker frame, mm; rows of [R | t]):")
        lines += ["   " + "  ".join(f"{v:12.6f}" for v in row) for row in f["tracker_T_base"][:3]]
    if out.get("tracker_check"):
        lines.append(f"  tracker: {check_line(out['tracker_check'])}")
    summary = out.get("summary") or {}
    if summary.get("beam_breaks") or summary.get("skipped_points"):
        skipped = summary.get("skipped_points", [])
        lines.append(f"  line of sight: {summary.get('beam_breaks', 0)} beam breaks, "
                     f"{len(skipped)} points skipped {skipped[:10]}, "
                     f"{summary.get('spares_measured', 0)} spares measured in their place")
    warm = summary.get("warmup")
    if warm:
        lines.append(f"  warm-up: {warm.get('reason')}")
        curve = zip(warm.get("t_min") or [], warm.get("curve_mm") or [], strict=True)
        lines.append("  drift curve (min: mm from the first reading): "
                     + ", ".join(f"{t:.1f}: {d:.3f}" for t, d in curve))
    if out["status"] in ("paused", "stopped"):
        lines.append(f"  resume with: cellcal resume {out['run']} --db {out['db']}")
    return lines


def outcome_exit_code(out: dict) -> int:
    """0 completed, 3 incomplete (too many points skipped), 130 stopped (Ctrl-C), 128 + N
    stopped at once by signal N, else 1; a warm-up that completed its plan without
    settling (the robot still drifted) is 1 too: its goal was not reached."""
    signum = out.get("signal")
    if signum:
        return 128 + int(getattr(signal, signum, 0) or 1)
    warm = (out.get("summary") or {}).get("warmup")
    if out["status"] == "completed" and warm is not None and not warm.get("settled"):
        return 1
    return {"completed": 0, "incomplete": 3, "stopped": 130}.get(out["status"], 1)


def check_line(c: dict) -> str:
    """One line of what the tracker's checks found (a ``TrackerCheck``, JSON)."""
    parts = []
    if c.get("ready") is not None:
        parts.append("ready")
    if c.get("temp_c") is not None:
        parts.append(f"air {c['temp_c']:.1f} °C {c['pressure_hpa']:.1f} hPa "
                     f"{c['humidity_pct']:.0f} %RH ({c['air_source']})")
    if c.get("reflector"):
        parts.append(f"reflector {c['reflector']}")
    if c.get("face"):
        parts.append(f"face {c['face']}")
    f = c.get("two_face")
    if f:
        parts.append(f"two faces {f['diff_mm']:.3f} mm apart (allowed {f['tol_mm']:.3f} + "
                     f"{f['noise_mm']:.3f} noise)")
    return ", ".join(parts) or "no checks offered"
