"""The demo's cold start (``cellcal demo --cold-start``): the simulated robot starts at the
air's temperature and warms up while it is captured.

Its links grow and its joint zeros move with the joints' temperatures (hidden, a few
tenths of a mm over the warm-up; :mod:`sim_drivers.thermal`). The capture runs on the
simulated clock (each measurement lasts :data:`MEASURE_S`, so 450 poses take about an
hour of the robot's time and seconds of ours) and measures a reference pose again every
:data:`DRIFT_EVERY` points (``capture --drift-check``): the curve shows the drift, the
diagnosis names it, the automatic diagnosis adds the drift effects.
"""

from __future__ import annotations

from daq.drift_checks import DriftCheck, drift_curve
from daq.run_context import ExecutorOptions

#: what the cold-start demo hides, in its closing table
HIDDEN = "the warm-up (thermal drift)"
#: the effect families that model the warm-up (:mod:`calibration.effects.drift`)
DRIFT_FAMILIES = ("thermal_growth", "thermal_zero", "time_growth", "base_drift")
#: seconds of simulated time per measurement: 450 poses span about an hour of warm-up
MEASURE_S = 8.0
#: a drift check every this many points
DRIFT_EVERY = 25
#: how the story's capture line ends
CAPTURE_NOTE = f", from cold, measuring a reference pose again every {DRIFT_EVERY} points"


def capture_options() -> dict:
    """The capture settings of the cold start (:class:`daq.service.CaptureRequest`
    keywords): long measurements on the simulated clock, drift checks."""
    return {"executor": ExecutorOptions(measure_s=MEASURE_S),
            "drift_check": DriftCheck(DRIFT_EVERY)}


def drift_story(store, run_id: int) -> str:
    """What the drift checks of the run saw, in one line (for the demo's story)."""
    curves = drift_curve(store.samples(run_id))
    if not curves:
        return "      no drift checks recorded"
    c = max(curves, key=lambda k: k.max_mm)
    warmed = ("" if c.joint_temp_c is None else
              f" while the joints warmed from {c.joint_temp_c[0]:.1f} to "
              f"{c.joint_temp_c[-1]:.1f} °C")
    flag = (f"above the {c.bound_mm:.3f} mm bound: the robot drifted during the capture"
            if c.flagged.any() else f"within the {c.bound_mm:.3f} mm bound")
    return (f"      drift checks: {len(c.drift_mm)} readings of the reference pose; it moved "
            f"up to {c.max_mm:.3f} mm over {c.t_s[-1] / 60:.0f} min{warmed} ({flag})")


def drift_found(added: list[str]) -> str | None:
    """:data:`HIDDEN` when the automatic diagnosis added a drift effect, else the first
    effect it added (None: none)."""
    if any(e.startswith(DRIFT_FAMILIES) for e in added):
        return HIDDEN
    return added[0] if added else None
