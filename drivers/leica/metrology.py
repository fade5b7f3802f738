"""The metrology capabilities of :class:`~drivers.leica.driver.EmsconTracker`.

A mixin, apart so that each module stays readable: the ready gate
(GetSystemStatus + GetMeasurementStatusInfo), the environment
(Get/SetEnvironmentParams), reflectors by name (GetReflectors, Get/SetReflector)
and two-face measurement (ChangeFace, GetFace). It uses the driver's plumbing
(``_call``, ``_resync``, ``_get``/``_put`` of settings) and its state.
"""

from __future__ import annotations

import time
from typing import TYPE_CHECKING, Any

import numpy as np

from drivers.errors import CommandRejected, ProtocolError
from drivers.leica import codec
from drivers.leica.enums import (
    ES_LaserProcessorStatus,
    ES_MeasurementStatusInfo,
    ES_TargetType,
    ES_TrackerFace,
    ES_TrackerProcessorStatus,
    ES_WeatherMonitorStatus,
    name_of,
)
from drivers.protocols import Environment, Measurement, Readiness, Reflector, measure_both_faces


class EmsconCapabilities:
    """ReadyGate, EnvironmentSensor, ReflectorSelect and TwoFace over emScon."""

    # what the driver (:class:`~drivers.leica.driver.EmsconTracker`) gives this mixin
    _dev: str
    _confirmed: set[str]
    _face: int
    _reflectors: list[Reflector]
    _want_reflector: str | None
    if TYPE_CHECKING:
        def _resync(self, deadline: float) -> None: ...

        def _call(self, packet: codec.Packet, deadline: float,
                  answers: int = 1) -> list[codec.Packet]: ...

        def _get(self, key: str, deadline: float) -> Any: ...

        def _put(self, key: str, deadline: float, stationary_ms: int | None = None) -> None: ...

        def _wanted(self, key: str, stationary_ms: int | None = None) -> Any: ...

        def measure(self, duration_s: float = 0.5, timeout: float = 10.0) -> Measurement: ...

    def ready(self, timeout: float = 2.0) -> Readiness:
        """The ready gate: initialised, warmed up, weather station reporting, reflector found."""
        deadline = time.monotonic() + timeout
        self._resync(deadline)
        st = self._call(codec.GetSystemStatusCT(), deadline)[0]
        info = self._call(codec.GetMeasurementStatusInfoCT(), deadline)[0].lMeasurementStatusInfo
        return Readiness.of(
            initialised=st.trackerProcessorStatus == ES_TrackerProcessorStatus.ES_TPS_Initialized,
            warmed_up=st.laserStatus == ES_LaserProcessorStatus.ES_LPS_LaserReady,
            weather_station=st.weatherMonitorStatus != ES_WeatherMonitorStatus.ES_WMS_NotConnected,
            target=bool(info & ES_MeasurementStatusInfo.ES_MSI_ReflectorFound),
            detail={"initialised": name_of(ES_TrackerProcessorStatus, st.trackerProcessorStatus),
                    "warmed_up": name_of(ES_LaserProcessorStatus, st.laserStatus),
                    "weather_station": name_of(ES_WeatherMonitorStatus,
                                               st.weatherMonitorStatus)},
        )

    def check_ready(self, timeout: float = 2.0) -> Readiness:
        """:meth:`ready`, raising NotReady naming every failed check."""
        return self.ready(timeout).raise_if_not_ok(self._dev)

    def environment(self, timeout: float = 2.0) -> Environment:
        """GetEnvironmentParams (°C, hPa, %RH) and whether a weather station supplies them."""
        deadline = time.monotonic() + timeout
        self._resync(deadline)
        self._ensure_units(deadline)
        st = self._call(codec.GetSystemStatusCT(), deadline)[0]
        p = self._call(codec.GetEnvironmentParamsCT(), deadline)[0]
        station = st.weatherMonitorStatus != ES_WeatherMonitorStatus.ES_WMS_NotConnected
        return Environment(p.dTemperature, p.dPressure, p.dHumidity,
                           "station" if station else "manual")

    def set_environment(self, temp_c: float, pressure_hpa: float, humidity_pct: float,
                        timeout: float = 2.0) -> None:
        """SetEnvironmentParams: the air the tracker corrects its distances for."""
        values = np.array([temp_c, pressure_hpa, humidity_pct], float)
        if not np.all(np.isfinite(values)):
            raise CommandRejected(self._dev, "ES_C_SetEnvironmentParams", "non-finite value")
        deadline = time.monotonic() + timeout
        self._resync(deadline)
        self._ensure_units(deadline)
        self._call(codec.SetEnvironmentParamsCT(
            dTemperature=float(temp_c), dPressure=float(pressure_hpa),
            dHumidity=float(humidity_pct)), deadline)

    def _ensure_units(self, deadline: float) -> None:
        if "units" not in self._confirmed:
            if self._get("units", deadline) != self._wanted("units"):
                self._put("units", deadline)
            self._confirmed.add("units")

    def _read_reflectors(self, deadline: float) -> list[Reflector]:
        out = []
        for p in self._call(codec.GetReflectorsCT(), deadline):
            out.append(Reflector(
                name=codec.wstring(p.cReflectorName), id=int(p.iInternalReflectorId),
                target_type=name_of(ES_TargetType, p.targetType),
                surface_offset_mm=float(p.dSurfaceOffset),  # mm: units are set first
            ))
        return out

    def _resolve(self, name: str) -> Reflector:
        for r in self._reflectors:
            if r.name.casefold() == name.casefold():
                return r
        known = ", ".join(repr(r.name) for r in self._reflectors) or "none"
        raise CommandRejected(self._dev, "ES_C_SetReflector",
                              f"no reflector {name!r}; the tracker knows {known}")

    def reflectors(self, timeout: float = 2.0) -> list[Reflector]:
        """GetReflectors: every reflector the tracker knows."""
        deadline = time.monotonic() + timeout
        self._resync(deadline)
        self._ensure_units(deadline)
        self._reflectors = self._read_reflectors(deadline)
        return list(self._reflectors)

    def reflector(self, timeout: float = 2.0) -> Reflector:
        """GetReflector: the reflector in use."""
        deadline = time.monotonic() + timeout
        self._resync(deadline)
        rid = self._get("reflector", deadline)
        for r in self._reflectors:
            if r.id == rid:
                return r
        return Reflector(name=f"reflector {rid}", id=rid)

    def set_reflector(self, name: str, timeout: float = 2.0) -> Reflector:
        """SetReflector by name (resolved through GetReflectors); kept across reconnects."""
        deadline = time.monotonic() + timeout
        self._resync(deadline)
        if not any(r.name.casefold() == name.casefold() for r in self._reflectors):
            self._reflectors = self._read_reflectors(deadline)
        r = self._resolve(name)
        self._want_reflector = r.name
        self._put("reflector", deadline)
        return r

    def face(self, timeout: float = 2.0) -> int:
        """GetFace: 1 or 2."""
        deadline = time.monotonic() + timeout
        self._resync(deadline)
        f = self._call(codec.GetFaceCT(), deadline)[0].trackerFace
        self._face = int(f)
        if f not in (ES_TrackerFace.ES_TF_Face1, ES_TrackerFace.ES_TF_Face2):
            raise ProtocolError(self._dev, "ES_C_GetFace", f"face {f}")
        return self._face

    def change_face(self, timeout: float = 30.0) -> int:
        """ChangeFace; returns the new face."""
        deadline = time.monotonic() + timeout
        self._resync(deadline)
        self._call(codec.ChangeFaceCT(), deadline)
        return self.face(max(deadline - time.monotonic(), 0.01))

    def measure_faces(self, duration_s: float = 0.5,
                      timeout: float = 60.0) -> tuple[Measurement, Measurement]:
        """Measure in this face, ChangeFace, measure again: ``(face 1, face 2)``."""
        return measure_both_faces(self, duration_s, timeout)
