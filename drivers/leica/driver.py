"""Leica laser trackers behind the emScon TPI (TCP, port 700): ``emscon://host[:port]``.

:class:`EmsconTracker` is a :class:`~drivers.protocols.TrackerDriver` with the
optional capabilities :class:`~drivers.protocols.ReadyGate`,
:class:`~drivers.protocols.EnvironmentSensor`,
:class:`~drivers.protocols.ReflectorSelect`, :class:`~drivers.protocols.TwoFace` and
:class:`~drivers.protocols.SixDof` (6-DoF targets, :mod:`drivers.leica.six_dof`).

emScon keeps its settings (units, coordinate system, measurement mode and
time, reflector) on the server, shared by every client, and any client may
change them at any time. The driver therefore never assumes them: on connect
it sets mm / rad / °C / hPa / %RH, the right-handed rectangular system and the
stationary mode (6D stationary for a 6-DoF measurement); a status change
announcing that one of them changed makes the driver read it back (and set it
again if it differs) before the next measurement, and a result that arrived
after such a change is measured again.

Every wait has a deadline: silence is :class:`~drivers.errors.CommandTimeout`,
bytes that are not emScon :class:`~drivers.errors.ProtocolError`, and the link
is reopened before the next command after either. Status codes become typed
errors (:data:`STATUS_ERRORS`); unsolicited status changes and error packets
are queued as events (:meth:`EmsconTracker.events`).
"""

from __future__ import annotations

import collections
import logging
import time
from typing import Any

import numpy as np

from drivers.errors import (
    BeamBroken,
    CommandRejected,
    CommandTimeout,
    ConnectionLost,
    DriverError,
    NotReady,
    ProtocolError,
)
from drivers.leica import codec
from drivers.leica.enums import (
    ES_Command,
    ES_CoordinateSystemType,
    ES_LaserProcessorStatus,
    ES_MeasMode,
    ES_MeasurementStatusInfo,
    ES_ResultStatus,
    ES_SystemStatusChange,
    ES_TrackerProcessorStatus,
    ES_WeatherMonitorStatus,
    name_of,
)
from drivers.leica.link import PacketLink
from drivers.leica.metrology import EmsconCapabilities
from drivers.leica.probe_packets import ProbeStationaryResultT
from drivers.leica.six_dof import EmsconSixDof
from drivers.leica.units import DRIVER_UNITS
from drivers.protocols import (
    DeviceIdentity,
    Measurement,
    Reflector,
    TrackerStatus,
)

#: the packets themselves are logged by :mod:`drivers.leica.link` (DEBUG); here, at INFO: the
#: settings put, a resynchronisation, another client's changes, error statuses, a beam lost
log = logging.getLogger(__name__)

RS = ES_ResultStatus
SSC = ES_SystemStatusChange

#: ES_ResultStatus -> error class (anything else non-zero: DriverError)
STATUS_ERRORS: dict[int, type[DriverError]] = {
    RS.ES_RS_ServerBusy: NotReady,
    # NotImplemented, WrongParameter, WrongParameter1..7
    **{code: CommandRejected for code in range(2, 11)},
    **{code: CommandRejected for code in range(12, 23, 2)},  # ParameterNOutOfRangeNOK
    RS.ES_RS_WrongCurrentReflector: CommandRejected,
    RS.ES_RS_MeteoDataOutOfRange: CommandRejected,  # set_environment out of range
    RS.ES_RS_NoTrackerConnected: NotReady,
    RS.ES_RS_TrackerNotInitialized: NotReady,
    RS.ES_RS_MeasurementStatusNotReady: BeamBroken,
    RS.ES_RS_ADMStartUpBusy: NotReady,
    RS.ES_RS_NoStationaryResult: BeamBroken,
    RS.ES_RS_SensorNotLeveled: NotReady,
    RS.ES_RS_SensorNotWarmedUp: NotReady,
    RS.ES_RS_SensorNotStable: NotReady,
    RS.ES_RS_SystemNotReadyForMeasurement: NotReady,
    # 6-DoF: a tracker without a 6D camera, or a 6D measurement in face 2, cannot be
    # measured again at the next pose either; a probe not seen (well) at this pose can
    RS.ES_RS_NoMeasurementCamera: CommandRejected,
    RS.ES_RS_6DModeNotAllowed: CommandRejected,
    RS.ES_RS_6DMeasurementFace2NotAllowed: CommandRejected,
    RS.ES_RS_NoMeasurementProbe: BeamBroken,
    RS.ES_RS_NoActiveMeasurementProbe: BeamBroken,
    RS.ES_RS_Bad6DResult: BeamBroken,
}

#: status change -> the driver setting it puts in doubt
_SETTING_OF_CHANGE = {
    SSC.ES_SSC_UnitsChanged: "units",
    SSC.ES_SSC_CoordinateSystemTypeChanged: "coords",
    SSC.ES_SSC_MeasurementModeChanged: "mode",
    SSC.ES_SSC_StationaryModeParamsChanged: "stationary",
    SSC.ES_SSC_ReflectorChanged: "reflector",
}

DEFAULT_PORT = 700


def status_error(device: str, command: int, status: int, detail: str = "") -> DriverError:
    """The typed error for a non-OK ``status`` of ``command``; the message names both."""
    cls = STATUS_ERRORS.get(int(status), DriverError)
    text = f"status {int(status)} {name_of(ES_ResultStatus, status)}"
    return cls(device, name_of(ES_Command, command), f"{text} {detail}".strip())


def _logged(e: DriverError) -> DriverError:
    """``e``, logged at INFO (an error status the driver raises)."""
    log.info("%s", e)
    return e


class EmsconTracker(EmsconCapabilities, EmsconSixDof):
    """A Leica tracker behind an emScon server.

    Parameters
    ----------
    url : str
        ``emscon://host[:port]``, used in messages.
    host, port : str, int
        The server (emScon's default port is 700).
    auto_init : bool
        On :meth:`connect`, send ``Initialize`` when the tracker is not initialised.
    reflector : str or None
        Select this reflector (by name) on every connect.
    """

    def __init__(
        self, url: str, host: str, port: int = DEFAULT_PORT, *, auto_init: bool = True,
        reflector: str | None = None,
    ) -> None:
        self.url = url
        self.auto_init = auto_init
        self._dev = f"tracker {url}"
        self._link = PacketLink(host, port, self._dev)
        self._dirty = False
        self._user_closed = True
        self._confirmed: set[str] = set()
        self._stationary_ms: int | None = None
        self._want_reflector = reflector
        self._reflectors: list[Reflector] = []
        self._reflector_id: int | None = None
        self._face = 0
        self._meas_status: int | None = None
        #: the measurement mode the driver wants (stationary, or 6D stationary)
        self._mode = int(ES_MeasMode.ES_MM_Stationary)
        #: probe id -> name, learnt by GetProbes (None: not asked yet)
        self._probe_names: dict[int, str] | None = None
        self._events: collections.deque[tuple[float, str]] = collections.deque(maxlen=1000)

    # ----------------------------------------------------------- connection
    def connect(self, timeout: float = 5.0) -> None:
        """Open the link, set units / coordinates / mode, learn reflectors and face,
        and initialise the tracker if needed (``auto_init``)."""
        deadline = time.monotonic() + timeout
        self._user_closed = False
        self._link.open(timeout)
        try:
            self._handshake(deadline)
        except BaseException:
            self._link.close()
            raise
        if self.auto_init:
            st = self._call(codec.GetSystemStatusCT(), deadline)[0]
            if st.trackerProcessorStatus != ES_TrackerProcessorStatus.ES_TPS_Initialized:
                self.initialise(timeout=max(deadline - time.monotonic(), 0.01))

    def _handshake(self, deadline: float) -> None:
        self._dirty = False
        self._confirmed.clear()
        self._stationary_ms = None
        self._meas_status = None
        for key in ("units", "coords", "mode"):
            self._put(key, deadline)
        self._reflectors = self._read_reflectors(deadline)
        if self._want_reflector is not None:
            self._put("reflector", deadline)
        self._get("reflector", deadline)
        self._confirmed.add("reflector")
        self._face = self._call(codec.GetFaceCT(), deadline)[0].trackerFace
        log.info("%s: settings put (mm, rad, °C, hPa, %%RH, right-handed, mode %s); %d "
                 "reflectors, reflector %s, face %d", self._dev, self._mode,
                 len(self._reflectors), self._reflector_id, self._face)

    def close(self) -> None:
        """Close the link (idempotent)."""
        self._user_closed = True
        self._link.close()

    def __enter__(self) -> EmsconTracker:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    @property
    def connected(self) -> bool:
        """Whether the link is open."""
        return self._link.is_open

    def _resync(self, deadline: float) -> None:
        """Reopen the link after a timeout or garbage (stale answers may be in flight)."""
        if self._dirty and not self._user_closed:
            log.info("%s: reopening the link after a timeout or garbage", self._dev)
            self._link.open(max(deadline - time.monotonic(), 0.01))
            self._handshake(deadline)

    # ------------------------------------------------------------- plumbing
    def _send(self, packet: codec.Packet, name: str, deadline: float) -> None:
        try:
            self._link.send(packet, name, deadline)
        except ConnectionLost:
            self._dirty = True
            raise

    def _next(self, deadline: float, command: str,
              beam_lost: bool = False) -> codec.Packet | codec.UnknownPacket:
        try:
            packet = self._link.read(deadline, command)
        except (ProtocolError, ConnectionLost):
            self._dirty = True
            raise
        if packet is None:
            self._dirty = True
            log.info("%s: %s: no answer in time%s", self._dev, command,
                     " (beam lost)" if beam_lost else "")
            if beam_lost:
                raise BeamBroken(self._dev, command, "beam lost (MeasStatus_NotReady), no result")
            raise CommandTimeout(self._dev, command, "no answer in time")
        return packet

    def _call(self, packet: codec.Packet, deadline: float,
              answers: int = 1) -> list[codec.Packet]:
        """Send a command; return its ``answers`` answer packets (OK status), handling
        unsolicited packets that arrive meanwhile."""
        command = int(packet.command)
        name = name_of(ES_Command, command)
        self._send(packet, name, deadline)
        out: list[codec.Packet] = []
        while len(out) < answers:
            p = self._next(deadline, name)
            if isinstance(p, codec.AnswerRT | codec.BasicCommandRT) and p.command == command:
                if p.status != RS.ES_RS_AllOK:
                    raise _logged(status_error(self._dev, command, p.status))
                out.append(p)
                if isinstance(p, codec.GetReflectorsRT):
                    answers = max(1, p.iTotalReflectors)
            elif isinstance(p, codec.ErrorResponseT) and p.command == command:
                raise _logged(status_error(self._dev, command, p.status))
            else:
                self._unsolicited(p)
        return out

    def _unsolicited(self, p: codec.Packet | codec.UnknownPacket) -> None:
        now = time.time()
        if isinstance(p, codec.SystemStatusChangeT):
            change = p.systemStatusChange
            self._events.append((now, name_of(ES_SystemStatusChange, change)))
            key = _SETTING_OF_CHANGE.get(change)
            if key is not None:
                log.debug("%s: %s: the %s setting is read back before the next "
                          "measurement", self._dev, name_of(ES_SystemStatusChange, change), key)
                self._confirmed.discard(key)
            if change in (SSC.ES_SSC_MeasStatus_NotReady, SSC.ES_SSC_MeasStatus_Busy,
                          SSC.ES_SSC_MeasStatus_Ready):
                self._meas_status = change
            elif change == SSC.ES_SSC_IsFace1:
                self._face = 1
            elif change == SSC.ES_SSC_IsFace2:
                self._face = 2
        elif isinstance(p, codec.ErrorResponseT):
            self._events.append((now, f"error {name_of(ES_Command, p.command)}: status "
                                      f"{p.status} {name_of(ES_ResultStatus, p.status)}"))
        elif isinstance(p, codec.AnswerRT | codec.BasicCommandRT):
            pass  # a late answer to a command given up on
        else:
            self._events.append((now, f"ignored {type(p).__name__}"))

    # ------------------------------------------------------------- settings
    def _wanted(self, key: str, stationary_ms: int | None = None) -> Any:
        if key == "units":
            return tuple(int(u) for u in DRIVER_UNITS)
        if key == "coords":
            return int(ES_CoordinateSystemType.ES_CS_RHR)
        if key == "mode":
            return self._mode
        if key == "stationary":
            if stationary_ms is None:
                raise ValueError("the stationary setting needs its time (stationary_ms)")
            return (int(stationary_ms), 0)
        if key == "reflector":
            if self._want_reflector is None:
                raise ValueError("no reflector to select (reflector=None)")
            return self._resolve(self._want_reflector).id
        raise KeyError(key)

    def _put(self, key: str, deadline: float, stationary_ms: int | None = None) -> None:
        want = self._wanted(key, stationary_ms)
        packet: codec.Packet
        if key == "units":
            names = ("lenUnitType", "angUnitType", "tempUnitType", "pressUnitType", "humUnitType")
            packet = codec.SetUnitsCT(**dict(zip(names, want, strict=True)))
        elif key == "coords":
            packet = codec.SetCoordinateSystemTypeCT(coordSysType=want)
        elif key == "mode":
            packet = codec.SetMeasurementModeCT(measMode=want)
        elif key == "stationary":
            packet = codec.SetStationaryModeParamsCT(lMeasTime=want[0], bUseADM=want[1])
            self._stationary_ms = want[0]
        else:
            packet = codec.SetReflectorCT(iInternalReflectorId=want)
            self._reflector_id = want
        self._call(packet, deadline)
        self._confirmed.add(key)

    def _get(self, key: str, deadline: float) -> Any:
        if key == "units":
            p = self._call(codec.GetUnitsCT(), deadline)[0]
            return (p.lenUnitType, p.angUnitType, p.tempUnitType, p.pressUnitType, p.humUnitType)
        if key == "coords":
            return self._call(codec.GetCoordinateSystemTypeCT(), deadline)[0].coordSysType
        if key == "mode":
            return self._call(codec.GetMeasurementModeCT(), deadline)[0].measMode
        if key == "stationary":
            p = self._call(codec.GetStationaryModeParamsCT(), deadline)[0]
            return (p.lMeasTime, p.bUseADM)
        rid = self._call(codec.GetReflectorCT(), deadline)[0].iInternalReflectorId
        self._reflector_id = rid
        return rid

    def _ensure(self, deadline: float, stationary_ms: int) -> bool:
        """Make the server's settings the driver's; True when any had been changed."""
        changed = False
        keys = ["units", "coords", "mode", "stationary"]
        if self._want_reflector is not None:
            keys.append("reflector")
        elif "reflector" not in self._confirmed:  # someone else chose one: learn which
            self._get("reflector", deadline)
            self._confirmed.add("reflector")
        for key in keys:
            if key == "stationary" and self._stationary_ms != stationary_ms:
                self._put(key, deadline, stationary_ms)
                continue
            if key in self._confirmed:
                continue
            if self._get(key, deadline) != self._wanted(key, stationary_ms):
                log.info("%s: the server's %s setting was changed: set again", self._dev, key)
                self._put(key, deadline, stationary_ms)
                changed = True
            self._confirmed.add(key)
        return changed

    # ------------------------------------------------------------- commands
    def status(self, timeout: float = 1.0) -> TrackerStatus:
        """GetSystemStatus + GetMeasurementStatusInfo: initialised, warmed up, reflector found."""
        deadline = time.monotonic() + timeout
        self._resync(deadline)
        st = self._call(codec.GetSystemStatusCT(), deadline)[0]
        info = self._call(codec.GetMeasurementStatusInfoCT(), deadline)[0].lMeasurementStatusInfo
        found = bool(info & ES_MeasurementStatusInfo.ES_MSI_ReflectorFound)
        return TrackerStatus(
            connected=True,
            initialised=st.trackerProcessorStatus == ES_TrackerProcessorStatus.ES_TPS_Initialized,
            warmed_up=st.laserStatus == ES_LaserProcessorStatus.ES_LPS_LaserReady,
            beam_ok=found,
            target_present=found,
            message=(f"{name_of(ES_TrackerProcessorStatus, st.trackerProcessorStatus)} "
                     f"{name_of(ES_LaserProcessorStatus, st.laserStatus)} "
                     f"{name_of(ES_WeatherMonitorStatus, st.weatherMonitorStatus)} "
                     f"serial {st.lTrackerSerialNumber}"),
            timestamp=time.time(),
        )

    def identify(self, timeout: float = 2.0) -> DeviceIdentity:
        """GetSystemSoftwareVersion + GetSystemStatus: the emScon server's software version
        (firmware) and the tracker's serial number. A cellcal simulator's version names it
        (``cellcal sim ...``)."""
        deadline = time.monotonic() + timeout
        self._resync(deadline)
        version = codec.wstring(self._call(codec.GetSystemSoftwareVersionCT(), deadline)[0]
                                .cSoftwareVersion)
        st = self._call(codec.GetSystemStatusCT(), deadline)[0]
        return DeviceIdentity("tracker", "emScon tracker", str(st.lTrackerSerialNumber),
                              version, simulator=version.startswith("cellcal sim"))

    def initialise(self, timeout: float = 30.0) -> None:
        """``Initialize``: home the tracker (needed once per power-up)."""
        deadline = time.monotonic() + timeout
        self._resync(deadline)
        self._call(codec.InitializeCT(), deadline)

    def measure(self, duration_s: float = 0.5, timeout: float = 10.0) -> Measurement:
        """One stationary measurement of ``duration_s`` s (one StartMeasurement).

        Returns xyz and std in mm (tracker frame, right-handed), the covariance
        when the server sends SingleMeasResult2, the air the tracker used
        (``env``), the reflector and face. ``n`` is 1: emScon does not report
        how many samples it averaged.
        """
        return self._measure_in(ES_MeasMode.ES_MM_Stationary, duration_s,
                                time.monotonic() + timeout)

    def _use_mode(self, mode: int) -> None:
        """Want ``mode`` from now on (read back and set before the next measurement)."""
        if self._mode != int(mode):
            self._mode = int(mode)
            self._confirmed.discard("mode")

    def _measure_in(self, mode: int, duration_s: float, deadline: float) -> Measurement:
        """One measurement in ``mode`` (ES_MeasMode) of ``duration_s`` s, by ``deadline``."""
        ms = max(1, int(round(duration_s * 1000.0)))
        for _ in range(2):
            self._resync(deadline)
            self._use_mode(mode)
            self._ensure(deadline, ms)
            m, suspect = self._measure_once(deadline)
            if not suspect or not self._ensure(deadline, ms):
                return m
            # another client changed a setting during the measurement: measure again
            log.info("%s: a setting changed during the measurement: measuring again",
                     self._dev)
        raise NotReady(self._dev, "ES_C_StartMeasurement",
                       "another client keeps changing the server's settings")

    def _measure_once(self, deadline: float) -> tuple[Measurement, bool]:
        command = ES_Command.ES_C_StartMeasurement
        name = command.name
        self._send(codec.StartMeasurementCT(), name, deadline)
        before = set(self._confirmed)
        self._meas_status = None
        while True:
            lost = self._meas_status == SSC.ES_SSC_MeasStatus_NotReady
            p = self._next(deadline, name, beam_lost=lost)
            if isinstance(p, codec.AnswerRT | codec.BasicCommandRT) and p.command == command:
                if p.status != RS.ES_RS_AllOK:
                    raise _logged(status_error(self._dev, command, p.status))
            elif isinstance(p, codec.ErrorResponseT) and p.command == command:
                raise _logged(status_error(self._dev, command, p.status))
            elif isinstance(p, codec.SingleMeasResultT | codec.SingleMeasResult2T
                            | ProbeStationaryResultT):
                if p.status != RS.ES_RS_AllOK:
                    raise _logged(status_error(self._dev, command, p.status))
                if self._meas_status == SSC.ES_SSC_MeasStatus_NotReady:
                    log.info("%s: beam lost during the measurement", self._dev)
                    raise BeamBroken(self._dev, name, "beam lost during the measurement "
                                     "(MeasStatus_NotReady before the result)")
                return self._to_measurement(p), self._confirmed != before
            else:
                self._unsolicited(p)

    def _to_measurement(self, p: codec.Packet) -> Measurement:
        if isinstance(p, ProbeStationaryResultT):
            return self._to_pose(p)
        xyz = np.array([p.dVal1, p.dVal2, p.dVal3], float)
        std = np.array([p.dStd1, p.dStd2, p.dStd3], float)
        if not (np.all(np.isfinite(xyz)) and np.all(np.isfinite(std))):
            raise ProtocolError(self._dev, "ES_C_StartMeasurement", "non-finite result")
        covar = None
        if isinstance(p, codec.SingleMeasResult2T):
            covar = (p.dCovar12, p.dCovar13, p.dCovar23)
        return Measurement(**self._fields(p, xyz, std, covar))

    def _fields(self, p: codec.Packet, xyz: np.ndarray, std: np.ndarray,
                covar: tuple[float, float, float] | None = None) -> dict[str, Any]:
        """The :class:`Measurement` fields of a result ``p`` (3D or 6D): ``xyz``, ``std``
        (mm), the covariance from ``covar`` (the 12, 13, 23 terms, or None), the air of
        ``p``, the reflector selected and the face."""
        cov = None
        if covar is not None:
            cov = np.diag(std**2)
            cov[0, 1] = cov[1, 0] = covar[0]
            cov[0, 2] = cov[2, 0] = covar[1]
            cov[1, 2] = cov[2, 1] = covar[2]
        ref = next((r.name for r in self._reflectors if r.id == self._reflector_id), "")
        return dict(xyz=xyz, std=std, n=1, timestamp=time.time(),
                    env={"temp_c": p.dTemperature, "pressure_hpa": p.dPressure,
                         "humidity_pct": p.dHumidity},
                    cov=cov, reflector=ref, face=int(self._face))

    # --------------------------------------------------------------- events
    def events(self, poll_s: float = 0.0) -> list[tuple[float, str]]:
        """Unsolicited status changes and errors so far, oldest first, as (epoch s, name);
        clears the queue. ``poll_s`` > 0 first reads the link for that long."""
        if poll_s > 0 and self._link.is_open and not self._dirty:
            deadline = time.monotonic() + poll_s
            while True:
                try:
                    p = self._link.read(deadline, "poll")
                except (ProtocolError, ConnectionLost):
                    self._dirty = True
                    raise
                if p is None:
                    break
                self._unsolicited(p)
        out = list(self._events)
        self._events.clear()
        return out
