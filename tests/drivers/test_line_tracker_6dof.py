"""The line protocol's optional 6-DoF reading, MEAS6D: the exact exchange (transcript),
the driver against the simulated tracker, and the refusals."""

from __future__ import annotations

import numpy as np
import pytest

from calibration.model.transforms import matrix_to_quat, quat_angle
from drivers.errors import CommandRejected, ProtocolError
from drivers.protocols import PoseMeasurement
from drivers.urls import open_tracker
from sim_drivers.cell import SimCell
from sim_drivers.model_truth import ModelTruth
from sim_drivers.tracker_server import TrackerServer
from tests.sim_drivers.helpers import ScriptedPeer, measure_pose_at, tmac_cell

HELLO = ("HELLO", ["OK HELLO TRK 1 1.0"])
STATUS = ("STATUS?", ["OK STATUS init=1 warm=1 beam=1"])
MODE = ("SET MODE STATIONARY time_ms=200", ["OK MODE STATIONARY time_ms=200"])
REPLY = ("OK MEAS6D x=1000.5 y=-2.0 z=300.25 sx=0.01 sy=0.02 sz=0.03 qw=0.5 qx=0.5 "
         "qy=-0.5 qz=0.5 sdx=0.01 sdy=0.02 sdz=0.02 target=TMAC n=200 T=21.5 P=1000.0 "
         "H=40.0 face=1 t=1700000000.5 seq=4")


def _pose(reply: str):
    with ScriptedPeer([HELLO, STATUS, MODE, ("MEAS6D", [reply])]) as peer:
        m = measure_pose_at(f"tracker+tcp://127.0.0.1:{peer.port}", 0.2)
        peer.check()
        return m


def test_meas6d_exchange_and_reading():
    m = _pose(REPLY)
    assert isinstance(m, PoseMeasurement)
    assert np.array_equal(m.xyz, [1000.5, -2.0, 300.25])
    np.testing.assert_allclose(m.quat, [0.5, 0.5, -0.5, 0.5])
    np.testing.assert_allclose(m.std_deg, [0.01, 0.02, 0.02])
    assert m.sigma_deg == pytest.approx(np.sqrt(0.0009 / 3))
    assert m.target == "TMAC" and m.n == 200 and m.face == 1
    assert m.env == {"temp_c": 21.5, "pressure_hpa": 1000.0, "humidity_pct": 40.0}


@pytest.mark.parametrize("change", [("qw=0.5", "qw=0.6"), (" sdz=0.02", ""),
                                    ("sdx=0.01", "sdx=nan")])
def test_a_bad_6d_reply_is_a_protocol_error(change):
    with pytest.raises(ProtocolError, match="MEAS6D"):
        _pose(REPLY.replace(*change))


def test_against_the_simulated_tracker():
    cell = tmac_cell(8)
    with TrackerServer(cell) as srv, open_tracker(srv.url) as trk:
        trk.connect(5.0)
        m, p = trk.measure_pose(0.1, 5.0), trk.measure(0.1, 5.0)
        trk.change_face(5.0)
        with pytest.raises(CommandRejected, match="FACE2_6D"):
            trk.measure_pose(0.1, 5.0)
    assert np.degrees(quat_angle(m.quat, matrix_to_quat(cell.true_orientation()))) < 0.1
    truth_xyz = cell.true_point()
    for reading in (m, p):
        assert np.all(np.abs(reading.xyz - truth_xyz) < 6 * cell.tracker_sigma(truth_xyz))
    assert m.target == "T-Mac_TMC30-F" and m.sigma_deg == pytest.approx(0.01, rel=0.2)


def test_without_a_6dof_target_meas6d_is_refused():
    cell = SimCell(ModelTruth.from_spec("ur10e", None, 8), seed=8)
    with TrackerServer(cell) as srv, open_tracker(srv.url) as trk:
        trk.connect(5.0)
        with pytest.raises(CommandRejected, match="NO_6DOF_TARGET"):
            trk.measure_pose(0.1, 5.0)
