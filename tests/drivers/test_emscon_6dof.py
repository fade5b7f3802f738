"""emScon 6-DoF: the probe structs against ES_C_API_Def.h, the exact packets of a 6D
measurement (transcript), the driver against the simulated server (units another client
set, refusals), and what the CESAPI client can and cannot do with 6D."""

from __future__ import annotations

import time

import numpy as np
import pytest

from calibration.model.transforms import matrix_to_quat, quat_angle
from drivers.errors import BeamBroken, CommandRejected, ProtocolError
from drivers.leica import codec, probe_packets
from drivers.leica.enums import ES_MeasMode, ES_ResultStatus, ES_TrackerProcessorStatus
from drivers.protocols import PoseMeasurement
from drivers.urls import open_tracker
from sim_drivers.cell import SimCell
from sim_drivers.emscon_server import EmsconServer
from sim_drivers.model_truth import ModelTruth
from tests.drivers.test_emscon_transcript import ScriptedEmscon, transcript
from tests.sim_drivers.helpers import measure_pose_at, tmac_cell

#: sizes from the header (4-byte packing): 12 bytes ReturnDataT + 9 ints + 41 doubles...
HEADER_SIZES = {"ProbeStationaryResultT": 12 + 9 * 4 + 41 * 8,
                "ProbePosResultT": 12 + 4 * 4 + 10 * 8,
                "GetProbesCT": 12, "GetProbesRT": 16 + 5 * 4 + 64 + 256,
                "GetProbeCT": 12, "GetProbeRT": 20}


@pytest.mark.parametrize("name,size", sorted(HEADER_SIZES.items()))
def test_probe_struct_sizes_match_the_header(name, size):
    assert size == getattr(probe_packets, name).SIZE


def test_header_values_of_the_6d_enums():
    assert ES_MeasMode.ES_MM_6DStationary == 6 and ES_MeasMode.ES_MM_6DCircleCenter == 11
    assert ES_ResultStatus.ES_RS_6DModeNotAllowed == 92
    assert ES_ResultStatus.ES_RS_6DMeasurementFace2NotAllowed == 97
    assert codec.RESULTS[4] is probe_packets.ProbeStationaryResultT
    assert codec.RESULTS[11] is probe_packets.ProbePosResultT


def test_6d_packets_decode_by_type_and_command():
    r = probe_packets.ProbeStationaryResultT(dQuaternion0=1.0, dPosition2=-3.5)
    got = codec.decode(r.pack(), "client")
    assert got == r and got.dPosition2 == -3.5
    assert codec.decode(probe_packets.GetProbesCT().pack(), "server") == (
        probe_packets.GetProbesCT())
    assert isinstance(codec.decode(probe_packets.GetProbeRT(iInternalProbeId=3).pack()),
                      probe_packets.GetProbeRT)


def _result(**kw):
    base = dict(measMode=6, lRotationStatus=1, iInternalProbeId=7, dPosition1=1500.0,
                dPosition2=-20.0, dPosition3=400.0, dStdDevPosition1=0.01,
                dStdDevPosition2=0.01, dStdDevPosition3=0.02, dQuaternion0=0.5,
                dQuaternion1=0.5, dQuaternion2=-0.5, dQuaternion3=0.5,
                dStdDevRotationAngleX=np.radians(0.01), dStdDevRotationAngleY=np.radians(0.02),
                dStdDevRotationAngleZ=np.radians(0.02), dTemperature=21.0, dPressure=1000.0,
                dHumidity=40.0)
    return probe_packets.ProbeStationaryResultT(**{**base, **kw})


def pose_transcript(result):
    """connect (3D, as today), then measure_pose: GetProbes once, the mode switched to 6D
    (read back, then set), the stationary time, one StartMeasurement."""
    probes = probe_packets.GetProbesRT(iTotalProbes=1, iInternalProbeId=7, probeType=4,
                                       cName=codec.to_wstring("TMAC-7"))
    return transcript()[:7] + [
        (probe_packets.GetProbesCT(), [probes]),
        (codec.GetMeasurementModeCT(), [codec.GetMeasurementModeRT(measMode=0)]),
        (codec.SetMeasurementModeCT(measMode=6), [codec.SetMeasurementModeRT()]),
        (codec.SetStationaryModeParamsCT(lMeasTime=250, bUseADM=0),
         [codec.SetStationaryModeParamsRT()]),
        (codec.StartMeasurementCT(), [codec.StartMeasurementRT(), result]),
    ]


def _connect_and_measure_pose(peer):
    return measure_pose_at(f"emscon://127.0.0.1:{peer.port}", 0.25)


def test_measure_pose_exchanges_exactly_these_packets():
    with ScriptedEmscon(pose_transcript(_result())) as peer:
        m = _connect_and_measure_pose(peer)
        peer.check()
    assert isinstance(m, PoseMeasurement)
    assert np.array_equal(m.xyz, [1500.0, -20.0, 400.0])
    np.testing.assert_allclose(m.quat, [0.5, 0.5, -0.5, 0.5])
    np.testing.assert_allclose(m.std_deg, [0.01, 0.02, 0.02])
    assert m.sigma_deg == pytest.approx(np.sqrt((0.01**2 + 2 * 0.02**2) / 3))
    assert m.target == "TMAC-7 (MachineControlProbe)" and m.face == 2
    assert m.env == {"temp_c": 21.0, "pressure_hpa": 1000.0, "humidity_pct": 40.0}


@pytest.mark.parametrize("fields, error, words", [
    ({"lRotationStatus": 0}, BeamBroken, "Status6D not set"),
    ({"lRotationStatus": 1 | 4}, BeamBroken, "NotEnoughLED"),
    ({"dQuaternion0": 0.6}, ProtocolError, "quaternion of length"),
    ({"status": int(ES_ResultStatus.ES_RS_Bad6DResult)}, BeamBroken, "Bad6DResult"),
])
def test_a_bad_6d_result_is_a_typed_error(fields, error, words):
    with ScriptedEmscon(pose_transcript(_result(**fields))) as peer, pytest.raises(
            error, match=words):
        _connect_and_measure_pose(peer)


@pytest.fixture(scope="module")
def truth():
    return ModelTruth.from_spec("ur10e", None, 6)


def test_against_the_simulator_in_any_units_another_client_set():
    cell = tmac_cell(6)
    with EmsconServer(cell) as srv:
        trk = open_tracker(srv.url)
        trk.connect(5.0)
        try:
            assert trk.probes() == {1: "T-Mac TMC30-F (MachineControlProbe)"}
            assert trk.probe() == 1
            m = trk.measure_pose(0.1, 5.0)
            with open_tracker(srv.url) as other:  # another client: m, deg, 3D stationary
                other.connect(5.0)
                for packet in (codec.SetUnitsCT(lenUnitType=0, angUnitType=1),
                               codec.SetMeasurementModeCT(measMode=0)):
                    other._call(packet, time.monotonic() + 2.0)
            m2 = trk.measure_pose(0.1, 5.0)
            assert srv.units[:2] == (1, 0) and srv.meas_mode == 6
            p3 = trk.measure(0.1, 5.0)  # back to 3D: a Measurement of the same point
        finally:
            trk.close()
    R = matrix_to_quat(cell.true_orientation())
    for pose in (m, m2):
        assert np.degrees(quat_angle(pose.quat, R)) < 6 * 0.01 * np.sqrt(3)
        assert np.all(np.abs(pose.xyz - cell.true_point()) < 6 * cell.tracker_sigma(pose.xyz))
        assert pose.sigma_deg == pytest.approx(0.01, rel=0.2)
    assert type(p3).__name__ == "Measurement" and srv.meas_mode == 0


def test_no_6d_camera_and_face_2_are_refused(truth):
    with EmsconServer(SimCell(truth, seed=6)) as srv:
        trk = open_tracker(srv.url)
        trk.connect(5.0)
        try:
            with pytest.raises(CommandRejected, match="ES_RS_6DModeNotAllowed"):
                trk.measure_pose(0.1, 5.0)
            assert trk.probes() == {}
        finally:
            trk.close()
    with EmsconServer(tmac_cell(6)) as srv:
        trk = open_tracker(srv.url)
        trk.connect(5.0)
        try:
            trk.change_face(5.0)
            with pytest.raises(CommandRejected, match="6DMeasurementFace2NotAllowed"):
                trk.measure_pose(0.1, 5.0)
        finally:
            trk.close()


# -------------------------------------------------------------------- CESAPI
P = pytest.importorskip("CESAPI.packet")


def test_cesapi_1_1_3_has_no_6d_result_and_cannot_decode_one():
    """CESAPI 1.1.3 mirrors the AT4xx extract of the header: no ES_MM_6D* mode, no
    ES_DT_StationaryProbeMeasResult, no ProbeStationaryResultT, no GetProbes; its
    PacketFactory has no branch for a 6D result and fails on one."""
    assert not hasattr(P, "ES_MM_6DStationary") and not hasattr(P, "ProbeStationaryResultT")
    assert not hasattr(P, "ES_DT_StationaryProbeMeasResult") and not hasattr(P, "GetProbesCT")
    with pytest.raises(AttributeError):
        P.PacketFactory().packet(_result().pack())


@pytest.mark.timeout(120)
def test_cesapi_sets_the_6d_mode_by_number_and_measures_the_tmac_in_3d():
    """What CESAPI can do with a 6-DoF tracker: set ES_MM_6DStationary by its number (the
    server keeps it for our driver), read it back, and measure the T-Mac's reflector in 3D."""
    cmd_mod = pytest.importorskip("CESAPI.command")
    conn_mod = pytest.importorskip("CESAPI.connection")
    cell = tmac_cell(6, tracker_initialised=True)
    with EmsconServer(cell) as srv:
        conn = conn_mod.Connection()
        conn.connect(host=srv.host, port=srv.port)
        try:
            cmd = cmd_mod.CommandSync(conn)
            assert cmd.GetSystemStatus().trackerProcessorStatus == (
                ES_TrackerProcessorStatus.ES_TPS_Initialized)
            units = P.SystemUnitsDataT()
            units.lenUnitType, units.angUnitType = P.ES_LU_Millimeter, P.ES_AU_Radian
            units.pressUnitType = P.ES_PU_HPascal
            cmd.SetUnits(units)
            cmd.SetMeasurementMode(int(ES_MeasMode.ES_MM_6DStationary))
            assert cmd.GetMeasurementMode().measMode == 6
            cmd.SetMeasurementMode(P.ES_MM_Stationary)
            m = cmd.StartMeasurement()
            xyz = np.array([m.dVal1, m.dVal2, m.dVal3])
        finally:
            conn.disconnect()
    truth_xyz = cell.true_point()
    assert np.all(np.abs(xyz - truth_xyz) < 6 * cell.tracker_sigma(truth_xyz))
