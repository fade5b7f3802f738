"""The thermal state a compensation was made for, in words (``cellcal compensate``): the
state :func:`calibration.fit.thermal_state.target_state` describes."""

from __future__ import annotations


def state_line(state: dict) -> str:
    """The thermal state a compensation used, in one line."""
    parts = []
    if "joint_temp_c" in state:
        lo, hi = state["joint_temp_c"]
        parts.append(f"joints {lo:.1f}" + (f"–{hi:.1f}" if hi - lo >= 0.05 else "") + " °C")
    if "temp_c" in state:
        lo, hi = state["temp_c"]
        parts.append(f"air {lo:.1f}" + (f"–{hi:.1f}" if hi - lo >= 0.05 else "") + " °C")
    if "t_s" in state:
        w = state.get("time_window_s")
        if w and w[1] > w[0]:
            s = [(v - w[0]) / (w[1] - w[0]) for v in state["t_s"]]
            held = " (drift held at its end value)" if max(s) >= 1 else ""
            parts.append(f"time {min(s):.0%}–{max(s):.0%} of the capture's window{held}"
                         if max(s) - min(s) > 1e-9 else
                         f"time {s[0]:.0%} of the capture's window{held}")
    source = {"targets": "given per target", "mixed": "partly per target, else the "
              "calibration's warm state (the end of its capture)",
              "calibration's warm state": "the calibration's warm state (the end of its "
              "capture)"}[state["source"]]
    return f"{', '.join(parts)}: {source}"
