"""EmsconTracker against a scripted emScon peer: the exact packets of connect and measure.

The peer (the line-protocol transcript peer, speaking packets) follows a
transcript of (expected command packet, [reply packets]) on a real TCP socket and
fails on a packet it did not expect or an exchange that never happened.
"""

from __future__ import annotations

import numpy as np
import pytest

from drivers.leica import codec
from drivers.leica.enums import ES_SystemStatusChange, ES_TrackerProcessorStatus
from drivers.leica.framing import FrameReader
from drivers.urls import open_tracker
from tests.sim_drivers.helpers import ScriptedPeer


class ScriptedEmscon(ScriptedPeer):
    """:class:`ScriptedPeer` speaking emScon: requests are decoded command packets
    (compared field by field), replies are packets."""

    def _splitter(self):
        frames = FrameReader()
        return lambda data: [codec.decode(f, "server") for f in frames.feed(data)]

    @staticmethod
    def _encode(reply: codec.Packet) -> bytes:
        return reply.pack()


def _reflector(k: int, name: str) -> codec.GetReflectorsRT:
    return codec.GetReflectorsRT(iTotalReflectors=2, iInternalReflectorId=k, targetType=5,
                                 dSurfaceOffset=19.05, cReflectorName=codec.to_wstring(name))


def transcript(extra=()):
    return [
        (codec.SetUnitsCT(lenUnitType=1, angUnitType=0, tempUnitType=0, pressUnitType=1,
                          humUnitType=0), [codec.SetUnitsRT()]),
        (codec.SetCoordinateSystemTypeCT(coordSysType=0), [codec.SetCoordinateSystemTypeRT()]),
        (codec.SetMeasurementModeCT(measMode=0), [codec.SetMeasurementModeRT()]),
        (codec.GetReflectorsCT(), [_reflector(3, "RRR 1.5in"), _reflector(8, "RRR 0.5in")]),
        (codec.GetReflectorCT(), [codec.GetReflectorRT(iInternalReflectorId=8)]),
        (codec.GetFaceCT(), [codec.GetFaceRT(trackerFace=2)]),
        (codec.GetSystemStatusCT(), [codec.GetSystemStatusRT(
            trackerProcessorStatus=ES_TrackerProcessorStatus.ES_TPS_Initialized, laserStatus=3,
            weatherMonitorStatus=2)]),
        (codec.SetStationaryModeParamsCT(lMeasTime=250, bUseADM=0),
         [codec.SetStationaryModeParamsRT()]),
        (codec.StartMeasurementCT(), [
            codec.StartMeasurementRT(),
            codec.SystemStatusChangeT(
                systemStatusChange=ES_SystemStatusChange.ES_SSC_MeasStatus_Busy),
            codec.SingleMeasResult2T(dVal1=1000.5, dVal2=-2.0, dVal3=300.25, dStd1=0.01,
                                     dStd2=0.02, dStd3=0.03, dCovar12=1e-5, dTemperature=21.5,
                                     dPressure=1000.0, dHumidity=40.0),
        ]),
        *extra,
    ]


def _connect_and_measure(peer):
    trk = open_tracker(f"emscon://127.0.0.1:{peer.port}")
    try:
        trk.connect(2.0)
        return trk.measure(0.25, 2.0)
    finally:
        trk.close()


def test_connect_and_measure_exchange_exactly_these_packets():
    with ScriptedEmscon(transcript()) as peer:
        m = _connect_and_measure(peer)
        peer.check()
    assert np.array_equal(m.xyz, [1000.5, -2.0, 300.25])
    assert np.array_equal(m.std, [0.01, 0.02, 0.03])
    assert m.cov[0, 1] == m.cov[1, 0] == 1e-5 and m.cov[2, 2] == pytest.approx(9e-4)
    assert m.env == {"temp_c": 21.5, "pressure_hpa": 1000.0, "humidity_pct": 40.0}
    assert m.reflector == "RRR 0.5in" and m.face == 2


def test_an_unused_exchange_fails_the_transcript():
    extra = [(codec.GetUnitsCT(), [codec.GetUnitsRT(lenUnitType=1)])]
    with ScriptedEmscon(transcript(extra)) as peer:
        _connect_and_measure(peer)
        with pytest.raises(AssertionError, match="never happened"):
            peer.check()
