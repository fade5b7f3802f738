"""emScon TPI 6-DoF packets: the probe (6D) structs of ``ES_C_API_Def.h`` (TPI/SDK 3.6).

The part of the codec for 6-DoF targets (a T-Mac on a robot, a T-Probe): the
stationary 6D result ``ProbeStationaryResultT`` (``ES_DT_StationaryProbeMeasResult``,
measured in ``ES_MM_6DStationary``), the live ``ProbePosResultT``
(``ES_DT_ProbePosResult``), and the probe queries ``GetProbes`` / ``GetProbe``. The
header has no command that selects a probe: the tracker's camera recognises the probe
in view, and ``GetProbe`` says which one it is. Same conventions as
:mod:`drivers.leica.codec` (4-byte packing, 32-bit ``long`` and enums, UTF-16 strings),
on the same :class:`~drivers.leica.codec.Packet` base: :func:`drivers.leica.codec.decode`
knows these packets once this module is imported (the ``drivers.leica`` package does).

The quaternion ``dQuaternion0..3`` is (w, x, y, z), scalar first, the probe's
orientation in the tracker's coordinate system (it turns probe-frame vectors into
tracker ones). The header gives standard deviations for the rotation angles
``dRotationAngleX/Y/Z`` (in the server's angle unit), not for the quaternion; it does
not say in which order the angles compose, so this package reads the orientation from
the quaternion alone and the angles' standard deviations as the uncertainty of small
rotations about the tracker's x, y, z axes.
"""

from __future__ import annotations

from drivers.leica.codec import CT, RETURN_DATA, RT, WSTRING, AnswerRT, CommandCT, Packet
from drivers.leica.enums import ES_Command as C
from drivers.leica.enums import ES_DataType as DT

#: position, its statistics (std, total, covariances; a-priori ones) of a 6D result
_POSITION = (
    ("dPosition1", "d"), ("dPosition2", "d"), ("dPosition3", "d"),
    ("dStdDevPosition1", "d"), ("dStdDevPosition2", "d"), ("dStdDevPosition3", "d"),
    ("dStdDevPositionTotal", "d"),
    ("dCovarPosition12", "d"), ("dCovarPosition13", "d"), ("dCovarPosition23", "d"),
    ("dAprioriStdDevPosition1", "d"), ("dAprioriStdDevPosition2", "d"),
    ("dAprioriStdDevPosition3", "d"), ("dAprioriStdDevPositionTotal", "d"),
    ("dAprioriCovarPosition12", "d"), ("dAprioriCovarPosition13", "d"),
    ("dAprioriCovarPosition23", "d"),
)
#: the orientation: quaternion, rotation angles, their statistics
_ROTATION = (
    ("dQuaternion0", "d"), ("dQuaternion1", "d"), ("dQuaternion2", "d"), ("dQuaternion3", "d"),
    ("dRotationAngleX", "d"), ("dRotationAngleY", "d"), ("dRotationAngleZ", "d"),
    ("dStdDevRotationAngleX", "d"), ("dStdDevRotationAngleY", "d"),
    ("dStdDevRotationAngleZ", "d"), ("dStdDevRotationAngleTotal", "d"),
    ("dCovarRotationAngleXY", "d"), ("dCovarRotationAngleXZ", "d"),
    ("dCovarRotationAngleYZ", "d"),
    ("dAprioriStdDevRotationAngleX", "d"), ("dAprioriStdDevRotationAngleY", "d"),
    ("dAprioriStdDevRotationAngleZ", "d"), ("dAprioriStdDevRotationAngleTotal", "d"),
    ("dAprioriCovarRotationAngleXY", "d"), ("dAprioriCovarRotationAngleXZ", "d"),
    ("dAprioriCovarRotationAngleYZ", "d"),
)


class ProbeStationaryResultT(Packet):
    """``struct ProbeStationaryResultT``: one stationary 6D measurement (position of the
    probe's reference point or tip, orientation, their statistics, the air)."""

    TYPE = DT.ES_DT_StationaryProbeMeasResult
    RESULT = True
    FIELDS = (*RETURN_DATA, ("measMode", "i"), ("bIsTryMode", "i"), ("triggerStatus", "i"),
              ("lRotationStatus", "i"), ("iInternalProbeId", "i"), ("iFieldNumber", "i"),
              ("tipStatus", "i"), ("iInternalTipAdapterId", "i"), ("iTipAdapterInterface", "i"),
              *_POSITION, *_ROTATION,
              ("dTemperature", "d"), ("dPressure", "d"), ("dHumidity", "d"))


class ProbePosResultT(Packet):
    """``struct ProbePosResultT``: the live 6D position while locked on (when switched on)."""

    TYPE = DT.ES_DT_ProbePosResult
    RESULT = True
    FIELDS = (*RETURN_DATA, ("lRotationStatus", "i"), ("tipStatus", "i"),
              ("iInternalTipAdapterId", "i"), ("iTipAdapterInterface", "i"),
              ("dPosition1", "d"), ("dPosition2", "d"), ("dPosition3", "d"),
              ("dQuaternion0", "d"), ("dQuaternion1", "d"), ("dQuaternion2", "d"),
              ("dQuaternion3", "d"),
              ("dRotationAngleX", "d"), ("dRotationAngleY", "d"), ("dRotationAngleZ", "d"))


class GetProbesCT(CommandCT):
    COMMAND, FIELDS = C.ES_C_GetProbes, CT


class GetProbesRT(AnswerRT):
    """One packet per probe; ``iTotalProbes`` says how many follow in all."""

    COMMAND = C.ES_C_GetProbes
    FIELDS = (*RT, ("iTotalProbes", "i"), ("iInternalProbeId", "i"), ("lSerialNumber", "i"),
              ("probeType", "i"), ("iNumberOfFields", "i"), ("cName", WSTRING),
              ("cComment", "256s"))


class GetProbeCT(CommandCT):
    COMMAND, FIELDS = C.ES_C_GetProbe, CT


class GetProbeRT(AnswerRT):
    """The probe the tracker's camera sees now (its ``iInternalProbeId``)."""

    COMMAND, FIELDS = C.ES_C_GetProbe, (*RT, ("iInternalProbeId", "i"))
