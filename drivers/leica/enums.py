"""Leica emScon TPI enumerations, with the names and values of ``ES_C_API_Def.h`` / ``Enum.h``.

Source: the public C header of the emScon TPI/SDK 3.6 (``ES_C_API_Def.h``, the
full-featured version for all tracker types, and its mandatory ``Enum.h``).
Only the enumerations this package uses are listed, each with the members the
driver or the simulator may meet; a value missing here is still accepted on the
wire (decoded to a plain ``int``), see :func:`name_of`.

The header's own spelling is kept, including its typing errors
(``ES_SCC_InitializationStatusChanged``).
"""

from __future__ import annotations

from enum import IntEnum

#: ``#define ES_API_ERROR_OFFSET 10000``: the second range of ES_ResultStatus
ES_API_ERROR_OFFSET = 10000


class ES_DataType(IntEnum):  # noqa: N801 - the header's names
    """``enum ES_DataType``: what a packet on the wire is (``PacketHeaderT.type``)."""

    ES_DT_Command = 0
    ES_DT_Error = 1
    ES_DT_SingleMeasResult = 2
    ES_DT_MultiMeasResult = 3
    ES_DT_StationaryProbeMeasResult = 4
    ES_DT_ContinuousProbeMeasResult = 5
    ES_DT_NivelResult = 6
    ES_DT_ReflectorPosResult = 7
    ES_DT_SystemStatusChange = 8
    ES_DT_SingleMeasResult2 = 9
    ES_DT_MultiMeasResult2 = 10
    ES_DT_ProbePosResult = 11


class ES_Command(IntEnum):  # noqa: N801
    """``enum ES_Command`` (the commands this package speaks, and a few neighbours)."""

    ES_C_ExitApplication = 0
    ES_C_GetSystemStatus = 1
    ES_C_GetTrackerStatus = 2
    ES_C_SetUnits = 5
    ES_C_GetUnits = 6
    ES_C_Initialize = 7
    ES_C_Park = 10
    ES_C_SetEnvironmentParams = 20
    ES_C_GetEnvironmentParams = 21
    ES_C_SetRefractionParams = 22
    ES_C_GetRefractionParams = 23
    ES_C_SetMeasurementMode = 24
    ES_C_GetMeasurementMode = 25
    ES_C_SetCoordinateSystemType = 26
    ES_C_GetCoordinateSystemType = 27
    ES_C_SetStationaryModeParams = 28
    ES_C_GetStationaryModeParams = 29
    ES_C_SetReflector = 40
    ES_C_GetReflector = 41
    ES_C_GetReflectors = 42
    ES_C_SetSystemSettings = 47
    ES_C_GetSystemSettings = 48
    ES_C_StartMeasurement = 49
    ES_C_StopMeasurement = 52
    ES_C_ChangeFace = 53
    ES_C_GoBirdBath = 54
    ES_C_Unknown = 64
    ES_C_GetFace = 98
    ES_C_GetProbes = 103
    ES_C_GetProbe = 104
    ES_C_GetMeasurementProbeInfo = 119
    ES_C_GetMeasurementStatusInfo = 122
    ES_C_GetSystemSoftwareVersion = 142


class ES_MeasMode(IntEnum):  # noqa: N801
    """``enum ES_MeasMode``: 3D modes, and their 6D (probe) twins from 6."""

    ES_MM_Stationary = 0
    ES_MM_ContinuousTime = 1
    ES_MM_ContinuousDistance = 2
    ES_MM_Grid = 3
    ES_MM_SphereCenter = 4
    ES_MM_CircleCenter = 5
    ES_MM_6DStationary = 6
    ES_MM_6DContinuousTime = 7
    ES_MM_6DContinuousDistance = 8
    ES_MM_6DGrid = 9
    ES_MM_6DSphereCenter = 10
    ES_MM_6DCircleCenter = 11


class ES_TargetType(IntEnum):  # noqa: N801
    """``enum ES_TargetType``: reflector (prism) types."""

    ES_TT_Unknown = 0
    ES_TT_CornerCube = 1
    ES_TT_CatsEye = 2
    ES_TT_GlassPrism = 3
    ES_TT_RFIPrism = 4
    ES_TT_RRR15 = 5
    ES_TT_RRR05 = 6
    ES_TT_BRR15 = 7
    ES_TT_BRR05 = 8
    ES_TT_TBR05 = 9


class ES_TrackerStatus(IntEnum):  # noqa: N801
    """``enum ES_TrackerStatus`` (GetTrackerStatus)."""

    ES_TS_NotReady = 0
    ES_TS_Busy = 1
    ES_TS_Ready = 2
    ES_TS_6DStatusInvalid = 3


class ES_ResultStatus(IntEnum):  # noqa: N801
    """``enum ES_ResultStatus``: the status of every answer (0 is OK)."""

    ES_RS_AllOK = 0
    ES_RS_ServerBusy = 1
    ES_RS_NotImplemented = 2
    ES_RS_WrongParameter = 3
    ES_RS_WrongParameter1 = 4
    ES_RS_WrongParameter2 = 5
    ES_RS_WrongParameter3 = 6
    ES_RS_WrongParameter4 = 7
    ES_RS_WrongParameter5 = 8
    ES_RS_WrongParameter6 = 9
    ES_RS_WrongParameter7 = 10
    ES_RS_Parameter1OutOfRangeOK = 11
    ES_RS_Parameter1OutOfRangeNOK = 12
    ES_RS_Parameter2OutOfRangeOK = 13
    ES_RS_Parameter2OutOfRangeNOK = 14
    ES_RS_Parameter3OutOfRangeOK = 15
    ES_RS_Parameter3OutOfRangeNOK = 16
    ES_RS_WrongCurrentReflector = 23
    ES_RS_NoTPFound = 26
    ES_RS_NoWeathermonitorFound = 27
    ES_RS_NoLastMeasuredPoint = 28
    ES_RS_UsageConflict = 35
    ES_RS_Unknown = 36
    ES_RS_NoDistanceSet = 37
    ES_RS_NoTrackerConnected = 38
    ES_RS_TrackerNotInitialized = 39
    ES_RS_ModuleNotStarted = 40
    ES_RS_ModuleTimedOut = 41
    ES_RS_MeteoDataOutOfRange = 57
    ES_RS_NoMeasurementCamera = 67
    ES_RS_NoMeasurementProbe = 75
    ES_RS_NoActiveMeasurementProbe = 76
    ES_RS_6DModeNotAllowed = 92
    ES_RS_Bad6DResult = 93
    ES_RS_NoTemperatureFromWM = 94
    ES_RS_NoPressureFromWM = 95
    ES_RS_NoHumidityFromWM = 96
    ES_RS_6DMeasurementFace2NotAllowed = 97
    ES_RS_InvalidInputData = 98
    ES_RS_NoValidADMCompensation = ES_API_ERROR_OFFSET + 2
    ES_RS_PressureSensorProblem = ES_API_ERROR_OFFSET + 3
    ES_RS_MeasurementStatusNotReady = ES_API_ERROR_OFFSET + 4
    ES_RS_ADMStartUpBusy = ES_API_ERROR_OFFSET + 5  # alias of ES_RS_AIFMStartUpBusy
    ES_RS_NoAtr = ES_API_ERROR_OFFSET + 7
    ES_RS_NoStationaryResult = ES_API_ERROR_OFFSET + 9
    ES_RS_SensorNotLeveled = ES_API_ERROR_OFFSET + 10
    ES_RS_MultiConnectionsNotAllowed = ES_API_ERROR_OFFSET + 11
    ES_RS_SensorNotWarmedUp = ES_API_ERROR_OFFSET + 12
    ES_RS_SensorNotStable = ES_API_ERROR_OFFSET + 13
    ES_RS_SystemNotReadyForMeasurement = ES_API_ERROR_OFFSET + 14
    ES_RS_CommunicationWithSensorFailed = ES_API_ERROR_OFFSET + 15


class ES_TrackerProcessorStatus(IntEnum):  # noqa: N801
    """``enum ES_TrackerProcessorStatus``: start-up sequence; initialised is the last step."""

    ES_TPS_NoTPFound = 0
    ES_TPS_TPFound = 1
    ES_TPS_NBOpen = 2
    ES_TPS_Booted = 3
    ES_TPS_CompensationSet = 4
    ES_TPS_Initialized = 5


class ES_LaserProcessorStatus(IntEnum):  # noqa: N801
    """``enum ES_LaserProcessorStatus``: the laser warms up, then is ready."""

    ES_LPS_LCPCommFailed = 0
    ES_LPS_LCPNotAvail = 1
    ES_LPS_LaserHeatingUp = 2
    ES_LPS_LaserReady = 3
    ES_LPS_UnableToStabilize = 4
    ES_LPS_LaserOff = 5


class ES_ADMStatus(IntEnum):  # noqa: N801
    """``enum ES_ADMStatus``."""

    ES_AS_NoADM = 0
    ES_AS_ADMCommFailed = 1
    ES_AS_ADMReady = 2
    ES_AS_ADMBusy = 3
    ES_AS_HWError = 4
    ES_AS_SecurityLockActive = 5
    ES_AS_NotCompensated = 6


class ES_WeatherMonitorStatus(IntEnum):  # noqa: N801
    """``enum ES_WeatherMonitorStatus``: whether a weather station feeds the tracker."""

    ES_WMS_NotConnected = 0
    ES_WMS_ReadOnly = 1
    ES_WMS_ReadAndCalculateRefractions = 2


class ES_SystemStatusChange(IntEnum):  # noqa: N801
    """``enum ES_SystemStatusChange``: what a SystemStatusChangeT packet announces."""

    ES_SSC_DistanceSet = 0
    ES_SSC_LaserWarmedUp = 1
    ES_SSC_EnvironmentParamsChanged = 2
    ES_SSC_RefractionParamsChanged = 3
    ES_SSC_SearchParamsChanged = 4
    ES_SSC_AdmParamsChanged = 5
    ES_SSC_UnitsChanged = 6
    ES_SSC_ReflectorChanged = 7
    ES_SSC_SystemSettingsChanged = 8
    ES_SSC_TemperatureRangeChanged = 9
    ES_SSC_CameraParamsChanged = 10
    ES_SSC_CompensationChanged = 11
    ES_SSC_CoordinateSystemTypeChanged = 12
    ES_SSC_StationOrientationParamsChanged = 15
    ES_SSC_TransformationParamsChanged = 16
    ES_SSC_MeasurementModeChanged = 17
    ES_SSC_StationaryModeParamsChanged = 18
    ES_SSC_StatisticModeChanged = 24
    ES_SSC_MeasStatus_NotReady = 25
    ES_SSC_MeasStatus_Busy = 26
    ES_SSC_MeasStatus_Ready = 27
    ES_SSC_IsFace1 = 30
    ES_SSC_IsFace2 = 31
    ES_SSC_ProbeChanged = 36
    ES_SSC_MeasStatus_6DStatusInvalid = 99
    ES_SSC_ObjectTemperatureChanged = 105
    ES_SCC_InitializationStatusChanged = 151  # sic: the header's own typo
    ES_SCC_TiltSensorStatusChanged = 152  # sic
    ES_SSC_SensorDetected = 850
    ES_SSC_SensorDisconnected = 851
    ES_SSC_TPConnectionClosing = 997
    ES_SSC_ServerClosing = 998
    ES_SSC_ServerStarted = 999


class ES_TrackerFace(IntEnum):  # noqa: N801
    """``enum ES_TrackerFace`` (GetFace)."""

    ES_TF_Unknown = 0
    ES_TF_Face1 = 1
    ES_TF_Face2 = 2


class ES_MeasurementStatusInfo(IntEnum):  # noqa: N801
    """``enum ES_MeasurementStatusInfo``: bit flags of GetMeasurementStatusInfo."""

    ES_MSI_Unknown = 0
    ES_MSI_TrackerFound = 1
    ES_MSI_TrackerCompensationFound = 2
    ES_MSI_ADMFound = 4
    ES_MSI_ADMCompensationFound = 8
    ES_MSI_MeasurementCameraFound = 16
    ES_MSI_InternalCameraParamsOK = 32
    ES_MSI_CameraToTrackerParamsFound = 64
    ES_MSI_MeasurementProbeFound = 128
    ES_MSI_ProbeParamsFound = 256
    ES_MSI_ReflectorFound = 2048
    ES_MSI_InFace1 = 4096
    ES_MSI_SensorBatteryMounted = 16384
    ES_MSI_NivelInWorkingRange = 32768
    ES_MSI_Initialized = 65536


class ES_ProbeType(IntEnum):  # noqa: N801
    """``enum ES_ProbeType`` (GetProbes): a T-Mac is a machine control probe."""

    ES_PT_None = 0
    ES_PT_Reflector = 1
    ES_PT_TProbe = 2
    ES_PT_TScan = 3
    ES_PT_MachineControlProbe = 4
    ES_PT_MachineControlProbeMultiSide = 5
    ES_PT_TCamToTrackerTool = 100
    ES_PT_ZoomArtifactTool = 200


class ES_TriggerStatus(IntEnum):  # noqa: N801
    """``enum ES_TriggerStatus``: the probe's trigger button in a 6D result."""

    ES_TS_TriggerNotPressed = 0
    ES_TS_TriggerPressed = 1


class ES_MeasurementTipStatus(IntEnum):  # noqa: N801
    """``enum ES_MeasurementTipStatus`` in a 6D result."""

    ES_PTS_TipOK = 0
    ES_PTS_UnknownTip = 1
    ES_PTS_MultipleTipsAttached = 2


#: ``struct RotationStatus`` (the bit fields of ``lRotationStatus`` in a 6D result, the
#: first declared the lowest bit): bit -> name; Status6D set means the rotation is valid
ROTATION_STATUS_BITS = {
    0: "Status6D", 1: "Error6D", 2: "NotEnoughLED", 3: "RMSToHigh", 4: "AngleOutOfRange",
    5: "Frozen6DValues", 6: "DistanceOutOfRange", 16: "Face2",
}


# ---------------------------------------------------------------- Enum.h
class ES_LengthUnit(IntEnum):  # noqa: N801
    """``enum ES_LengthUnit`` (Enum.h)."""

    ES_LU_Meter = 0
    ES_LU_Millimeter = 1
    ES_LU_Micron = 2
    ES_LU_Foot = 3
    ES_LU_Yard = 4
    ES_LU_Inch = 5


class ES_AngleUnit(IntEnum):  # noqa: N801
    """``enum ES_AngleUnit`` (Enum.h)."""

    ES_AU_Radian = 0
    ES_AU_Degree = 1
    ES_AU_Gon = 2


class ES_TemperatureUnit(IntEnum):  # noqa: N801
    """``enum ES_TemperatureUnit`` (Enum.h)."""

    ES_TU_Celsius = 0
    ES_TU_Fahrenheit = 1


class ES_PressureUnit(IntEnum):  # noqa: N801
    """``enum ES_PressureUnit`` (Enum.h); mbar is the server's default."""

    ES_PU_Mbar = 0
    ES_PU_HPascal = 1
    ES_PU_KPascal = 2
    ES_PU_MmHg = 3
    ES_PU_Psi = 4
    ES_PU_InH2O = 5
    ES_PU_InHg = 6


class ES_HumidityUnit(IntEnum):  # noqa: N801
    """``enum ES_HumidityUnit`` (Enum.h)."""

    ES_HU_RH = 0


class ES_CoordinateSystemType(IntEnum):  # noqa: N801
    """``enum ES_CoordinateSystemType`` (Enum.h): RHR is right-handed rectangular."""

    ES_CS_RHR = 0
    ES_CS_LHRX = 1
    ES_CS_LHRY = 2
    ES_CS_LHRZ = 3
    ES_CS_CCW = 4
    ES_CS_CCC = 5
    ES_CS_SCW = 6
    ES_CS_SCC = 7


def name_of(enum: type[IntEnum], value: int) -> str:
    """The header's name of ``value`` in ``enum``, or ``"<enum name> <value>"`` when unknown."""
    try:
        return enum(value).name
    except ValueError:
        return f"{enum.__name__} {value}"
