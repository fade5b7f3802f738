"""``sim://`` is the application's scheme: registered by cellcal, loaded when first opened;
the real cell's URLs never import the simulator."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

from cellcal.url_schemes import register_schemes
from drivers import urls
from sim_drivers import inprocess
from sim_drivers.modbus_server import ModbusRobotServer
from sim_drivers.tracker_server import TrackerServer
from tests.sim_drivers.helpers import make_cell

ROOT = Path(__file__).resolve().parents[2]
TOY = str(ROOT / "tests" / "daq" / "data" / "toyarm.yaml")

#: a fresh interpreter: the application's schemes registered, the real cell's drivers
#: opened and used, then a sim:// robot; the simulator's modules loaded after each step
PROBE = """
import json, sys
from cellcal.url_schemes import register_schemes
from drivers.urls import open_robot, open_tracker

def loaded():
    return sorted(m for m in sys.modules if m.split(".")[0] == "sim_drivers")

register_schemes()
seen = {"registered": loaded()}
with open_robot(sys.argv[1]) as robot, open_tracker(sys.argv[2]) as tracker:
    robot.connect(5.0)
    tracker.connect(5.0)
    robot.read_joints()
    tracker.status()
seen["real cell"] = loaded()
open_robot(sys.argv[3])
seen["sim"] = loaded()
print(json.dumps(seen))
"""


def test_the_real_cell_never_imports_the_simulator():
    with ModbusRobotServer(make_cell(seed=3)) as robot, TrackerServer(make_cell(seed=3)) as trk:
        out = subprocess.run(
            [sys.executable, "-c", PROBE, robot.url, trk.url, f"sim://robot?model={TOY}"],
            cwd=ROOT, capture_output=True, text=True, timeout=60,
            env={**os.environ, "PYTHONPATH": str(ROOT)})
    assert out.returncode == 0, out.stderr
    seen = json.loads(out.stdout)
    assert seen["registered"] == [] and seen["real cell"] == []
    assert "sim_drivers.inprocess" in seen["sim"]


def test_sim_opens_once_registered():
    url = f"sim://robot?model={TOY}&seed=2&name=schemes"
    urls.unregister_scheme("sim")
    try:
        with pytest.raises(ValueError, match="bad robot URL .*: unknown scheme 'sim'"):
            urls.open_robot(url)
    finally:
        register_schemes()
    try:
        with urls.open_robot(url) as robot:
            robot.connect(1.0)
            assert robot.identify(1.0).simulator
    finally:
        inprocess.reset_cells()
