"""The simulated emScon server, spoken to packet by packet over a real socket."""

from __future__ import annotations

import socket
import struct

import numpy as np
import pytest

from drivers.leica import codec
from drivers.leica.enums import ES_Command as C
from drivers.leica.enums import ES_CoordinateSystemType as CS
from drivers.leica.enums import ES_ResultStatus as RS
from drivers.leica.enums import ES_SystemStatusChange as SSC
from drivers.leica.framing import FrameReader
from sim_drivers.emscon_server import EmsconServer
from tests.sim_drivers.helpers import make_cell


class RawClient:
    """Packets in and out, nothing interpreted."""

    def __init__(self, port: int) -> None:
        self.sock = socket.create_connection(("127.0.0.1", port), timeout=2.0)
        self.frames = FrameReader()
        self.inbox: list = []

    def send(self, packet) -> None:
        self.sock.sendall(packet if isinstance(packet, bytes) else packet.pack())

    def read(self, n: int = 1) -> list:
        while len(self.inbox) < n:
            data = self.sock.recv(4096)
            assert data, "server closed"
            self.inbox += [codec.decode(f) for f in self.frames.feed(data)]
        out, self.inbox = self.inbox[:n], self.inbox[n:]
        return out

    def answer(self, packet, n: int = 1) -> list:
        """Send, then return the next ``n`` packets that are not status changes."""
        self.send(packet)
        out = []
        while len(out) < n:
            p = self.read()[0]
            if not isinstance(p, codec.SystemStatusChangeT):
                out.append(p)
        return out

    def close(self) -> None:
        self.sock.close()


@pytest.fixture
def cell():
    return make_cell(seed=2, tracker_initialised=True)


@pytest.fixture
def server(cell):
    with EmsconServer(cell) as srv:
        yield srv


@pytest.fixture
def client(server):
    c = RawClient(server.port)
    yield c
    c.close()


def test_unknown_command_gets_its_own_number_and_not_implemented(client):
    (a,) = client.answer(codec.BasicCommandCT(command=C.ES_C_Park))
    assert isinstance(a, codec.BasicCommandRT)
    assert (a.command, a.status) == (C.ES_C_Park, RS.ES_RS_NotImplemented)
    (a,) = client.answer(codec.BasicCommandCT(command=4321))
    assert (a.command, a.status) == (4321, RS.ES_RS_NotImplemented)


def test_a_packet_that_is_no_command_is_an_error_response(client):
    (a,) = client.answer(codec.SystemStatusChangeT(systemStatusChange=6))
    assert isinstance(a, codec.ErrorResponseT) and a.status == RS.ES_RS_InvalidInputData


def test_units_persist_on_the_server_and_other_clients_hear_of_changes(server, client):
    other = RawClient(server.port)
    try:
        other.answer(codec.GetFaceCT())  # connected and served: it will hear broadcasts
        (a,) = client.answer(codec.SetUnitsCT(lenUnitType=5, pressUnitType=4))
        assert a.status == 0
        (change,) = other.read()
        assert change.systemStatusChange == SSC.ES_SSC_UnitsChanged
    finally:
        other.close()
    late = RawClient(server.port)  # a client connecting later sees the same units
    try:
        (u,) = late.answer(codec.GetUnitsCT())
        assert (u.lenUnitType, u.pressUnitType) == (5, 4)
    finally:
        late.close()


def test_bad_parameters_are_rejected_with_the_parameter_number(client):
    (a,) = client.answer(codec.SetUnitsCT(lenUnitType=1, tempUnitType=7))
    assert a.status == RS.ES_RS_WrongParameter3
    (a,) = client.answer(codec.SetStationaryModeParamsCT(lMeasTime=0))
    assert a.status == RS.ES_RS_Parameter1OutOfRangeNOK
    (a,) = client.answer(codec.SetMeasurementModeCT(measMode=1))
    assert a.status == RS.ES_RS_NotImplemented
    (a,) = client.answer(codec.SetReflectorCT(iInternalReflectorId=99))
    assert a.status == RS.ES_RS_WrongParameter1


def test_get_reflectors_sends_one_answer_per_reflector(client):
    answers = client.answer(codec.GetReflectorsCT(), n=5)
    assert [a.iInternalReflectorId for a in answers] == [1, 2, 3, 4, 5]
    assert {a.iTotalReflectors for a in answers} == {5}
    assert codec.wstring(answers[0].cReflectorName) == "RRR 1.5in"


def test_measurement_in_metres_and_spherical_degrees(cell, client):
    truth = cell.true_point()
    sigma = cell.tracker_sigma(truth)
    client.answer(codec.SetUnitsCT(lenUnitType=0, angUnitType=1))  # m, degrees
    rt, res = client.answer(codec.StartMeasurementCT(), n=2)
    assert rt.status == 0 and isinstance(res, codec.SingleMeasResult2T)
    assert np.allclose([res.dVal1, res.dVal2, res.dVal3], truth / 1000.0, atol=6 * sigma / 1e3)
    client.answer(codec.SetCoordinateSystemTypeCT(coordSysType=CS.ES_CS_SCC))
    rt, res = client.answer(codec.StartMeasurementCT(), n=2)
    assert isinstance(res, codec.SingleMeasResultT)  # no covariances outside rectangular
    hz, v, d = res.dVal1, res.dVal2, res.dVal3
    assert d == pytest.approx(np.linalg.norm(truth) / 1000.0, abs=6 * sigma / 1e3)
    assert hz == pytest.approx(np.degrees(np.arctan2(truth[1], truth[0])), abs=1e-3)
    assert v == pytest.approx(np.degrees(np.arccos(truth[2] / np.linalg.norm(truth))), abs=1e-3)


def test_faults_carry_the_real_codes(cell, client):
    cell.tracker_initialised = False
    (rt,) = client.answer(codec.StartMeasurementCT())
    assert rt.status == RS.ES_RS_TrackerNotInitialized == 39
    (rt,) = client.answer(codec.ChangeFaceCT())
    assert rt.status == 39
    client.answer(codec.InitializeCT())
    cell.warmup_s = cell.now() + 100
    (rt,) = client.answer(codec.StartMeasurementCT())
    assert rt.status == RS.ES_RS_SensorNotWarmedUp == 10012
    cell.warmup_s = 0
    cell.beam_ok = False
    (rt,) = client.answer(codec.StartMeasurementCT())
    assert rt.status == RS.ES_RS_MeasurementStatusNotReady == 10004
    cell.beam_ok = True
    cell.faults.arm("beam")
    client.send(codec.StartMeasurementCT())
    rt, lost, err, back = client.read(4)
    assert rt.status == 0
    assert lost.systemStatusChange == SSC.ES_SSC_MeasStatus_NotReady == 25
    assert isinstance(err, codec.ErrorResponseT)
    assert (err.command, err.status) == (C.ES_C_StartMeasurement, RS.ES_RS_NoStationaryResult)
    assert back.systemStatusChange == SSC.ES_SSC_MeasStatus_Ready


def test_change_face_announces_the_face(cell, client):
    client.send(codec.ChangeFaceCT())
    change, rt = client.read(2)  # the change is announced before the answer
    assert change.systemStatusChange == SSC.ES_SSC_IsFace2 and rt.status == 0
    (f,) = client.answer(codec.GetFaceCT())
    assert f.trackerFace == 2 and cell.tracker_face == 2


def test_garbage_from_the_server_has_an_impossible_length(cell, client):
    cell.faults.arm("garbage")
    client.send(codec.GetFaceCT())
    data = client.sock.recv(64)
    (size,) = struct.unpack_from("<i", data)
    assert size > 4096
