"""The simulated laser tracker behind Leica's emScon TPI, with the driver's own codec.

:class:`EmsconServer` serves a :class:`~sim_drivers.cell.SimCell`'s tracker on
loopback TCP as an emScon server would: binary packets of ``ES_C_API_Def.h``
(:mod:`drivers.leica.codec`), one answer per command (``GetReflectors``: one
per reflector), measurement results and status changes sent when they happen.

Like a real server it keeps its settings for every client, and they persist
across connections: units, coordinate system type, measurement mode,
stationary measuring time. A client that changes one changes it for all, and
every client (itself included) is told by a ``SystemStatusChangeT``, sent
before the answer to the change. A fresh server reports in metres,
degrees, °C, mbar (``units=`` to start otherwise).

Commands: GetSystemStatus, GetTrackerStatus, Initialize, Set/GetUnits,
Set/GetEnvironmentParams, Set/GetMeasurementMode (stationary, and 6D stationary
with a 6-DoF target on the tool: GetProbes, GetProbe and the 6D result are
:mod:`sim_drivers.emscon_probe`),
Set/GetCoordinateSystemType, Set/GetStationaryModeParams, Set/GetReflector,
GetReflectors, StartMeasurement, ChangeFace, GetFace,
GetMeasurementStatusInfo, GetSystemSoftwareVersion. Any other command is
answered with its own command number and ``ES_RS_NotImplemented``.

The cell's refusals carry the real codes: not initialised 39
(``ES_RS_TrackerNotInitialized``), not warmed up 10012
(``ES_RS_SensorNotWarmedUp``), no reflector in the beam 10004
(``ES_RS_MeasurementStatusNotReady``), target moving during the measurement
10009 (``ES_RS_NoStationaryResult``). The ``beam`` fault breaks the beam
after the measurement started: ``ES_SSC_MeasStatus_NotReady``, an
``ErrorResponseT`` with 10009, then ``ES_SSC_MeasStatus_Ready``. ``garbage``
sends bytes whose length prefix is no emScon length; ``slow``/``drop`` as for
every simulated server.

Coordinate systems other than RHR are the simulator's reading of the header's
names (LHRX/Y/Z: that axis negated; CCW/CCC: cylindrical (angle, radius, z);
SCW/SCC: spherical (horizontal angle, zenith angle, distance); "CW" angles
turn the other way), with standard deviations turned into the same
coordinates to first order; results in those systems are SingleMeasResultT,
in RHR/LHR SingleMeasResult2T (or SingleMeasResultT with ``result2=False``).
"""

from __future__ import annotations

import threading

import numpy as np

from drivers.leica import codec
from drivers.leica.enums import (
    ES_ADMStatus,
    ES_Command,
    ES_CoordinateSystemType,
    ES_DataType,
    ES_LaserProcessorStatus,
    ES_MeasMode,
    ES_MeasurementStatusInfo,
    ES_ResultStatus,
    ES_SystemStatusChange,
    ES_TargetType,
    ES_TrackerFace,
    ES_TrackerProcessorStatus,
    ES_TrackerStatus,
    ES_WeatherMonitorStatus,
)
from drivers.leica.framing import FrameReader
from drivers.leica.units import (
    PER_HPA,
    PER_MM,
    PER_RAD,
    SERVER_DEFAULT_UNITS,
    temp_from_c,
    temp_to_c,
    valid_units,
)
from sim_drivers.cell import CellRefused, SimCell
from sim_drivers.emscon_probe import ProbeCommands
from sim_drivers.faults import FaultInjector
from sim_drivers.line_server import LineServer
from sim_drivers.tracker_optics import TRACKER_REFLECTORS

C, RS, SSC, CS = ES_Command, ES_ResultStatus, ES_SystemStatusChange, ES_CoordinateSystemType

#: the cell's refusal names -> the status emScon reports
CELL_STATUS = {
    "NOT_INITIALISED": RS.ES_RS_TrackerNotInitialized,
    "NOT_WARMED_UP": RS.ES_RS_SensorNotWarmedUp,
    "NOT_STABLE": RS.ES_RS_NoStationaryResult,
    "BEAM_BROKEN": RS.ES_RS_MeasurementStatusNotReady,
    "NO_TARGET": RS.ES_RS_MeasurementStatusNotReady,
    "BAD_ARGUMENT": RS.ES_RS_WrongParameter1,
    "FACE2_6D": RS.ES_RS_6DMeasurementFace2NotAllowed,
    "NO_6DOF_TARGET": RS.ES_RS_NoMeasurementProbe,
}

#: the server's tracker serial number (GetSystemStatus)
SERIAL = 390123
VERSION = (3, 6, 999)

#: bytes a ``garbage`` fault sends: a length prefix far beyond any packet
GARBAGE = bytes([0xFF, 0xFF, 0xFF, 0x7F, 0x8F, 0x00, 0xFF, 0x1B, 0x23, 0x40, 0xC3, 0x28])


class _Framer(FrameReader):
    """The server side of the framing: requests are whole packets (bytes)."""


def to_coordinates(xyz: np.ndarray, std: np.ndarray, system: int, per_mm: float,
                   per_rad: float) -> tuple[np.ndarray, np.ndarray, bool]:
    """Tracker-frame mm → the server's coordinate system and units: (values, std,
    whether the system is rectangular)."""
    x, y, z = xyz
    if system in (CS.ES_CS_RHR, CS.ES_CS_LHRX, CS.ES_CS_LHRY, CS.ES_CS_LHRZ):
        sign = np.ones(3)
        if system != CS.ES_CS_RHR:
            sign[int(system) - 1] = -1.0
        return sign * xyz * per_mm, std * per_mm, True
    hz = float(np.arctan2(y, x))
    if system in (CS.ES_CS_CCW, CS.ES_CS_SCW):
        hz = -hz
    rho = float(np.hypot(x, y))
    r = float(np.linalg.norm(xyz))
    s = float(np.sqrt(np.mean(std**2)))
    if system in (CS.ES_CS_CCW, CS.ES_CS_CCC):
        values = np.array([hz * per_rad, rho * per_mm, z * per_mm])
        sd = np.array([s / max(rho, 1e-9) * per_rad, s * per_mm, std[2] * per_mm])
    else:
        v = float(np.arccos(np.clip(z / max(r, 1e-9), -1.0, 1.0)))
        values = np.array([hz * per_rad, v * per_rad, r * per_mm])
        sd = np.array([s / max(rho, 1e-9) * per_rad, s / max(r, 1e-9) * per_rad, s * per_mm])
    return values, sd, False


class EmsconSession(ProbeCommands):
    """One client connection; the settings live in the :class:`EmsconServer`."""

    def __init__(self, server: EmsconServer) -> None:
        self.server = server
        self.cell = server.cell
        self.conn = None

    def bind(self, server, conn) -> None:
        self.conn = conn

    # ------------------------------------------------------------- dispatch
    def handle(self, frame: bytes) -> list[bytes]:
        try:
            packet = codec.decode(frame, "server")
        except codec.DecodeError:
            return [codec.ErrorResponseT(command=C.ES_C_Unknown,
                                         status=RS.ES_RS_InvalidInputData).pack()]
        if packet.type != ES_DataType.ES_DT_Command:
            return [codec.ErrorResponseT(command=C.ES_C_Unknown,
                                         status=RS.ES_RS_InvalidInputData).pack()]
        handler = getattr(self, f"_{C(packet.command).name[5:]}", None) if (
            packet.command in C._value2member_map_) else None
        if handler is None:
            return [codec.BasicCommandRT(command=packet.command,
                                         status=RS.ES_RS_NotImplemented).pack()]
        replies, changes = handler(packet)
        if self.server.chatter:
            replies = [self.server.status_packet(SSC.ES_SSC_EnvironmentParamsChanged), *replies]
        self.server.remember_status(replies)
        # every client hears of a change before the answer goes out: a client that
        # learns of it (through another one's answer) and then measures cannot get
        # its result before the announcement
        for change in changes:
            self.server.status_change(change)
        return replies

    @staticmethod
    def _answer(cls, status: int = RS.ES_RS_AllOK, **fields) -> bytes:
        return cls(status=int(status), **fields).pack()

    # ------------------------------------------------------------- commands
    def _GetSystemStatus(self, p):  # noqa: N802 - named after ES_C_GetSystemStatus
        c = self.cell
        tps = (ES_TrackerProcessorStatus.ES_TPS_Initialized if c.tracker_initialised
               else ES_TrackerProcessorStatus.ES_TPS_CompensationSet)
        laser = (ES_LaserProcessorStatus.ES_LPS_LaserReady if c.tracker_warmed_up()
                 else ES_LaserProcessorStatus.ES_LPS_LaserHeatingUp)
        wms = (ES_WeatherMonitorStatus.ES_WMS_ReadAndCalculateRefractions if c.weather_station
               else ES_WeatherMonitorStatus.ES_WMS_NotConnected)
        return [self._answer(
            codec.GetSystemStatusRT, lastResultStatus=self.server.last_status,
            trackerProcessorStatus=tps, laserStatus=laser, admStatus=ES_ADMStatus.ES_AS_ADMReady,
            iMajorVersionNumber=VERSION[0], iMinorVersionNumber=VERSION[1],
            iBuildNumber=VERSION[2], weatherMonitorStatus=wms, lFlagsValue=0,
            lTrackerSerialNumber=SERIAL + int(c.seed))], []

    def _GetTrackerStatus(self, p):  # noqa: N802
        c = self.cell
        if self.server.busy.locked():
            st = ES_TrackerStatus.ES_TS_Busy
        elif c.tracker_initialised and c.tracker_warmed_up() and c.tracker_target_visible():
            st = ES_TrackerStatus.ES_TS_Ready
        else:
            st = ES_TrackerStatus.ES_TS_NotReady
        return [self._answer(codec.GetTrackerStatusRT, trackerStatus=st)], []

    def _GetMeasurementStatusInfo(self, p):  # noqa: N802
        c, M = self.cell, ES_MeasurementStatusInfo  # noqa: N806
        flags = M.ES_MSI_TrackerFound | M.ES_MSI_TrackerCompensationFound | M.ES_MSI_ADMFound
        flags |= M.ES_MSI_ADMCompensationFound
        if c.tracker_initialised:
            flags |= M.ES_MSI_Initialized
            if c.tracker_target_visible():
                flags |= M.ES_MSI_ReflectorFound
        if c.tracker_face == 1:
            flags |= M.ES_MSI_InFace1
        flags |= self.six_dof_flags()
        return [self._answer(codec.GetMeasurementStatusInfoRT,
                             lastResultStatus=self.server.last_status,
                             lMeasurementStatusInfo=int(flags))], []

    def _GetSystemSoftwareVersion(self, p):  # noqa: N802
        return [self._answer(codec.GetSystemSoftwareVersionRT,
                             cSoftwareVersion=codec.to_wstring("cellcal sim emScon 3.6"))], []

    def _Initialize(self, p):  # noqa: N802
        self.cell.tracker_init()
        return [self._answer(codec.InitializeRT)], [SSC.ES_SCC_InitializationStatusChanged]

    def _SetUnits(self, p):  # noqa: N802
        units = (p.lenUnitType, p.angUnitType, p.tempUnitType, p.pressUnitType, p.humUnitType)
        bad = valid_units(units)
        if bad:
            return [self._answer(codec.SetUnitsRT, RS.ES_RS_WrongParameter1 + bad - 1)], []
        with self.server.lock:
            self.server.units = tuple(int(u) for u in units)
        return [self._answer(codec.SetUnitsRT)], [SSC.ES_SSC_UnitsChanged]

    def _GetUnits(self, p):  # noqa: N802
        names = ("lenUnitType", "angUnitType", "tempUnitType", "pressUnitType", "humUnitType")
        return [self._answer(codec.GetUnitsRT,
                             **dict(zip(names, self.server.units, strict=True)))], []

    def _SetEnvironmentParams(self, p):  # noqa: N802
        u = self.server.units
        try:
            self.cell.set_tracker_environment(temp_to_c(p.dTemperature, u[2]),
                                              p.dPressure / PER_HPA[u[3]], p.dHumidity)
        except CellRefused:
            return [self._answer(codec.SetEnvironmentParamsRT,
                                 RS.ES_RS_MeteoDataOutOfRange)], []
        return [self._answer(codec.SetEnvironmentParamsRT)], [SSC.ES_SSC_EnvironmentParamsChanged]

    def _GetEnvironmentParams(self, p):  # noqa: N802
        t, pr, h, _ = self.cell.tracker_environment()
        u = self.server.units
        return [self._answer(codec.GetEnvironmentParamsRT, dTemperature=temp_from_c(t, u[2]),
                             dPressure=pr * PER_HPA[u[3]], dHumidity=h)], []

    def _SetMeasurementMode(self, p):  # noqa: N802
        if p.measMode == ES_MeasMode.ES_MM_6DStationary and self.cell.six_dof is None:
            return [self._answer(codec.SetMeasurementModeRT, RS.ES_RS_6DModeNotAllowed)], []
        if p.measMode not in (ES_MeasMode.ES_MM_Stationary, ES_MeasMode.ES_MM_6DStationary):
            return [self._answer(codec.SetMeasurementModeRT, RS.ES_RS_NotImplemented)], []
        with self.server.lock:
            self.server.meas_mode = int(p.measMode)
        return [self._answer(codec.SetMeasurementModeRT)], [SSC.ES_SSC_MeasurementModeChanged]

    def _GetMeasurementMode(self, p):  # noqa: N802
        return [self._answer(codec.GetMeasurementModeRT, measMode=self.server.meas_mode)], []

    def _SetCoordinateSystemType(self, p):  # noqa: N802
        if p.coordSysType not in CS._value2member_map_:
            return [self._answer(codec.SetCoordinateSystemTypeRT, RS.ES_RS_WrongParameter1)], []
        with self.server.lock:
            self.server.coord_sys = int(p.coordSysType)
        return ([self._answer(codec.SetCoordinateSystemTypeRT)],
                [SSC.ES_SSC_CoordinateSystemTypeChanged])

    def _GetCoordinateSystemType(self, p):  # noqa: N802
        return [self._answer(codec.GetCoordinateSystemTypeRT,
                             coordSysType=self.server.coord_sys)], []

    def _SetStationaryModeParams(self, p):  # noqa: N802
        if not 1 <= p.lMeasTime <= 60000:
            return [self._answer(codec.SetStationaryModeParamsRT,
                                 RS.ES_RS_Parameter1OutOfRangeNOK)], []
        with self.server.lock:
            self.server.stationary = (int(p.lMeasTime), int(p.bUseADM))
        return ([self._answer(codec.SetStationaryModeParamsRT)],
                [SSC.ES_SSC_StationaryModeParamsChanged])

    def _GetStationaryModeParams(self, p):  # noqa: N802
        ms, adm = self.server.stationary
        return [self._answer(codec.GetStationaryModeParamsRT, lMeasTime=ms, bUseADM=adm)], []

    def _SetReflector(self, p):  # noqa: N802
        try:
            self.cell.select_reflector(int(p.iInternalReflectorId))
        except CellRefused:
            return [self._answer(codec.SetReflectorRT, RS.ES_RS_WrongParameter1)], []
        return [self._answer(codec.SetReflectorRT)], [SSC.ES_SSC_ReflectorChanged]

    def _GetReflector(self, p):  # noqa: N802
        return [self._answer(codec.GetReflectorRT,
                             iInternalReflectorId=self.cell.tracker_reflector.id)], []

    def _GetReflectors(self, p):  # noqa: N802
        per_mm = PER_MM[self.server.units[0]]
        return [self._answer(
            codec.GetReflectorsRT, iTotalReflectors=len(TRACKER_REFLECTORS),
            iInternalReflectorId=r.id, targetType=ES_TargetType[r.target_type],
            dSurfaceOffset=r.surface_offset_mm * per_mm, cReflectorName=codec.to_wstring(r.name),
        ) for r in TRACKER_REFLECTORS], []

    def _ChangeFace(self, p):  # noqa: N802
        try:
            face = self.cell.tracker_change_face()
        except CellRefused as e:
            return [self._answer(codec.ChangeFaceRT, CELL_STATUS[e.name])], []
        return [self._answer(codec.ChangeFaceRT)], [SSC.ES_SSC_IsFace1 if face == 1
                                                    else SSC.ES_SSC_IsFace2]

    def _GetFace(self, p):  # noqa: N802
        face = ES_TrackerFace.ES_TF_Face1 if self.cell.tracker_face == 1 else (
            ES_TrackerFace.ES_TF_Face2)
        return [self._answer(codec.GetFaceRT, trackerFace=face)], []

    def _StartMeasurement(self, p):  # noqa: N802
        srv, c = self.server, self.cell
        rt = codec.StartMeasurementRT
        six_d = srv.meas_mode == ES_MeasMode.ES_MM_6DStationary
        if not (srv.meas_mode == ES_MeasMode.ES_MM_Stationary or (
                six_d and srv.coord_sys == CS.ES_CS_RHR)):
            return [self._answer(rt, RS.ES_RS_NotImplemented)], []
        if not srv.busy.acquire(blocking=False):
            return [self._answer(rt, RS.ES_RS_ServerBusy)], []
        try:
            if not c.tracker_initialised:
                return [self._answer(rt, RS.ES_RS_TrackerNotInitialized)], []
            if not c.tracker_warmed_up():
                return [self._answer(rt, RS.ES_RS_SensorNotWarmedUp)], []
            if not c.tracker_target_visible():
                return [self._answer(rt, RS.ES_RS_MeasurementStatusNotReady)], []
            srv.send(self.conn, [self._answer(rt)])  # accepted: the measurement runs
            error = codec.ErrorResponseT(command=C.ES_C_StartMeasurement,
                                         status=RS.ES_RS_NoStationaryResult)
            if srv.faults.fires("beam"):
                srv.status_change(SSC.ES_SSC_MeasStatus_NotReady)
                srv.send(self.conn, [error.pack()])
                srv.status_change(SSC.ES_SSC_MeasStatus_Ready)
                return [], []
            try:
                measure = c.tracker_measure_pose if six_d else c.tracker_measure
                r = measure(srv.stationary[0] / 1000.0)
            except CellRefused as e:
                error.status = int(CELL_STATUS.get(e.name, RS.ES_RS_Unknown))
                return [error.pack()], []
        finally:
            srv.busy.release()
        return [self._probe_result(r) if six_d else self._result(r)], []

    def _result(self, r) -> bytes:
        srv = self.server
        u = srv.units
        values, sd, rectangular = to_coordinates(np.asarray(r.xyz, float), np.asarray(r.std, float),
                                           srv.coord_sys, PER_MM[u[0]], PER_RAD[u[1]])
        common = dict(
            measMode=ES_MeasMode.ES_MM_Stationary, bIsTryMode=0,
            dVal1=values[0], dVal2=values[1], dVal3=values[2],
            dStd1=sd[0], dStd2=sd[1], dStd3=sd[2], dStdTotal=float(np.linalg.norm(sd)),
            dAprioriStd1=sd[0], dAprioriStd2=sd[1], dAprioriStd3=sd[2],
            dAprioriStdTotal=float(np.linalg.norm(sd)),
            dTemperature=temp_from_c(r.temp_c, u[2]), dPressure=r.pressure_hpa * PER_HPA[u[3]],
            dHumidity=r.humidity_pct,
        )
        if not (rectangular and srv.result2):
            return codec.SingleMeasResultT(**common).pack()
        # the cell's noise is isotropic and independent per axis: the covariances are 0
        return codec.SingleMeasResult2T(**common, dCovar12=0.0, dCovar13=0.0,
                                        dCovar23=0.0).pack()


class EmsconServer(LineServer):
    """An emScon TPI server for ``cell`` on loopback TCP.

    Parameters
    ----------
    cell : SimCell
    faults : FaultInjector or None
        Defaults to the cell's injector (or none).
    host, port : str, int
        TCP address (port 0: a free one; emScon's own is 700).
    units : tuple of 5 ints
        The server's units at start (ES_LengthUnit, ES_AngleUnit, ...).
    chunk_bytes : int
        > 0: send every reply in pieces of this size (packets split over reads).
    chatter : bool
        Send a status change (EnvironmentParamsChanged) in front of every answer.
    result2 : bool
        Results as SingleMeasResult2T (with covariances) rather than SingleMeasResultT.
    """

    GARBAGE = GARBAGE

    def __init__(
        self,
        cell: SimCell,
        *,
        faults: FaultInjector | None = None,
        host: str = "127.0.0.1",
        port: int = 0,
        units: tuple[int, int, int, int, int] = tuple(int(u) for u in SERVER_DEFAULT_UNITS),
        chunk_bytes: int = 0,
        chatter: bool = False,
        result2: bool = True,
    ) -> None:
        faults = faults if faults is not None else (cell.faults or FaultInjector())
        self.cell = cell
        self.lock = threading.Lock()
        self.busy = threading.Lock()
        self.units = tuple(int(u) for u in units)
        self.coord_sys = int(CS.ES_CS_RHR)
        self.meas_mode = int(ES_MeasMode.ES_MM_Stationary)
        self.stationary = (1000, 1)
        self.last_status = int(RS.ES_RS_AllOK)
        self.chatter = chatter
        self.result2 = result2
        super().__init__(lambda: EmsconSession(self), faults=faults, host=host, port=port,
                         transport="tcp", name="sim-emscon")
        self.chunk_bytes = int(chunk_bytes)

    @property
    def url(self) -> str:
        """The driver URL ``emscon://host:port``."""
        return f"emscon://{self.host}:{self.port}"

    def _framer(self):
        return _Framer()

    def _internal_error(self, request, e: Exception) -> bytes:
        return codec.ErrorResponseT(command=C.ES_C_Unknown, status=RS.ES_RS_Unknown).pack()

    @staticmethod
    def status_packet(change: int) -> bytes:
        """A SystemStatusChangeT packet."""
        return codec.SystemStatusChangeT(systemStatusChange=int(change)).pack()

    def status_change(self, change: int) -> None:
        """Tell every client about ``change`` (an ES_SystemStatusChange)."""
        self.broadcast(self.status_packet(change))

    def remember_status(self, replies: list[bytes]) -> None:
        """Keep the status of the last answer (GetSystemStatus.lastResultStatus)."""
        for r in replies:
            if len(r) >= 16 and r[4:8] == b"\0\0\0\0":
                self.last_status = int.from_bytes(r[12:16], "little", signed=True)
