"""Interoperation: the independent open-source emScon client CESAPI (MIT, PyPI ``CESAPI``)
talks to the simulated emScon tracker, and its points agree with the simulator's truth.

CESAPI is used through its public API: ``Connection.connect`` and ``CommandSync``'s
command methods, with its own packet classes (``SystemUnitsDataT``...).
"""

from __future__ import annotations

import numpy as np
import pytest

from sim_drivers.emscon_server import EmsconServer
from tests.sim_drivers.helpers import make_cell

cesapi_command = pytest.importorskip("CESAPI.command")
cesapi_connection = pytest.importorskip("CESAPI.connection")
P = pytest.importorskip("CESAPI.packet")


def _units(length: int):
    u = P.SystemUnitsDataT()
    u.lenUnitType = length
    u.angUnitType = P.ES_AU_Radian
    u.tempUnitType = P.ES_TU_Celsius
    u.pressUnitType = P.ES_PU_HPascal
    u.humUnitType = P.ES_HU_RH
    return u


@pytest.mark.timeout(120)
def test_cesapi_initialises_sets_units_and_measures_the_truth():
    cell = make_cell(seed=9)
    with EmsconServer(cell) as srv:
        conn = cesapi_connection.Connection()
        conn.connect(host=srv.host, port=srv.port)
        try:
            cmd = cesapi_command.CommandSync(conn)
            status = cmd.GetSystemStatus()
            assert status.trackerProcessorStatus == P.ES_TPS_CompensationSet
            cmd.Initialize()
            assert cell.tracker_initialised
            assert cmd.GetSystemStatus().trackerProcessorStatus == P.ES_TPS_Initialized

            cmd.SetUnits(_units(P.ES_LU_Millimeter))
            params = P.StationaryModeDataT()
            params.lMeasTime = 100
            cmd.SetStationaryModeParams(params)
            truth = cell.true_point()
            sigma = cell.tracker_sigma(truth)
            mm = cmd.StartMeasurement()
            assert isinstance(mm, P.SingleMeasResult2T)
            xyz_mm = np.array([mm.dVal1, mm.dVal2, mm.dVal3])
            assert np.all(np.abs(xyz_mm - truth) < 6 * sigma)
            assert mm.dStd1 == pytest.approx(sigma, rel=0.5)
            assert mm.dTemperature == pytest.approx(20.0, abs=0.1)

            cmd.SetUnits(_units(P.ES_LU_Meter))
            m = cmd.StartMeasurement()
            xyz_m = np.array([m.dVal1, m.dVal2, m.dVal3])
            assert np.all(np.abs(xyz_m * 1000.0 - truth) < 6 * sigma)
            assert m.dStd1 == pytest.approx(sigma / 1000.0, rel=0.5)
            got = cmd.GetUnits()
            assert got.unitsSettings.lenUnitType == P.ES_LU_Meter
            first = cmd.GetReflectors()
            assert first.iTotalReflectors == 5
        finally:
            conn.disconnect()
    assert srv.units[0] == P.ES_LU_Meter  # the server keeps what CESAPI set
    print(f"\nCESAPI: mm {xyz_mm} / m {xyz_m}, truth {truth} mm")
