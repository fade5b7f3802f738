"""The simulated emScon server's 6-DoF part: probe queries and the 6D stationary result.

A mixin of :class:`~sim_drivers.emscon_server.EmsconSession`, apart so that each module
stays readable. With a 6-DoF target on the cell's tool (``SimCell(six_dof=...)``) the
server knows one probe (``GetProbes``: the T-Mac, ``ES_PT_MachineControlProbe``; its
camera always sees it, ``GetProbe``), accepts ``ES_MM_6DStationary`` and answers
``StartMeasurement`` there with a ``ProbeStationaryResultT``. Without one it has no 6D
camera: ``GetProbes`` lists none and ``SetMeasurementMode(ES_MM_6DStationary)`` is
``ES_RS_6DModeNotAllowed`` (92). The other 6D modes (continuous, grid...) are
``ES_RS_NotImplemented``, and so is 6D in a coordinate system other than RHR (a
simulator's limit).

Result fields: position and its standard deviations as the 3D result's, in the
server's units; the quaternion (w, x, y, z) of the target frame in the tracker frame;
``dRotationAngleX/Y/Z`` the simulator's reading of the header's rotation angles, the
fixed-axis x-y-z angles of R = Rz(Z)·Ry(Y)·Rx(X) (the header does not say), and their
standard deviations those of the simulated orientation noise, in the angle unit;
``lRotationStatus`` ``Status6D`` (valid), face 1.
"""

from __future__ import annotations

import numpy as np

from calibration.model.dh_conversion import urdf_rpy
from calibration.model.transforms import quat_to_matrix
from drivers.leica import codec, probe_packets
from drivers.leica.enums import (
    ES_MeasMode,
    ES_MeasurementStatusInfo,
    ES_ProbeType,
    ES_TriggerStatus,
)
from drivers.leica.units import PER_HPA, PER_MM, PER_RAD, temp_from_c

#: the header's RotationStatus bit Status6D: the rotation is valid
STATUS_6D_VALID = 1
#: measurement status info bits of a tracker with a 6D camera that sees its probe
SIX_DOF_FLAGS = (ES_MeasurementStatusInfo.ES_MSI_MeasurementCameraFound
                 | ES_MeasurementStatusInfo.ES_MSI_InternalCameraParamsOK
                 | ES_MeasurementStatusInfo.ES_MSI_CameraToTrackerParamsFound
                 | ES_MeasurementStatusInfo.ES_MSI_MeasurementProbeFound
                 | ES_MeasurementStatusInfo.ES_MSI_ProbeParamsFound)


class ProbeCommands:
    """GetProbes, GetProbe and the 6D result of an emScon session (``self.cell``,
    ``self.server``, ``self._answer`` come from the session)."""

    def _GetProbes(self, p):  # noqa: N802 - named after ES_C_GetProbes
        t = self.cell.six_dof
        if t is None:
            return [self._answer(probe_packets.GetProbesRT, iTotalProbes=0)], []
        return [self._answer(
            probe_packets.GetProbesRT, iTotalProbes=1, iInternalProbeId=t.probe_id,
            lSerialNumber=t.serial, probeType=ES_ProbeType.ES_PT_MachineControlProbe,
            iNumberOfFields=1, cName=codec.to_wstring(t.name),
            cComment=codec.to_wstring("cellcal simulator", 128))], []

    def _GetProbe(self, p):  # noqa: N802
        t = self.cell.six_dof
        return [self._answer(probe_packets.GetProbeRT,
                             iInternalProbeId=0 if t is None else t.probe_id)], []

    def six_dof_flags(self) -> int:
        """The GetMeasurementStatusInfo bits the 6-DoF target adds (0 without one)."""
        return int(SIX_DOF_FLAGS) if self.cell.six_dof is not None else 0

    def _probe_result(self, r) -> bytes:
        """A ProbeStationaryResultT of the cell's 6D reading ``r`` in the server's units."""
        u = self.server.units
        per_mm, per_rad = PER_MM[u[0]], PER_RAD[u[1]]
        pos = r.reading
        sd = np.asarray(pos.std, float) * per_mm
        rot_sd = np.radians(np.asarray(r.std_deg, float)) * per_rad
        roll, pitch, yaw = urdf_rpy(quat_to_matrix(r.quat))
        q = np.asarray(r.quat, float)
        return probe_packets.ProbeStationaryResultT(
            status=0, measMode=ES_MeasMode.ES_MM_6DStationary, bIsTryMode=0,
            triggerStatus=ES_TriggerStatus.ES_TS_TriggerNotPressed,
            lRotationStatus=STATUS_6D_VALID, iInternalProbeId=r.probe_id, iFieldNumber=0,
            dPosition1=pos.xyz[0] * per_mm, dPosition2=pos.xyz[1] * per_mm,
            dPosition3=pos.xyz[2] * per_mm,
            dStdDevPosition1=sd[0], dStdDevPosition2=sd[1], dStdDevPosition3=sd[2],
            dStdDevPositionTotal=float(np.linalg.norm(sd)),
            dAprioriStdDevPosition1=sd[0], dAprioriStdDevPosition2=sd[1],
            dAprioriStdDevPosition3=sd[2], dAprioriStdDevPositionTotal=float(np.linalg.norm(sd)),
            dQuaternion0=q[0], dQuaternion1=q[1], dQuaternion2=q[2], dQuaternion3=q[3],
            dRotationAngleX=roll * per_rad, dRotationAngleY=pitch * per_rad,
            dRotationAngleZ=yaw * per_rad,
            dStdDevRotationAngleX=rot_sd[0], dStdDevRotationAngleY=rot_sd[1],
            dStdDevRotationAngleZ=rot_sd[2],
            dStdDevRotationAngleTotal=float(np.linalg.norm(rot_sd)),
            dAprioriStdDevRotationAngleX=rot_sd[0], dAprioriStdDevRotationAngleY=rot_sd[1],
            dAprioriStdDevRotationAngleZ=rot_sd[2],
            dAprioriStdDevRotationAngleTotal=float(np.linalg.norm(rot_sd)),
            dTemperature=temp_from_c(pos.temp_c, u[2]), dPressure=pos.pressure_hpa * PER_HPA[u[3]],
            dHumidity=pos.humidity_pct,
        ).pack()
