"""The thermal state a calibration was made at, and the one a compensation is made for.

A model with a drift effect (:mod:`calibration.effects.drift`, or ``thermal`` over the air
temperature) predicts a different robot at another temperature or time. Its parameters
mean something only with the state they were fitted against, so params.json records it
(``thermal``, :func:`thermal_record`) and a reloaded model uses it
(:func:`apply_thermal_record`). The record has a ``version`` of its own
(:data:`RECORD_VERSION`; a reader refuses a newer one, a params.json without the record
still loads):

- ``time_window_s`` [t0, t1]: the calibration rows' first and last time (s, epoch). The
  time effects (``time_growthK``, ``base_driftK``) scale time to it; without it a reloaded
  model would measure time against the new data's own span.
- ``temp_ref_c``: the temperature the rises are taken from (``temp_ref_c`` metadata,
  default 20 °C).
- ``warm_state``: the state at the end of the capture, the warmest the calibration saw
  (the median over the last tenth of the calibration rows in time): ``t_s`` (the window's
  end), ``joint_temp_c`` (N values) and ``temp_c`` where the data have them.

A compensation (:func:`target_state`) uses each target's own ``joint_temp1..N``,
``temp_c`` and ``t_s`` where the targets CSV gives them, else the calibration's warm state:
a program runs on a robot that has warmed up, not on the cold one the capture began with.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, Any

import numpy as np

from ..data.columns import column
from ..data.dataset import Dataset
from ..effects.drift import DEFAULT_TEMP_REF_C, DRIFT, DRIFT_WINDOW_KEY
from ..errors import ParamsError

if TYPE_CHECKING:
    from ..effects.base import Effect
    from .error_model import ErrorModel
    from .identify import Fit

#: the effect families that depend on the thermal state (or the time it drifts over)
THERMAL_FAMILIES = frozenset(DRIFT) | {"thermal"}
#: what each family reads from a target: a column of :class:`~calibration.data.dataset.Dataset`
_NEEDS = {"thermal_growth": "joint_temp", "thermal_zero": "joint_temp",
          "time_growth": "t_s", "base_drift": "t_s", "thermal": "temp_c"}
#: the version of the ``thermal`` record written; readers take 1..RECORD_VERSION
RECORD_VERSION = 1
#: the share of the calibration rows (the last in time) whose median is the warm state
WARM_SHARE = 0.1


def thermal_effects(error_model: ErrorModel) -> list[Effect]:
    """The effects of a model that depend on the thermal state."""
    return [e for e in error_model.effects if e.family in THERMAL_FAMILIES]


def thermal_record(fit: Fit) -> dict[str, Any] | None:
    """The ``thermal`` record of params.json for a fit with a thermal effect, else None."""
    effects = thermal_effects(fit.error_model)
    if not effects:
        return None
    d: Dataset = fit.data
    out: dict[str, Any] = {"version": RECORD_VERSION,
                           "temp_ref_c": float(d.meta.get("temp_ref_c", DEFAULT_TEMP_REF_C))}
    window = d.meta.get(DRIFT_WINDOW_KEY)
    if window is not None:
        out["time_window_s"] = [float(v) for v in window.split(",")]
    order = np.argsort(d.t_s, kind="stable") if d.t_s is not None else np.arange(d.n)
    last = order[-max(1, math.ceil(WARM_SHARE * d.n)):]
    warm: dict[str, Any] = {}
    if d.t_s is not None:
        warm["t_s"] = out.get("time_window_s", [0.0, float(d.t_s.max())])[1]
    if d.joint_temp is not None:
        warm["joint_temp_c"] = [float(v) for v in np.median(d.joint_temp[last], axis=0)]
    if d.temp_c is not None:
        warm["temp_c"] = float(np.median(d.temp_c[last]))
    out["warm_state"] = warm
    return out


def check_thermal_record(rec: Any, n_joints: int, source: str) -> dict | None:
    """The ``thermal`` record read back strictly (ParamsError naming the file and key)."""
    if rec is None:
        return None
    where = f"{source}: thermal"
    if not isinstance(rec, dict):
        raise ParamsError(f"{where}: not an object")

    def number(v: Any, key: str) -> float:
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
            raise ParamsError(f"{where}.{key}: {v!r} is not a finite number")
        return float(v)

    version = rec.get("version", RECORD_VERSION)
    if isinstance(version, bool) or not isinstance(version, int) or version < 1:
        raise ParamsError(f"{where}.version: {version!r} is not a version number")
    if version > RECORD_VERSION:
        raise ParamsError(f"{where}.version: {version} is newer than this cellcal reads "
                          f"({RECORD_VERSION}); update cellcal")
    out: dict[str, Any] = {"version": version,
                           "temp_ref_c": number(rec.get("temp_ref_c", DEFAULT_TEMP_REF_C),
                                                "temp_ref_c")}
    if "time_window_s" in rec:
        w = rec["time_window_s"]
        if not isinstance(w, list) or len(w) != 2:
            raise ParamsError(f"{where}.time_window_s: give [t0, t1] (s)")
        t0, t1 = (number(v, "time_window_s") for v in w)
        if t1 < t0:
            raise ParamsError(f"{where}.time_window_s: ends ({t1:g}) before it starts ({t0:g})")
        out["time_window_s"] = [t0, t1]
    warm = rec.get("warm_state", {})
    if not isinstance(warm, dict):
        raise ParamsError(f"{where}.warm_state: not an object")
    out["warm_state"] = {}
    for key in ("t_s", "temp_c"):
        if key in warm:
            out["warm_state"][key] = number(warm[key], f"warm_state.{key}")
    if "joint_temp_c" in warm:
        temps = warm["joint_temp_c"]
        if not isinstance(temps, list) or len(temps) != n_joints:
            raise ParamsError(f"{where}.warm_state.joint_temp_c: give {n_joints} temperatures")
        out["warm_state"]["joint_temp_c"] = [number(v, "warm_state.joint_temp_c")
                                             for v in temps]
    return out


def apply_thermal_record(effects: list[Any], rec: dict[str, Any] | None) -> None:
    """Give the effects of a reloaded model the state they were calibrated against: the
    time window and the reference temperature (None: a file without the record, whose
    effects measure time against the data they meet, as before)."""
    if rec is None:
        return
    for e in effects:
        if hasattr(e, "calibrated_window") and "time_window_s" in rec:
            e.calibrated_window = tuple(rec["time_window_s"])
        if hasattr(e, "temp_ref_c"):
            e.temp_ref_c = rec["temp_ref_c"]


def target_state(error_model: ErrorModel, rec: dict | None, columns: dict, n: int
                 ) -> tuple[dict, dict | None]:
    """The columns a compensation binds (each target's own, else the warm state) and
    the thermal state used, for the user: ``{"source": "targets"|"calibration's warm
    state"|"mixed", "joint_temp_c": [lo, hi] ..., "t_s": ..., "temp_c": ...}``; (columns,
    None) for a model without thermal effects. ParamsError when the targets lack a column
    and the calibration recorded no state to fill it (a params.json before version 3)."""
    needs = sorted({_NEEDS[e.family] for e in thermal_effects(error_model)})
    if not needs:
        return columns, None
    warm = (rec or {}).get("warm_state", {})
    warm_key = {"joint_temp": "joint_temp_c", "t_s": "t_s", "temp_c": "temp_c"}
    out, given, filled = dict(columns), [], []
    for col in needs:
        if col in columns:
            given.append(col)
            continue
        if warm_key[col] not in warm:
            raise ParamsError(
                f"the calibration's {', '.join(e.label for e in thermal_effects(error_model))}"
                f" needs {_column_names(col)} in the targets: the params file records no warm "
                "state to use instead (calibrate again with this cellcal)")
        value = np.asarray(warm[warm_key[col]], float)
        out[col] = np.tile(value, (n, 1)) if value.ndim else np.full(n, float(value))
        filled.append(col)
    state: dict[str, Any] = {"source": ("targets" if not filled else
                                        "calibration's warm state" if not given else "mixed"),
                             "from_targets": given, "from_calibration": filled}
    if "joint_temp" in out:
        jt = np.asarray(out["joint_temp"], float)
        state["joint_temp_c"] = [float(jt.min()), float(jt.max())]
    if "temp_c" in out:
        state["temp_c"] = [float(np.min(out["temp_c"])), float(np.max(out["temp_c"]))]
    if "t_s" in out:
        state["t_s"] = [float(np.min(out["t_s"])), float(np.max(out["t_s"]))]
        if rec and "time_window_s" in rec:
            state["time_window_s"] = rec["time_window_s"]
    return out, state


def _column_names(col: str) -> str:
    """The CSV column(s) of Dataset field ``col``, as a message names them."""
    return ", ".join(c.replace("{j}", "1..N") for c in column(col).csv)
