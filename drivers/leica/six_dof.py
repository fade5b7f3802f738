"""The 6-DoF capability of :class:`~drivers.leica.driver.EmsconTracker`: a T-Mac's pose.

A mixin, apart so that each module stays readable: :meth:`EmsconSixDof.measure_pose`
switches the server to ``ES_MM_6DStationary`` (the driver keeps the mode it wants
and sets it again whenever another client or a reconnect changed it, as for every
setting), starts one measurement and reads the ``ProbeStationaryResultT``
(:mod:`drivers.leica.probe_packets`); :meth:`EmsconSixDof.probes` lists the 6-DoF
targets the server knows (``GetProbes``) and :meth:`EmsconSixDof.probe` the one the
camera sees (``GetProbe``). emScon has no command to choose a probe: the camera
recognises the one in view.

A result whose rotation status (``lRotationStatus``, ``struct RotationStatus``) is
not valid (``Status6D`` clear, or ``Error6D``, ``NotEnoughLED``... set) is
:class:`~drivers.errors.BeamBroken`: the target was not seen well enough at that
pose, as a broken beam. A quaternion whose length is not 1 (within 1e-6) is a
:class:`~drivers.errors.ProtocolError`.
"""

from __future__ import annotations

import time
from typing import TYPE_CHECKING, Any

import numpy as np

from drivers.errors import BeamBroken, ProtocolError
from drivers.leica import codec, probe_packets
from drivers.leica.enums import ROTATION_STATUS_BITS, ES_MeasMode, ES_ProbeType, name_of
from drivers.protocols import Measurement, PoseMeasurement

#: largest accepted | |q| - 1 | of a quaternion on the wire (the server computes in doubles)
QUAT_TOLERANCE = 1e-6


class EmsconSixDof:
    """SixDof over emScon (``measure_pose``, ``probes``, ``probe``)."""

    # what the driver (:class:`~drivers.leica.driver.EmsconTracker`) gives this mixin
    _dev: str
    #: probe id -> name, learnt by GetProbes (None: not asked yet)
    _probe_names: dict[int, str] | None
    if TYPE_CHECKING:
        def _resync(self, deadline: float) -> None: ...

        def _call(self, packet: codec.Packet, deadline: float,
                  answers: int = 1) -> list[codec.Packet]: ...

        def _measure_in(self, mode: int, duration_s: float, deadline: float
                        ) -> Measurement: ...

        def _fields(self, p: codec.Packet, xyz: np.ndarray, std: np.ndarray,
                    covar: tuple[float, float, float] | None = None) -> dict[str, Any]: ...

    def probes(self, timeout: float = 2.0) -> dict[int, str]:
        """GetProbes: the 6-DoF targets the server knows, id -> "name (type)"."""
        deadline = time.monotonic() + timeout
        self._resync(deadline)
        self._probe_names = {}
        for p in self._call(probe_packets.GetProbesCT(), deadline):
            if p.iTotalProbes == 0:
                break
            kind = name_of(ES_ProbeType, p.probeType).removeprefix("ES_PT_")
            name = codec.wstring(p.cName) or f"probe {p.iInternalProbeId}"
            self._probe_names[int(p.iInternalProbeId)] = f"{name} ({kind})"
        return dict(self._probe_names)

    def probe(self, timeout: float = 2.0) -> int:
        """GetProbe: the id of the probe the tracker's camera sees now (0: none)."""
        deadline = time.monotonic() + timeout
        self._resync(deadline)
        return int(self._call(probe_packets.GetProbeCT(), deadline)[0].iInternalProbeId)

    def measure_pose(self, duration_s: float = 0.5, timeout: float = 10.0) -> PoseMeasurement:
        """One 6D stationary measurement of ``duration_s`` s: position (mm) and orientation
        (unit quaternion, tracker frame) of the 6-DoF target with their uncertainties.

        The first call learns the probes' names (``GetProbes``) for ``target``.
        """
        deadline = time.monotonic() + timeout
        if self._probe_names is None:
            self.probes(max(deadline - time.monotonic(), 0.01))
        m = self._measure_in(ES_MeasMode.ES_MM_6DStationary, duration_s, deadline)
        if not isinstance(m, PoseMeasurement):
            raise ProtocolError(self._dev, "ES_C_StartMeasurement",
                                "a 3D result in 6D stationary mode")
        return m

    def _to_pose(self, p: codec.Packet) -> PoseMeasurement:
        """A ProbeStationaryResultT as a PoseMeasurement (the driver's units: mm, rad)."""
        command = "ES_C_StartMeasurement"
        status = int(p.lRotationStatus)
        bad = [name for bit, name in ROTATION_STATUS_BITS.items()
               if bit not in (0, 16) and status >> bit & 1]
        if not status & 1 or bad:
            raise BeamBroken(self._dev, command, "6D rotation status invalid "
                             f"({', '.join(bad) or 'Status6D not set'}): the 6-DoF target "
                             "was not seen well enough")
        xyz = np.array([p.dPosition1, p.dPosition2, p.dPosition3], float)
        std = np.array([p.dStdDevPosition1, p.dStdDevPosition2, p.dStdDevPosition3], float)
        quat = np.array([p.dQuaternion0, p.dQuaternion1, p.dQuaternion2, p.dQuaternion3])
        std_rad = np.array([p.dStdDevRotationAngleX, p.dStdDevRotationAngleY,
                            p.dStdDevRotationAngleZ], float)
        if not all(np.all(np.isfinite(v)) for v in (xyz, std, quat, std_rad)):
            raise ProtocolError(self._dev, command, "non-finite 6D result")
        norm = float(np.linalg.norm(quat))
        if abs(norm - 1.0) > QUAT_TOLERANCE:
            raise ProtocolError(self._dev, command, f"quaternion of length {norm:.9g}, not 1")
        covar = (p.dCovarPosition12, p.dCovarPosition13, p.dCovarPosition23)
        std_deg = np.degrees(std_rad)
        pid = int(p.iInternalProbeId)
        return PoseMeasurement(
            **self._fields(p, xyz, std, covar), quat=quat / norm, std_deg=std_deg,
            sigma_deg=float(np.sqrt(np.mean(std_deg**2))),
            target=(self._probe_names or {}).get(pid, f"probe {pid}"),
        )
