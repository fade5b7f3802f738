"""emScon TPI packets: one class per C struct of ``ES_C_API_Def.h`` (TPI/SDK 3.6), little-endian.

The header packs its structs to 4 bytes (``#pragma pack(4)``), ``long`` and
every ``enum`` are 32-bit, ``ES_BOOL`` is ``int``, strings are ``unsigned short
[32]`` (UTF-16LE, NUL-padded). Every field here is 4 or 8 bytes (or a 64-byte
string) and lies at a multiple of 4, so the structs have no padding and Python's
standard-size ``<`` layout is the wire layout; :class:`Packet` checks this for
every class it builds, and the tests check every size against the header.

Nested structs are flattened in declaration order with their own field names:
``SetUnitsCT {BasicCommandCT packetInfo {PacketHeaderT packetHeader
{lPacketSize, type}, command}, SystemUnitsDataT unitsSettings {lenUnitType,
...}}`` has the attributes ``lPacketSize, type, command, lenUnitType, ...``.

Commands (``...CT``) and their answers (``...RT``) are both ``ES_DT_Command``
packets; an answer echoes the command and adds ``status`` (``ES_ResultStatus``).
:func:`decode` turns one frame (from :class:`~drivers.leica.framing.FrameReader`)
into a packet object; ``side`` says whether command frames are answers (a
client reading) or commands (a server reading).
"""

from __future__ import annotations

import struct
from typing import TYPE_CHECKING, Any, ClassVar

from drivers.leica.enums import ES_Command as C
from drivers.leica.enums import ES_DataType as DT

# ------------------------------------------------------------- building blocks
#: PacketHeaderT
HEADER = (("lPacketSize", "i"), ("type", "i"))
#: BasicCommandCT: a command without parameters
CT = (*HEADER, ("command", "i"))
#: BasicCommandRT: an answer without data
RT = (*CT, ("status", "i"))
#: ReturnDataT: the prefix of result packets
RETURN_DATA = (*HEADER, ("status", "i"))
#: SystemUnitsDataT
UNITS = (("lenUnitType", "i"), ("angUnitType", "i"), ("tempUnitType", "i"),
         ("pressUnitType", "i"), ("humUnitType", "i"))
#: EnvironmentDataT
ENVIRONMENT = (("dTemperature", "d"), ("dPressure", "d"), ("dHumidity", "d"))
#: StationaryModeDataT
STATIONARY = (("lMeasTime", "i"), ("bUseADM", "i"))
#: ESVersionNumberT
VERSION = (("iMajorVersionNumber", "i"), ("iMinorVersionNumber", "i"), ("iBuildNumber", "i"))
#: unsigned short [32], a UTF-16LE string
WSTRING = "64s"

#: command number -> CT class / RT class (filled by the classes below)
COMMANDS: dict[int, type[Packet]] = {}
ANSWERS: dict[int, type[Packet]] = {}
#: ES_DataType -> result class, for result structs declared elsewhere with ``RESULT = True``
#: (the 6D ones of :mod:`drivers.leica.probe_packets`)
RESULTS: dict[int, type[Packet]] = {}


class DecodeError(ValueError):
    """A frame that is no packet of the protocol (unknown type, wrong size)."""


def _check_layout(cls: type[Packet]) -> None:
    offset = 0
    for name, code in cls.FIELDS:
        size = struct.calcsize("<" + code)
        align = min(4, size if not code.endswith("s") else 2)
        if offset % align:
            raise TypeError(f"{cls.__name__}.{name} at offset {offset} would be padded")
        offset += size
    if offset % 4:
        raise TypeError(f"{cls.__name__}: size {offset} is not a multiple of 4")


class Packet:
    """Base of every packet struct: ``FIELDS`` in the header's order, values as attributes.

    ``Packet(**fields)`` fills missing fields with 0 (``b""`` for strings) and the
    constants ``lPacketSize``, ``type``, ``command`` with the class's own; ``pack()``
    gives the bytes, ``unpack(frame)`` the packet of exactly ``SIZE`` bytes.
    """

    FIELDS: ClassVar[tuple[tuple[str, str], ...]] = ()
    TYPE: ClassVar[int] = -1
    COMMAND: ClassVar[int | None] = None
    #: "CT" a command, "RT" its answer, "" anything else
    ROLE: ClassVar[str] = ""
    STRUCT: ClassVar[struct.Struct]
    SIZE: ClassVar[int]
    NAMES: ClassVar[tuple[str, ...]]

    if TYPE_CHECKING:  # the FIELDS, set as attributes by __init__
        def __getattr__(self, name: str) -> Any: ...

    def __init_subclass__(cls, **kw: Any) -> None:
        super().__init_subclass__(**kw)
        if not cls.FIELDS:
            return
        _check_layout(cls)
        cls.STRUCT = struct.Struct("<" + "".join(code for _, code in cls.FIELDS))
        cls.SIZE = cls.STRUCT.size
        cls.NAMES = tuple(name for name, _ in cls.FIELDS)
        if cls.COMMAND is not None and cls.ROLE:
            (COMMANDS if cls.ROLE == "CT" else ANSWERS)[int(cls.COMMAND)] = cls
        if cls.__dict__.get("RESULT"):
            RESULTS[int(cls.TYPE)] = cls

    def __init__(self, **values: Any) -> None:
        for name, code in self.FIELDS:
            setattr(self, name, b"" if code.endswith("s") else 0)
        self.lPacketSize = self.SIZE
        self.type = int(self.TYPE)
        if self.COMMAND is not None:
            self.command = int(self.COMMAND)
        for name, value in values.items():
            if name not in self.NAMES:
                raise TypeError(f"{type(self).__name__} has no field {name!r}")
            setattr(self, name, value)

    def pack(self) -> bytes:
        """The packet's bytes (``lPacketSize`` as set, normally ``SIZE``)."""
        return self.STRUCT.pack(*(getattr(self, n) for n in self.NAMES))

    @classmethod
    def unpack(cls, frame: bytes) -> Packet:
        """The packet in ``frame`` (exactly ``SIZE`` bytes, else DecodeError)."""
        if len(frame) != cls.SIZE:
            raise DecodeError(f"{cls.__name__}: {len(frame)} bytes, expected {cls.SIZE}")
        return cls(**dict(zip(cls.NAMES, cls.STRUCT.unpack(frame), strict=True)))

    def fields(self) -> dict[str, object]:
        """Every field by name (for messages and tests)."""
        return {n: getattr(self, n) for n in self.NAMES}

    def __eq__(self, other: object) -> bool:
        return isinstance(other, Packet) and type(other) is type(self) \
            and other.fields() == self.fields()

    def __repr__(self) -> str:
        body = ", ".join(f"{k}={v!r}" for k, v in self.fields().items()
                         if k not in ("lPacketSize", "type"))
        return f"{type(self).__name__}({body})"


class CommandCT(Packet):
    """A command: ``BasicCommandCT`` + its parameters."""

    TYPE = DT.ES_DT_Command
    ROLE = "CT"


class AnswerRT(Packet):
    """An answer: ``BasicCommandRT`` + its data."""

    TYPE = DT.ES_DT_Command
    ROLE = "RT"


def wstring(raw: bytes) -> str:
    """``unsigned short [32]`` → str (UTF-16LE up to the first NUL)."""
    text = raw.decode("utf-16-le", "replace")
    return text.split("\0", 1)[0]


def to_wstring(text: str, chars: int = 32) -> bytes:
    """str → ``unsigned short [chars]`` (truncated to leave room for a NUL)."""
    return text[: chars - 1].encode("utf-16-le")


# ------------------------------------------------------------ generic packets
class PacketHeaderT(Packet):
    """``struct PacketHeaderT``: the start of every packet."""

    FIELDS = HEADER


class BasicCommandCT(CommandCT):
    """``struct BasicCommandCT``: any command without parameters (command set per instance)."""

    FIELDS = CT


class BasicCommandRT(AnswerRT):
    """``struct BasicCommandRT``: any answer without data (command set per instance)."""

    FIELDS = RT


class ReturnDataT(Packet):
    """``struct ReturnDataT``: the common prefix of result packets."""

    FIELDS = RETURN_DATA


class ErrorResponseT(Packet):
    """``struct ErrorResponseT``: a command failed, possibly long after its answer."""

    TYPE = DT.ES_DT_Error
    FIELDS = RT


class SystemStatusChangeT(Packet):
    """``struct SystemStatusChangeT``: unsolicited; ``systemStatusChange`` says what changed."""

    TYPE = DT.ES_DT_SystemStatusChange
    FIELDS = (*HEADER, ("systemStatusChange", "i"))


class SingleMeasResultT(Packet):
    """``struct SingleMeasResultT``: one stationary point, in the server's current units."""

    TYPE = DT.ES_DT_SingleMeasResult
    FIELDS = (*RETURN_DATA, ("measMode", "i"), ("bIsTryMode", "i"),
              ("dVal1", "d"), ("dVal2", "d"), ("dVal3", "d"),
              ("dStd1", "d"), ("dStd2", "d"), ("dStd3", "d"), ("dStdTotal", "d"),
              ("dPointingError1", "d"), ("dPointingError2", "d"), ("dPointingError3", "d"),
              ("dAprioriStd1", "d"), ("dAprioriStd2", "d"), ("dAprioriStd3", "d"),
              ("dAprioriStdTotal", "d"),
              ("dTemperature", "d"), ("dPressure", "d"), ("dHumidity", "d"))


class SingleMeasResult2T(Packet):
    """``struct SingleMeasResult2T``: SingleMeasResultT with covariances."""

    TYPE = DT.ES_DT_SingleMeasResult2
    FIELDS = (*RETURN_DATA, ("measMode", "i"), ("bIsTryMode", "i"),
              ("dVal1", "d"), ("dVal2", "d"), ("dVal3", "d"),
              ("dStd1", "d"), ("dStd2", "d"), ("dStd3", "d"), ("dStdTotal", "d"),
              ("dCovar12", "d"), ("dCovar13", "d"), ("dCovar23", "d"),
              ("dPointingErrorH", "d"), ("dPointingErrorV", "d"), ("dPointingErrorD", "d"),
              ("dAprioriStd1", "d"), ("dAprioriStd2", "d"), ("dAprioriStd3", "d"),
              ("dAprioriStdTotal", "d"),
              ("dAprioriCovar12", "d"), ("dAprioriCovar13", "d"), ("dAprioriCovar23", "d"),
              ("dTemperature", "d"), ("dPressure", "d"), ("dHumidity", "d"))


class NivelResultT(Packet):
    """``struct NivelResultT`` (decoded so it can be ignored cleanly)."""

    TYPE = DT.ES_DT_NivelResult
    FIELDS = (*RETURN_DATA, ("nivelStatus", "i"), ("dXTilt", "d"), ("dYTilt", "d"),
              ("dNivelTemperature", "d"))


class ReflectorPosResultT(Packet):
    """``struct ReflectorPosResultT``: live reflector position (when switched on)."""

    TYPE = DT.ES_DT_ReflectorPosResult
    FIELDS = (*RETURN_DATA, ("dVal1", "d"), ("dVal2", "d"), ("dVal3", "d"))


# ------------------------------------------------------- commands and answers
class InitializeCT(CommandCT):
    COMMAND, FIELDS = C.ES_C_Initialize, CT


class InitializeRT(AnswerRT):
    COMMAND, FIELDS = C.ES_C_Initialize, RT


class GetSystemStatusCT(CommandCT):
    COMMAND, FIELDS = C.ES_C_GetSystemStatus, CT


class GetSystemStatusRT(AnswerRT):
    COMMAND = C.ES_C_GetSystemStatus
    FIELDS = (*RT, ("lastResultStatus", "i"), ("trackerProcessorStatus", "i"),
              ("laserStatus", "i"), ("admStatus", "i"), *VERSION,
              ("weatherMonitorStatus", "i"), ("lFlagsValue", "i"), ("lTrackerSerialNumber", "i"))


class GetTrackerStatusCT(CommandCT):
    COMMAND, FIELDS = C.ES_C_GetTrackerStatus, CT


class GetTrackerStatusRT(AnswerRT):
    COMMAND, FIELDS = C.ES_C_GetTrackerStatus, (*RT, ("trackerStatus", "i"))


class SetUnitsCT(CommandCT):
    COMMAND, FIELDS = C.ES_C_SetUnits, (*CT, *UNITS)


class SetUnitsRT(AnswerRT):
    COMMAND, FIELDS = C.ES_C_SetUnits, RT


class GetUnitsCT(CommandCT):
    COMMAND, FIELDS = C.ES_C_GetUnits, CT


class GetUnitsRT(AnswerRT):
    COMMAND, FIELDS = C.ES_C_GetUnits, (*RT, *UNITS)


class SetEnvironmentParamsCT(CommandCT):
    COMMAND, FIELDS = C.ES_C_SetEnvironmentParams, (*CT, *ENVIRONMENT)


class SetEnvironmentParamsRT(AnswerRT):
    COMMAND, FIELDS = C.ES_C_SetEnvironmentParams, RT


class GetEnvironmentParamsCT(CommandCT):
    COMMAND, FIELDS = C.ES_C_GetEnvironmentParams, CT


class GetEnvironmentParamsRT(AnswerRT):
    COMMAND, FIELDS = C.ES_C_GetEnvironmentParams, (*RT, *ENVIRONMENT)


class SetMeasurementModeCT(CommandCT):
    COMMAND, FIELDS = C.ES_C_SetMeasurementMode, (*CT, ("measMode", "i"))


class SetMeasurementModeRT(AnswerRT):
    COMMAND, FIELDS = C.ES_C_SetMeasurementMode, RT


class GetMeasurementModeCT(CommandCT):
    COMMAND, FIELDS = C.ES_C_GetMeasurementMode, CT


class GetMeasurementModeRT(AnswerRT):
    COMMAND, FIELDS = C.ES_C_GetMeasurementMode, (*RT, ("measMode", "i"))


class SetCoordinateSystemTypeCT(CommandCT):
    COMMAND, FIELDS = C.ES_C_SetCoordinateSystemType, (*CT, ("coordSysType", "i"))


class SetCoordinateSystemTypeRT(AnswerRT):
    COMMAND, FIELDS = C.ES_C_SetCoordinateSystemType, RT


class GetCoordinateSystemTypeCT(CommandCT):
    COMMAND, FIELDS = C.ES_C_GetCoordinateSystemType, CT


class GetCoordinateSystemTypeRT(AnswerRT):
    COMMAND, FIELDS = C.ES_C_GetCoordinateSystemType, (*RT, ("coordSysType", "i"))


class SetStationaryModeParamsCT(CommandCT):
    COMMAND, FIELDS = C.ES_C_SetStationaryModeParams, (*CT, *STATIONARY)


class SetStationaryModeParamsRT(AnswerRT):
    COMMAND, FIELDS = C.ES_C_SetStationaryModeParams, RT


class GetStationaryModeParamsCT(CommandCT):
    COMMAND, FIELDS = C.ES_C_GetStationaryModeParams, CT


class GetStationaryModeParamsRT(AnswerRT):
    COMMAND, FIELDS = C.ES_C_GetStationaryModeParams, (*RT, *STATIONARY)


class SetReflectorCT(CommandCT):
    COMMAND, FIELDS = C.ES_C_SetReflector, (*CT, ("iInternalReflectorId", "i"))


class SetReflectorRT(AnswerRT):
    COMMAND, FIELDS = C.ES_C_SetReflector, RT


class GetReflectorCT(CommandCT):
    COMMAND, FIELDS = C.ES_C_GetReflector, CT


class GetReflectorRT(AnswerRT):
    COMMAND, FIELDS = C.ES_C_GetReflector, (*RT, ("iInternalReflectorId", "i"))


class GetReflectorsCT(CommandCT):
    COMMAND, FIELDS = C.ES_C_GetReflectors, CT


class GetReflectorsRT(AnswerRT):
    """One packet per reflector; ``iTotalReflectors`` says how many follow in all."""

    COMMAND = C.ES_C_GetReflectors
    FIELDS = (*RT, ("iTotalReflectors", "i"), ("iInternalReflectorId", "i"),
              ("targetType", "i"), ("dSurfaceOffset", "d"), ("cReflectorName", WSTRING))


class StartMeasurementCT(CommandCT):
    COMMAND, FIELDS = C.ES_C_StartMeasurement, CT


class StartMeasurementRT(AnswerRT):
    COMMAND, FIELDS = C.ES_C_StartMeasurement, RT


class StopMeasurementCT(CommandCT):
    COMMAND, FIELDS = C.ES_C_StopMeasurement, CT


class StopMeasurementRT(AnswerRT):
    COMMAND, FIELDS = C.ES_C_StopMeasurement, RT


class ChangeFaceCT(CommandCT):
    COMMAND, FIELDS = C.ES_C_ChangeFace, CT


class ChangeFaceRT(AnswerRT):
    COMMAND, FIELDS = C.ES_C_ChangeFace, RT


class GetFaceCT(CommandCT):
    COMMAND, FIELDS = C.ES_C_GetFace, CT


class GetFaceRT(AnswerRT):
    COMMAND, FIELDS = C.ES_C_GetFace, (*RT, ("trackerFace", "i"))


class GetMeasurementStatusInfoCT(CommandCT):
    COMMAND, FIELDS = C.ES_C_GetMeasurementStatusInfo, CT


class GetMeasurementStatusInfoRT(AnswerRT):
    COMMAND = C.ES_C_GetMeasurementStatusInfo
    FIELDS = (*RT, ("lastResultStatus", "i"), ("lMeasurementStatusInfo", "i"))


class GetSystemSoftwareVersionCT(CommandCT):
    COMMAND, FIELDS = C.ES_C_GetSystemSoftwareVersion, CT


class GetSystemSoftwareVersionRT(AnswerRT):
    COMMAND = C.ES_C_GetSystemSoftwareVersion
    FIELDS = (*RT, ("cSoftwareVersion", WSTRING))


# ------------------------------------------------------------------ decoding
#: result and event packets by ES_DataType
_BY_TYPE: dict[int, type[Packet]] = {
    DT.ES_DT_Error: ErrorResponseT,
    DT.ES_DT_SingleMeasResult: SingleMeasResultT,
    DT.ES_DT_NivelResult: NivelResultT,
    DT.ES_DT_ReflectorPosResult: ReflectorPosResultT,
    DT.ES_DT_SystemStatusChange: SystemStatusChangeT,
    DT.ES_DT_SingleMeasResult2: SingleMeasResult2T,
}


class UnknownPacket:
    """A well-framed packet of a known-to-exist type this package does not decode
    (multi-measurement and continuous probe results): kept as raw bytes, to be ignored."""

    def __init__(self, frame: bytes) -> None:
        self.raw = frame
        self.lPacketSize, self.type = struct.unpack_from("<ii", frame)

    def __repr__(self) -> str:
        return f"UnknownPacket(type={self.type}, {len(self.raw)} bytes)"


def decode(frame: bytes, side: str = "client") -> Packet | UnknownPacket:
    """The packet in one frame.

    Parameters
    ----------
    frame : bytes
        One whole packet (``lPacketSize`` bytes).
    side : {"client", "server"}
        Who reads: a client's ``ES_DT_Command`` frames are answers (RT), a
        server's are commands (CT).

    A command or answer this module has no struct for decodes as
    :class:`BasicCommandCT` / :class:`BasicCommandRT` when it has that size. An
    answer whose status is not OK may come without its data (BasicCommandRT
    size) and decodes as :class:`BasicCommandRT`. Raises :class:`DecodeError`
    for a frame of an unknown type or of the wrong size.
    """
    if len(frame) < 8:
        raise DecodeError(f"{len(frame)} bytes is no packet")
    size, dtype = struct.unpack_from("<ii", frame)
    if size != len(frame):
        raise DecodeError(f"lPacketSize {size} but {len(frame)} bytes")
    if dtype == DT.ES_DT_Command:
        if len(frame) < BasicCommandCT.SIZE:
            raise DecodeError("command packet shorter than BasicCommandCT")
        (command,) = struct.unpack_from("<i", frame, 8)
        basic: type[Packet]
        if side == "client":
            cls, basic = ANSWERS.get(command), BasicCommandRT
        else:
            cls, basic = COMMANDS.get(command), BasicCommandCT
        if cls is not None and len(frame) == cls.SIZE:
            return cls.unpack(frame)
        if len(frame) == basic.SIZE:
            packet = basic.unpack(frame)
            # data-less: an unknown command, or an answer that reports a failure
            if cls is None or (side == "client" and packet.status != 0):
                return packet
        name = cls.__name__ if cls else f"command {command}"
        want = cls.SIZE if cls else basic.SIZE
        raise DecodeError(f"{name}: {len(frame)} bytes, expected {want}")
    cls = _BY_TYPE.get(dtype) or RESULTS.get(dtype)
    if cls is not None:
        return cls.unpack(frame)
    if dtype in tuple(int(t) for t in DT):
        return UnknownPacket(frame)
    raise DecodeError(f"unknown packet type {dtype}")
