"""An RTDE (protocol v2) server for the simulated cell, so the real ur-rtde receive client works.

:class:`RtdeSimServer` runs the wire protocol in a child process
(:mod:`sim_drivers.rtde_child`; spawned, because the ur-rtde constructors hold
the GIL until the first data package arrives) and feeds it the cell's state
through shared memory: a small pump thread in this process polls
``cell.robot_state()`` and writes it, converted to controller units (m, rad),
into a block the child reads under a sequence lock. ::

    with RtdeSimServer(cell, host="127.0.0.7") as server:
        rx = rtde_receive.RTDEReceiveInterface(server.host)
        rx.getActualQ()

The port is 30004 (ur-rtde cannot be told otherwise); pick a loopback address
per test (Linux accepts any ``127.x.y.z``). When 30004 is taken on ``host`` the
server tries ``fallback_hosts`` and raises :class:`PortUnavailable` if every
one is taken.

Joint vectors on the wire always have 6 entries (as on a UR); a cell with
fewer joints is padded with zeros.
"""

from __future__ import annotations

import contextlib
import os
import select
import signal
import subprocess
import sys
import threading
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from sim_drivers import rtde_child as child
from sim_drivers.rtde_wire import RTDE_PORT

# RTDE guide: robot_mode, safety_mode, runtime_state values and status bits
ROBOT_MODE_POWER_OFF, ROBOT_MODE_RUNNING = 3, 7
SAFETY_NORMAL, SAFETY_PROTECTIVE_STOP, SAFETY_ROBOT_EMERGENCY_STOP, SAFETY_FAULT = 1, 3, 7, 9
RUNTIME_STOPPED, RUNTIME_PLAYING, RUNTIME_PAUSED = 1, 2, 4
SAFETY_BIT_NORMAL, SAFETY_BIT_PROTECTIVE = 1 << 0, 1 << 2
SAFETY_BIT_ROBOT_ESTOP, SAFETY_BIT_ESTOP = 1 << 6, 1 << 7
SAFETY_BIT_FAULT, SAFETY_BIT_STOPPED_BY_SAFETY = 1 << 9, 1 << 10
ROBOT_BIT_POWER_ON, ROBOT_BIT_PROGRAM_RUNNING = 1 << 0, 1 << 1

N_WIRE_JOINTS = 6
#: the joint temperature (°C) on the wire of a joint the cell does not report (a cell of
#: fewer joints, or whose controller reports none: a UR always streams six)
IDLE_JOINT_TEMP_C = 30.0


class PortUnavailable(OSError):
    """Port 30004 is taken on every loopback address the server tried."""


def controller_fields(state, program_running: bool = True) -> dict[str, object]:
    """Convert a SimCell ``RobotState`` to the RTDE variables the controller would report.

    Parameters
    ----------
    state : RobotState-like
        ``q`` and ``qd`` (rad, rad/s, n joints), ``tcp`` (mm; 3 values, or 6 with a
        rotation vector in rad), ``protective_stop``, ``emergency_stop``, ``fault``;
        ``joint_temp`` (°C, n joints) as the cell's controller reports them (the thermal
        model's, else the air's; a cell that reports none: every joint
        :data:`IDLE_JOINT_TEMP_C`).
    program_running : bool
        Whether the (simulated) control script runs; cleared by any stop.

    Returns
    -------
    dict
        Values in controller units: joints padded to 6 (rad, rad/s), poses in m + rad.
    """
    q = _pad6(state.q)
    qd = _pad6(getattr(state, "qd", None))
    tcp = np.zeros(6)
    t = np.asarray(state.tcp, float).ravel()
    tcp[:3] = t[:3] / 1000.0
    if t.size >= 6:
        tcp[3:6] = t[3:6]
    pstop, estop = bool(state.protective_stop), bool(state.emergency_stop)
    fault = bool(getattr(state, "fault", False))
    bits, mode, runtime = SAFETY_BIT_NORMAL, SAFETY_NORMAL, RUNTIME_PLAYING
    robot_mode = ROBOT_MODE_RUNNING
    if fault:
        bits, mode, runtime = SAFETY_BIT_FAULT | SAFETY_BIT_STOPPED_BY_SAFETY, SAFETY_FAULT, 1
    if pstop:
        bits, mode, runtime = SAFETY_BIT_PROTECTIVE | SAFETY_BIT_STOPPED_BY_SAFETY, 3, 4
    if estop:
        bits = SAFETY_BIT_ROBOT_ESTOP | SAFETY_BIT_ESTOP | SAFETY_BIT_STOPPED_BY_SAFETY
        mode, runtime, robot_mode = SAFETY_ROBOT_EMERGENCY_STOP, RUNTIME_STOPPED, 3
    if not program_running and runtime == RUNTIME_PLAYING:
        runtime = RUNTIME_STOPPED
    status = ROBOT_BIT_POWER_ON if robot_mode == ROBOT_MODE_RUNNING else 0
    if runtime == RUNTIME_PLAYING:
        status |= ROBOT_BIT_PROGRAM_RUNNING
    return {
        "robot_mode": robot_mode,
        "safety_mode": mode,
        "safety_status_bits": bits,
        "runtime_state": runtime,
        "robot_status_bits": status,
        "speed_scaling": 1.0,
        "actual_q": q,
        "actual_qd": qd,
        "target_q": q,
        "actual_TCP_pose": tcp,
        "target_TCP_pose": tcp,
        "actual_TCP_speed": np.zeros(6),
        "joint_temperatures": _joint_temperatures(getattr(state, "joint_temp", None)),
    }


def _joint_temperatures(temps) -> np.ndarray:
    """The six joint temperatures on the wire (°C): the cell's, padded with the idle value."""
    out = np.full(N_WIRE_JOINTS, IDLE_JOINT_TEMP_C)
    if temps is not None:
        a = np.asarray(temps, float).ravel()[:N_WIRE_JOINTS]
        out[: a.size] = a
    return out


def _pad6(v) -> np.ndarray:
    out = np.zeros(N_WIRE_JOINTS)
    if v is not None:
        a = np.asarray(v, float).ravel()[:N_WIRE_JOINTS]
        out[: a.size] = a
    return out


def _default_fields() -> dict[str, object]:
    class _Idle:
        q = np.zeros(N_WIRE_JOINTS)
        qd = np.zeros(N_WIRE_JOINTS)
        tcp = np.zeros(3)
        protective_stop = emergency_stop = fault = False

    return controller_fields(_Idle())


class RtdeSimServer:
    """RTDE server process streaming a simulated cell's robot state.

    Parameters
    ----------
    cell : SimCell-like, optional
        Anything with ``robot_state()``; polled by the pump thread. Without a
        cell, state comes only from :meth:`publish`.
    host : str
        Loopback address to bind (port 30004).
    fallback_hosts : sequence of str, optional
        Addresses tried in turn when ``host`` is taken; default ``127.0.0.2`` …
        ``127.0.0.40``. Pass ``()`` to try ``host`` only.
    max_frequency : float
        Highest streaming frequency a client may request, Hz (500 on e-Series).
    pump_hz : float
        How often the pump thread copies the cell's state into shared memory, Hz.
    controller_version : tuple of 4 int
        Reported by GET_URCONTROL_VERSION; 5.x makes ur-rtde ask for 500 Hz.
    lock : threading.Lock-like, optional
        Held while the pump reads the cell; share it with whoever commands the cell.
    start_timeout : float
        Seconds to wait for the child process to bind.
    """

    def __init__(
        self,
        cell=None,
        host: str = "127.0.0.1",
        *,
        port: int = RTDE_PORT,
        fallback_hosts: Sequence[str] | None = None,
        max_frequency: float = 500.0,
        pump_hz: float = 250.0,
        controller_version: tuple[int, int, int, int] = (5, 11, 1, 0),
        lock=None,
        start_timeout: float = 10.0,
    ) -> None:
        self.cell = cell
        self.requested_host = host
        self.port = port
        if fallback_hosts is None:
            fallback_hosts = [f"127.0.0.{i}" for i in range(2, 41)]
        self.hosts = [host] + [h for h in fallback_hosts if h != host]
        self.max_frequency = float(max_frequency)
        self.pump_hz = float(pump_hz)
        self.controller_version = tuple(int(v) for v in controller_version)
        self.lock = lock if lock is not None else threading.RLock()
        self.start_timeout = float(start_timeout)
        self.host: str | None = None
        self.program_running = True
        self.pump_error: BaseException | None = None
        self._block: child.SharedBlock | None = None  # exists while running
        self._fields: dict[str, object] = {}
        self._flags = {child.FREEZE: 0.0, child.SILENT: 0.0}
        self._write_lock = threading.Lock()
        self._proc: subprocess.Popen | None = None
        self._pump: threading.Thread | None = None
        self._pump_stop = threading.Event()
        self._write(_default_fields())

    # -- lifecycle -------------------------------------------------------------------------

    def start(self) -> RtdeSimServer:
        """Start the server process and (with a cell) the pump; return once bound.

        Raises
        ------
        PortUnavailable
            Port 30004 is taken on every address tried.
        RuntimeError
            The process did not come up within ``start_timeout``.
        """
        if self._proc is not None:
            return self
        if self.cell is not None:
            self.publish()
        with self._write_lock:
            self._block = child.SharedBlock()
            self._block.write_state(self._fields)
            for i, v in self._flags.items():
                self._block.set_ctl(i, v)
        fd = self._block.fileno()
        cmd = [sys.executable, "-m", "sim_drivers.rtde_child", "--fd", str(fd),
               "--hosts", ",".join(self.hosts), "--port", str(self.port),
               "--max-frequency", str(self.max_frequency),
               "--version", ".".join(map(str, self.controller_version))]
        root = str(Path(__file__).resolve().parent.parent)
        env = dict(os.environ)
        env["PYTHONPATH"] = os.pathsep.join(p for p in (root, env.get("PYTHONPATH")) if p)
        proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, pass_fds=(fd,), env=env)
        try:
            line = self._read_report(proc)
        except BaseException:
            proc.kill()
            proc.wait()
            proc.stdout.close()
            self._close_block()
            raise
        proc.stdout.close()
        status, _, detail = line.partition(" ")
        if status != "ok":
            proc.wait(self.start_timeout)
            self._close_block()
            raise PortUnavailable(detail or f"RTDE simulator exited with {proc.returncode}")
        self._proc = proc
        self.host = detail
        if self.cell is not None and self.pump_hz > 0:
            self._pump_stop.clear()
            self._pump = threading.Thread(target=self._run_pump, name="rtde-sim-pump",
                                          daemon=True)
            self._pump.start()
        return self

    def _read_report(self, proc: subprocess.Popen) -> str:
        ready, _, _ = select.select([proc.stdout], [], [], self.start_timeout)
        if not ready:
            raise RuntimeError(f"RTDE simulator did not start within {self.start_timeout} s")
        line = proc.stdout.readline().decode(errors="replace").strip()
        if not line:
            raise RuntimeError(f"RTDE simulator died on start (exit {proc.wait()})")
        return line

    def stop(self, timeout: float = 3.0) -> None:
        """Stop the pump and the server process; close every client connection."""
        self._pump_stop.set()
        if self._pump is not None:
            self._pump.join(timeout)
            self._pump = None
        proc, self._proc = self._proc, None
        if proc is None:
            return
        self._block.set_ctl(child.STOP, 1.0)
        try:
            proc.wait(timeout)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait(timeout)
        self._close_block()

    def _close_block(self) -> None:
        with self._write_lock:
            block, self._block = self._block, None
            if block is not None:
                block.close()

    def __enter__(self) -> RtdeSimServer:
        return self.start()

    def __exit__(self, *exc) -> None:
        self.stop()

    @property
    def url(self) -> str:
        """``ur://<host>`` of the running server."""
        return f"ur://{self.host}"

    @property
    def running(self) -> bool:
        return self._proc is not None and self._proc.poll() is None

    # -- state -----------------------------------------------------------------------------

    def publish(self, state=None) -> None:
        """Copy ``state`` (or ``cell.robot_state()``) into the block the server streams."""
        if state is None:
            if self.cell is None:
                return
            with self.lock:
                state = self.cell.robot_state()
        self._write(controller_fields(state, self.program_running))

    def _write(self, fields: dict[str, object]) -> None:
        with self._write_lock:
            self._fields.update(fields)
            if self._block is not None:
                self._block.write_state(fields)

    def _set_flag(self, i: int, on: bool) -> None:
        with self._write_lock:
            self._flags[i] = 1.0 if on else 0.0
            if self._block is not None:
                self._block.set_ctl(i, self._flags[i])

    def _ctl(self, i: int) -> float:
        with self._write_lock:
            return self._block.ctl(i) if self._block is not None else 0.0

    def _run_pump(self) -> None:
        period = 1.0 / self.pump_hz
        while not self._pump_stop.wait(period):
            try:
                self.publish()
            except Exception as e:  # keep streaming the last good state
                self.pump_error = e

    # -- faults and diagnostics ------------------------------------------------------------

    def freeze(self, on: bool = True) -> None:
        """Keep streaming, but with a frozen timestamp and frozen values (a hung controller)."""
        self._set_flag(child.FREEZE, on)

    def silence(self, on: bool = True) -> None:
        """Stop sending data packages while keeping connections open (a dead link)."""
        self._set_flag(child.SILENT, on)

    def kill(self) -> None:
        """Kill the server process abruptly (SIGKILL), as if the controller vanished."""
        if self._proc is not None:
            with contextlib.suppress(ProcessLookupError):
                os.kill(self._proc.pid, signal.SIGKILL)
            self._proc.wait(5.0)

    @property
    def clients(self) -> int:
        """Number of connected clients."""
        return int(self._ctl(child.CLIENTS))

    @property
    def packages_sent(self) -> int:
        """Data-package rounds sent so far."""
        return int(self._ctl(child.PACKAGES))

    @property
    def requested_frequency(self) -> float:
        """The frequency (Hz) the last client asked for in SETUP_OUTPUTS."""
        return float(self._ctl(child.FREQUENCY))
