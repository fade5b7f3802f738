"""The tracker's checks before a run: reflector, air, ready gate, two faces.

:func:`check_tracker` runs them on a connected tracker, using each optional capability
the tracker offers (:mod:`drivers.protocols`), in this order:

1. **reflector** (``TrackerSetup.reflector``): resolved by name (case-insensitive)
   through the tracker's list and selected (:class:`~drivers.protocols.ReflectorSelect`);
   an unknown name is refused listing the known ones, a tracker that cannot select one
   refuses the option.
2. **air** (``TrackerSetup.meteo``): a tracker whose weather station reports the air
   corrects with the station's values, so ``--meteo`` is refused there (nothing to
   force: the station's values win); without a station the values are set
   (:class:`~drivers.protocols.EnvironmentSensor`) and read back. Without a station and
   without ``--meteo`` the ready gate fails.
3. **ready gate** (:class:`~drivers.protocols.ReadyGate`): initialised, warmed up, the
   air known (a station, or ``--meteo``), the beam on the reflector.
4. **two faces** (:class:`~drivers.protocols.TwoFace`, only at the start of a run): the
   point where the robot stands is measured in both faces (the tracker is turned back
   to the face it was in). A difference beyond ``two_face_tol_mm`` plus the
   difference's own noise (2σ from the reported std of both measurements) refuses the
   run: the tracker needs compensation.

Each refusal is a :class:`~daq.errors.TrackerRefused` (exit code 2 at the command line)
naming the check and what to do; nothing has been stored then. Transient driver errors
(beam, timeout, dropped link) are retried with the executor's retries and backoff
after a reconnect. What was found is a :class:`~daq.run_context.TrackerCheck`, stored
with the run's context.

Units: mm, °C, hPa, %RH.
"""

from __future__ import annotations

import logging
import time

import numpy as np

from drivers.errors import DriverError
from drivers.protocols import (
    EnvironmentSensor,
    Readiness,
    ReadyGate,
    ReflectorSelect,
    SixDof,
    TwoFace,
)

from .errors import TrackerRefused
from .run_context import ExecutorOptions, TrackerCheck, TrackerSetup, TwoFaceCheck

log = logging.getLogger(__name__)

#: the two-face difference's allowance for noise, in standard deviations
TWO_FACE_K = 2.0

#: how :meth:`Readiness.of` words a missing weather station (the device's detail follows)
_STATION_WORDS = Readiness.of(True, True, False).problems[0]
#: what the capture says instead
NO_STATION = ("no weather station reports the air: connect one, or give the air measured "
              "at the cell with --meteo T,P,H (°C, hPa, %RH)")


def check_tracker(tracker, setup: TrackerSetup, options: ExecutorOptions | None = None, *,
                  two_face: bool = True) -> TrackerCheck:
    """Set up and check a connected tracker (the module docstring); what was found.

    ``two_face`` False skips the two-face check whatever ``setup`` asks (a resumed run).
    Raises :class:`~daq.errors.TrackerRefused`.
    """
    o = options or ExecutorOptions()
    attempt = 0
    while True:
        attempt += 1
        try:
            return _check(tracker, setup, o, two_face)
        except TrackerRefused as e:
            log.info("tracker refused: %s", e)
            raise
        except DriverError as e:
            if not e.transient or attempt > o.max_retries:
                log.info("tracker check failed: %s", e)
                raise TrackerRefused(f"tracker check: {e}; nothing was stored") from e
            wait = min(o.backoff_s * 2 ** (attempt - 1), o.backoff_max_s)
            log.info("tracker check: %s; retrying in %.2f s after reconnecting", e, wait)
            time.sleep(wait)
            try:
                tracker.close()
                tracker.connect(timeout=o.connect_timeout_s)
            except DriverError:
                pass  # counted as one more failed attempt by the next round


def _name(tracker) -> str:
    return f"tracker {getattr(tracker, 'url', '')}".strip()


def _check(tracker, setup: TrackerSetup, o: ExecutorOptions, two_face: bool) -> TrackerCheck:
    t = o.io_timeout_s + 1.0
    if o.six_dof and not isinstance(tracker, SixDof):
        raise TrackerRefused(f"{_name(tracker)} cannot measure a 6-DoF target's pose "
                             "(--six-dof); nothing was stored")
    reflector = _select_reflector(tracker, setup.reflector, t)
    readiness = tracker.ready(t) if isinstance(tracker, ReadyGate) else None
    env = tracker.environment(t) if isinstance(tracker, EnvironmentSensor) else None
    station = (readiness.weather_station if readiness is not None
               else None if env is None else env.source == "station")
    if setup.meteo is not None:
        env = _set_air(tracker, setup.meteo, station, env, t)
    problems: list[str] = []
    if readiness is not None:  # the station's own words are replaced by NO_STATION
        problems += [p for p in readiness.problems if not p.startswith(_STATION_WORDS)]
    if station is False and setup.meteo is None:
        problems.append(NO_STATION)
    if problems:
        raise TrackerRefused(f"{_name(tracker)} is not ready: {'; '.join(problems)}; "
                             "nothing was stored")
    faces = None
    if two_face and setup.two_face_check and isinstance(tracker, TwoFace):
        faces = _two_faces(tracker, setup.two_face_tol_mm, o)
    return TrackerCheck(
        ready=None if readiness is None else True,
        temp_c=None if env is None else float(env.temp_c),
        pressure_hpa=None if env is None else float(env.pressure_hpa),
        humidity_pct=None if env is None else float(env.humidity_pct),
        air_source=None if env is None else ("manual" if setup.meteo else env.source),
        reflector=reflector,
        face=tracker.face(t) if isinstance(tracker, TwoFace) else None,
        two_face=faces,
    )


def _select_reflector(tracker, name: str | None, timeout: float) -> str | None:
    """Select ``name`` (resolved through the tracker's list); the reflector in use."""
    if not isinstance(tracker, ReflectorSelect):
        if name is not None:
            raise TrackerRefused(f"--reflector: {_name(tracker)} cannot select a reflector "
                                 "(its protocol has no reflector list): select it at the "
                                 "tracker and drop --reflector")
        return None
    if name is None:
        return tracker.reflector(timeout).name
    known = tracker.reflectors(timeout)
    match = [r for r in known if r.name.casefold() == name.strip().casefold()]
    if not match:
        names = ", ".join(repr(r.name) for r in known) or "none"
        raise TrackerRefused(f"--reflector: {_name(tracker)} knows no reflector {name!r}; "
                             f"it knows {names}")
    return tracker.set_reflector(match[0].name, timeout).name


def _set_air(tracker, meteo, station: bool | None, env, timeout: float):
    """Give the tracker the air by hand; the environment it then reports."""
    if station:
        now = ("" if env is None else f" ({env.temp_c:.1f} °C, {env.pressure_hpa:.1f} hPa, "
               f"{env.humidity_pct:.0f} %RH)")
        raise TrackerRefused(f"--meteo: the weather station of {_name(tracker)} reports the "
                             f"air{now} and the tracker corrects with it: drop --meteo")
    if not isinstance(tracker, EnvironmentSensor):
        raise TrackerRefused(f"--meteo: {_name(tracker)} cannot be given the air (its "
                             "protocol has no environment command)")
    tracker.set_environment(*meteo, timeout=timeout)
    env = tracker.environment(timeout)
    got = np.array([env.temp_c, env.pressure_hpa, env.humidity_pct])
    if not np.allclose(got, meteo, atol=0.01, rtol=0):
        raise TrackerRefused(f"--meteo: {_name(tracker)} was given {tuple(meteo)} but reports "
                             f"{tuple(float(v) for v in got)}: check its environment settings")
    return env


def _two_faces(tracker, tol_mm: float, o: ExecutorOptions) -> TwoFaceCheck:
    """Measure where the robot stands in both faces, turn back; refuse beyond tolerance."""
    t = o.io_timeout_s + 1.0
    start = tracker.face(t)
    try:
        f1, f2 = tracker.measure_faces(o.measure_s, 2 * o.measure_timeout_s + 60.0)
    finally:
        if tracker.face(t) != start:
            tracker.change_face(60.0)
    noise = TWO_FACE_K * float(np.sqrt(np.sum(f1.std**2) + np.sum(f2.std**2)))
    check = TwoFaceCheck(diff_mm=float(np.linalg.norm(f1.xyz - f2.xyz)), tol_mm=tol_mm,
                         noise_mm=noise, distance_mm=float(np.linalg.norm(f1.xyz)))
    if not check.ok:
        raise TrackerRefused(
            f"two-face check: {_name(tracker)} measured the same point {check.diff_mm:.3f} mm "
            f"apart in its two faces at {check.distance_mm / 1000:.2f} m (allowed "
            f"{check.tol_mm:.3f} mm + {check.noise_mm:.3f} mm noise): the tracker needs "
            "compensation (its two-face / intermediate compensation), then capture again; "
            "nothing was stored")
    return check
