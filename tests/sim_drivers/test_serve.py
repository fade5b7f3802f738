"""``cellcal sim serve`` as a real subprocess, and SimStack in process."""

from __future__ import annotations

import contextlib
import signal
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest

from drivers.urls import open_robot, open_tracker
from sim_drivers.serve import PortInUse, ServeConfig, SimStack, ports_from_base
from tests.daq.capture_helpers import read_lines

ROOT = Path(__file__).resolve().parents[2]


@contextlib.contextmanager
def _serving(*args: str) -> Iterator[subprocess.Popen]:
    """``cellcal sim serve ARGS`` as a subprocess, killed if a test leaves it running."""
    proc = subprocess.Popen([sys.executable, "-m", "cellcal", "sim", "serve", *args], cwd=ROOT,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    try:
        yield proc
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
        proc.stdout.close()
        proc.stderr.close()


def test_cellcal_sim_serve_subprocess():
    with _serving("--model", "toy", "--seed", "3", "--faults", "beam=0", "--port-base", "0",
                  "--no-rtde") as proc:  # 30004 may be free or not
        urls = read_lines(proc, 6, timeout=20.0)
        assert urls[5] == f"export R='{urls[0]}' T='{urls[2]}'"  # ready to paste
        assert urls[0].startswith("modbus+tcp://127.0.0.1:")
        assert urls[1].startswith("socket://127.0.0.1:")
        assert urls[2].startswith("tracker+tcp://127.0.0.1:")
        assert urls[3].startswith("tracker+serial:///dev/")
        assert urls[4].startswith("emscon://127.0.0.1:")
        target = np.array([0.2, 0.3, -0.1])
        for robot_url in urls[:2]:
            with open_robot(robot_url) as rob:
                rob.connect(2.0)
                rob.move_joints(target, speed=0.5, timeout=2.0)
                assert np.allclose(rob.read_joints().q, target, atol=1e-4)
        points = []
        for tracker_url in urls[2:5]:
            with open_tracker(tracker_url) as trk:
                trk.connect(2.0)
                points.append(trk.measure(0.1, timeout=2.0).xyz)
        # same cell, same target, whatever the protocol
        assert np.linalg.norm(points[0] - points[1]) < 0.1
        assert np.linalg.norm(points[0] - points[2]) < 0.1
        proc.send_signal(signal.SIGTERM)
        assert proc.wait(timeout=10) == 0
        assert b"stopped" in proc.stderr.read()


def test_bad_fault_spec_is_a_usage_error():
    out = subprocess.run(
        [sys.executable, "-m", "cellcal", "sim", "serve", "--faults", "laser=1"],
        cwd=ROOT,
        capture_output=True,
        timeout=30,
    )
    assert out.returncode == 2
    assert b"unknown fault 'laser'" in out.stderr


def test_stack_refuses_a_port_in_use_or_falls_back_when_allowed():
    free = {"modbus": 0, "line_robot": 0, "tracker": 0, "emscon": 0}
    with SimStack(ServeConfig(pty=False, ports=free)) as a:
        taken = {"modbus": a.servers[0].port, "line_robot": 0, "tracker": 0, "emscon": 0}
        with pytest.raises(PortInUse, match=f"port {taken['modbus']} .Modbus robot.*--port-base"):
            SimStack(ServeConfig(pty=False, ports=taken)).start()


def test_stack_falls_back_to_free_ports_with_any_port():
    free = {"modbus": 0, "line_robot": 0, "tracker": 0, "emscon": 0}
    with SimStack(ServeConfig(pty=False, ports=free)) as a:
        taken = {
            "modbus": a.servers[0].port,
            "line_robot": a.servers[1].port,
            "tracker": a.servers[2].port,
            "emscon": a.servers[3].port,
        }
        with SimStack(ServeConfig(pty=False, ports=taken, any_port=True)) as b:
            assert len(b.urls) == 4
            assert [s.port for s in b.servers] != list(taken.values())
            with open_tracker(b.urls[2]) as trk:
                trk.connect(1.0)
                trk.measure(0.05, 1.0)


def test_stack_rejects_bad_faults():
    with pytest.raises(ValueError, match="unknown fault"):
        SimStack(ServeConfig(faults="nope=1"))


def test_sim_serve_ur10e_with_rtde_read_by_the_real_ur_client():
    """The default truth (a UR10e with hidden errors) is also served over RTDE: the real
    ur-rtde receive client sees the joints the Modbus robot was moved to."""
    with _serving("--seed", "1", "--no-pty", "--port-base", "0") as proc:
        urls = read_lines(proc, 4, timeout=20.0)
        while not urls[-1].startswith("export "):  # the RTDE line, if port 30004 was free
            urls += read_lines(proc, 1, timeout=5.0)
        ur = [u for u in urls if u.startswith("ur://")]
        if not ur:
            pytest.skip("port 30004 is taken on this machine: no RTDE server")
        assert ur[0] == "ur://127.0.0.1?read_only=1"
        target = np.radians([10.0, -70.0, 95.0, -110.0, -90.0, 5.0])
        with open_robot(urls[0]) as rob:
            rob.connect(2.0)
            rob.move_joints(target, speed=1.0, timeout=5.0)
        with open_robot(ur[0]) as urrob:
            urrob.connect(5.0)
            assert np.allclose(urrob.read_joints(timeout=2.0).q, target, atol=1e-3)
        proc.send_signal(signal.SIGTERM)
        assert proc.wait(timeout=15) == 0


def test_sim_serve_port_in_use_is_an_error_with_a_hint():
    free = {"modbus": 0, "line_robot": 0, "tracker": 0, "emscon": 0}
    with SimStack(ServeConfig(pty=False, ports=free)) as a:
        port = a.servers[0].port
        out = subprocess.run([sys.executable, "-m", "cellcal", "sim", "serve", "--no-pty",
                              "--no-rtde", "--port-base", "0", "--modbus-port", str(port)],
                             cwd=ROOT, capture_output=True, text=True, timeout=60)
    assert out.returncode == 2 and out.stdout == ""
    assert f"port {port} (Modbus robot)" in out.stderr and "--any-port" in out.stderr


def test_port_base_gives_four_consecutive_ports():
    assert ports_from_base(20000) == {"modbus": 20000, "line_robot": 20001, "tracker": 20002,
                                      "emscon": 20003}


def test_sim_serve_abb_serves_the_robot_over_rws_too():
    """``--abb``: the same robot as an ABB IRC5, its URL after the emScon tracker's (port
    base + 4); moved over RWS, seen by the Modbus driver."""
    with _serving("--model", "toy", "--abb", "--no-pty", "--no-rtde", "--port-base",
                  "0") as proc:
        urls = read_lines(proc, 6, timeout=20.0)
        assert urls[3].startswith("emscon://") and urls[4].startswith("abb://127.0.0.1:")
        assert urls[4].endswith("?joints=3")
        assert urls[5] == f"export R='{urls[4]}' T='{urls[2]}'"  # the ABB, ready to paste
        target = np.array([0.3, -0.2, 0.4])
        with open_robot(urls[4]) as abb:
            abb.connect(5.0)
            abb.move_joints(target, speed=0.5, timeout=5.0)
        with open_robot(urls[0]) as rob:
            rob.connect(2.0)
            assert np.allclose(rob.read_joints().q, target, atol=1e-4)
        proc.send_signal(signal.SIGTERM)
        assert proc.wait(timeout=10) == 0
