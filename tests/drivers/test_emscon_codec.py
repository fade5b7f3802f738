"""emScon codec: struct sizes against ES_C_API_Def.h (TPI 3.6), the independent CESAPI
client's layouts, and the length-prefixed framing."""

from __future__ import annotations

import struct

import pytest

from drivers.leica import codec
from drivers.leica.enums import (
    ES_Command,
    ES_DataType,
    ES_ResultStatus,
    ES_SystemStatusChange,
)
from drivers.leica.framing import MIN_PACKET, FrameReader, FramingError

# Sizes from the header with #pragma pack(4), long/enum/int/ES_BOOL = 4 bytes, double = 8:
# PacketHeaderT {lPacketSize, type} = 8; BasicCommandCT = header + command = 12;
# BasicCommandRT = + status = 16; ReturnDataT = header + status = 12.
HEADER_SIZES = {
    "PacketHeaderT": 8,
    "BasicCommandCT": 12,
    "BasicCommandRT": 16,
    "ReturnDataT": 12,
    "ErrorResponseT": 16,            # header + command + status
    "SystemStatusChangeT": 12,       # header + systemStatusChange
    "SingleMeasResultT": 156,        # ReturnDataT 12 + measMode, bIsTryMode 8 + 17 doubles 136
    "SingleMeasResult2T": 204,       # 12 + 8 + 23 doubles 184
    "NivelResultT": 40,              # 12 + nivelStatus 4 + 3 doubles
    "ReflectorPosResultT": 36,       # 12 + 3 doubles
    "InitializeCT": 12, "InitializeRT": 16,
    "GetSystemStatusCT": 12,
    "GetSystemStatusRT": 56,         # 16 + 4 enums 16 + ESVersionNumberT 12 + enum + 2 longs 12
    "GetTrackerStatusRT": 20,
    "SetUnitsCT": 32,                # 12 + SystemUnitsDataT (5 enums) 20
    "GetUnitsRT": 36,
    "SetEnvironmentParamsCT": 36,    # 12 + EnvironmentDataT (3 doubles) 24
    "GetEnvironmentParamsRT": 40,
    "SetMeasurementModeCT": 16, "GetMeasurementModeRT": 20,
    "SetCoordinateSystemTypeCT": 16, "GetCoordinateSystemTypeRT": 20,
    "SetStationaryModeParamsCT": 20,  # 12 + StationaryModeDataT {long lMeasTime; ES_BOOL} 8
    "GetStationaryModeParamsRT": 24,
    "SetReflectorCT": 16, "GetReflectorRT": 20,
    "GetReflectorsRT": 100,          # 16 + 2 ints + enum 12 + double 8 + unsigned short[32] 64
    "StartMeasurementCT": 12, "StartMeasurementRT": 16,
    "StopMeasurementCT": 12, "StopMeasurementRT": 16,
    "ChangeFaceCT": 12, "ChangeFaceRT": 16,
    "GetFaceRT": 20,
    "GetMeasurementStatusInfoRT": 24,  # 16 + enum + long
    "GetSystemSoftwareVersionRT": 80,  # 16 + unsigned short[32]
}


@pytest.mark.parametrize("name,size", sorted(HEADER_SIZES.items()))
def test_struct_sizes_match_the_header(name, size):
    assert size == getattr(codec, name).SIZE


def test_enum_values_match_the_header():
    assert ES_DataType.ES_DT_SingleMeasResult2 == 9
    assert ES_DataType.ES_DT_SystemStatusChange == 8
    assert ES_Command.ES_C_StartMeasurement == 49 and ES_Command.ES_C_ChangeFace == 53
    assert ES_Command.ES_C_GetMeasurementStatusInfo == 122
    assert ES_ResultStatus.ES_RS_TrackerNotInitialized == 39
    assert ES_ResultStatus.ES_RS_MeasurementStatusNotReady == 10004
    assert ES_ResultStatus.ES_RS_NoStationaryResult == 10009
    assert ES_ResultStatus.ES_RS_SensorNotWarmedUp == 10012
    assert ES_ResultStatus.ES_RS_SensorNotStable == 10013
    assert ES_ResultStatus.ES_RS_SystemNotReadyForMeasurement == 10014
    assert ES_SystemStatusChange.ES_SSC_MeasStatus_NotReady == 25


# ------------------------------------------------------------- against CESAPI
CESAPI = pytest.importorskip("CESAPI.packet")


def _ours_with_cesapi_twin():
    for name in sorted(vars(codec)):
        ours = getattr(codec, name)
        if (isinstance(ours, type) and issubclass(ours, codec.Packet) and ours.FIELDS
                and hasattr(CESAPI, name)):
            yield name


def test_every_struct_has_the_size_cesapi_packs():
    names = list(_ours_with_cesapi_twin())
    assert len(names) >= 40
    for name in names:
        assert len(getattr(CESAPI, name)().pack()) == getattr(codec, name).SIZE, name


def test_bytes_round_trip_through_cesapi():
    ours = codec.SingleMeasResult2T(status=0, dVal1=1.5, dVal2=-2.25, dVal3=1e3, dStd1=0.01,
                                    dCovar23=1e-6, dTemperature=20.5, dPressure=1013.25,
                                    dHumidity=45.0)
    theirs = CESAPI.SingleMeasResult2T()
    theirs.unpack(ours.pack())
    assert (theirs.dVal1, theirs.dVal2, theirs.dVal3) == (1.5, -2.25, 1e3)
    assert (theirs.dCovar23, theirs.dTemperature, theirs.dHumidity) == (1e-6, 20.5, 45.0)
    assert theirs.packetInfo.packetHeader.lPacketSize == 204
    units = CESAPI.SetUnitsCT()
    units.unitsSettings.lenUnitType = CESAPI.ES_LU_Inch
    units.unitsSettings.pressUnitType = CESAPI.ES_PU_Psi
    got = codec.decode(units.pack(), "server")
    assert isinstance(got, codec.SetUnitsCT)
    assert (got.lenUnitType, got.pressUnitType) == (5, 4)
    refl = codec.GetReflectorsRT(iTotalReflectors=2, iInternalReflectorId=7, targetType=5,
                                 dSurfaceOffset=19.05, cReflectorName=codec.to_wstring("RRR 1.5in"))
    theirs = CESAPI.GetReflectorsRT()
    theirs.unpack(refl.pack())
    assert theirs.iInternalReflectorId == 7 and theirs.dSurfaceOffset == 19.05
    assert codec.wstring(theirs.cReflectorName) == "RRR 1.5in"


# ------------------------------------------------------------------ framing
def _stream() -> tuple[bytes, list[bytes]]:
    packets = [
        codec.SystemStatusChangeT(systemStatusChange=25).pack(),
        codec.StartMeasurementRT(status=0).pack(),
        codec.SingleMeasResult2T(dVal1=1.0).pack(),
        codec.GetUnitsRT(lenUnitType=1).pack(),
    ]
    return b"".join(packets), packets


@pytest.mark.parametrize("chunk", [1, 3, 7, 12, 13, 100, 10_000])
def test_framing_survives_any_split(chunk):
    data, packets = _stream()
    reader, out = FrameReader(), []
    for k in range(0, len(data), chunk):
        out += reader.feed(data[k:k + chunk])
    assert out == packets and reader.pending == 0


def test_several_packets_in_one_read_and_a_tail():
    data, packets = _stream()
    reader = FrameReader()
    assert reader.feed(data + data[:5]) == packets
    assert reader.pending == 5
    assert reader.feed(data[5:]) == packets


@pytest.mark.parametrize("size", [0, -1, MIN_PACKET - 1, 1 << 30])
def test_a_length_outside_the_protocol_is_a_framing_error(size):
    reader = FrameReader()
    with pytest.raises(FramingError, match="packet length"):
        reader.feed(struct.pack("<ii", size, 0) + b"\0" * 8)
    assert reader.pending == 0


def test_decode_by_side_and_errors():
    ct = codec.GetUnitsCT().pack()
    assert isinstance(codec.decode(ct, "server"), codec.GetUnitsCT)
    # a failed answer may come without its data: decoded as BasicCommandRT
    short = codec.BasicCommandRT(command=ES_Command.ES_C_GetUnits, status=39).pack()
    assert isinstance(codec.decode(short, "client"), codec.BasicCommandRT)
    # ...but an OK answer without its data is not an answer
    ok_short = codec.BasicCommandRT(command=ES_Command.ES_C_GetUnits, status=0).pack()
    with pytest.raises(codec.DecodeError, match="GetUnitsRT"):
        codec.decode(ok_short, "client")
    with pytest.raises(codec.DecodeError, match="unknown packet type"):
        codec.decode(struct.pack("<iii", 12, 77, 0))
    with pytest.raises(codec.DecodeError, match="lPacketSize"):
        codec.decode(struct.pack("<iii", 16, 8, 0))
    # a known type this package does not decode (multi-measurement results) is kept raw
    other = codec.decode(struct.pack("<iii", 12, int(ES_DataType.ES_DT_MultiMeasResult), 0))
    assert isinstance(other, codec.UnknownPacket)
