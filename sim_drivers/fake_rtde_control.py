"""``FakeRTDEControl``: what cellcal uses of ur-rtde's ``RTDEControlInterface``, on a SimCell.

Same method names, signatures and units as ur-rtde 1.6.5 (metres, radians,
``asynchronous`` flag) and the same quirks:

- ``moveJ``/``moveL``/``stopJ`` return ``False`` (not an exception) when the
  robot is in a protective or emergency stop or a fault, and when the control
  script is not running;
- a protective stop, an emergency stop or a refused target (outside the
  limits, unreachable) kills the control script: ``isProgramRunning()`` stays
  ``False`` and every command returns ``False`` until ``reuploadScript()``;
- after ``disconnect()`` the commands raise ``RuntimeError`` (as the C++
  layer does on a closed socket) until ``reconnect()``.

The cell's fault injector applies as at the robot servers: ``pstop`` makes a move
command trigger a protective stop (:mod:`sim_drivers.faults`).

Joint vectors have 6 entries as on a UR; a cell with fewer joints uses the
first ``cell.n_joints`` and ignores the rest. With ``server`` (an
:class:`~sim_drivers.rtde_server.RtdeSimServer`) every command republishes
the cell's state at once and keeps the server's ``program_running`` (runtime
state, robot status bits) in step with the script.
"""

from __future__ import annotations

import threading

import numpy as np

from sim_drivers.cell import CellRefused


class FakeRTDEControl:
    """An ``RTDEControlInterface`` stand-in backed by a simulated cell.

    Parameters
    ----------
    cell : SimCell-like
        ``command_move_joints(q, speed)`` (rad, rad/s), ``command_move_linear(xyz, speed)``
        (mm, mm/s), ``command_stop()``, ``robot_state()``.
    hostname : str
        Accepted for signature compatibility (``RTDEControlInterface(hostname)``).
    server : RtdeSimServer, optional
        Told about the script state and republished after each command.
    lock : threading.Lock-like, optional
        Held around cell calls; defaults to the server's lock (or a new one).
    """

    def __init__(self, cell, hostname: str = "sim", server=None, lock=None) -> None:
        self.cell = cell
        self.hostname = hostname
        self.server = server
        self.lock = lock or (server.lock if server is not None else threading.RLock())
        self._connected = True
        self._script_running = True
        self.calls: list[tuple] = []
        self._sync()

    # -- connection --------------------------------------------------------------------

    def isConnected(self) -> bool:  # noqa: N802 - ur-rtde's name
        return self._connected

    def disconnect(self) -> None:
        self._connected = False

    def reconnect(self) -> bool:
        self._connected = True
        return True

    def _need_link(self, name: str, *args) -> None:
        self.calls.append((name, *args))
        if not self._connected:
            raise RuntimeError(f"RTDEControlInterface: {name}: not connected to {self.hostname}")

    # -- script ------------------------------------------------------------------------

    def isProgramRunning(self) -> bool:  # noqa: N802
        self._need_link("isProgramRunning")
        return self._script_running

    def reuploadScript(self) -> bool:  # noqa: N802
        """Restart the control script (refused, i.e. still stopped, while a stop is active)."""
        self._need_link("reuploadScript")
        st = self._state()
        self._script_running = not (st.protective_stop or st.emergency_stop or st.fault)
        self._sync()
        return True

    def stopScript(self) -> None:  # noqa: N802
        self._need_link("stopScript")
        self._script_running = False
        self._sync()

    def getRobotStatus(self) -> int:  # noqa: N802
        """Bit 0 power on, bit 1 program running (RTDE guide, robot_status_bits)."""
        self._need_link("getRobotStatus")
        st = self._state()
        power = 0 if st.emergency_stop else 1
        return power | (2 if self._script_running else 0)

    def isSteady(self) -> bool:  # noqa: N802
        self._need_link("isSteady")
        st = self._state()
        return bool(getattr(st, "steady", not st.moving)) and not st.moving

    # -- motion ------------------------------------------------------------------------

    def moveJ(  # noqa: N802
        self, q, speed: float = 1.05, acceleration: float = 1.4, asynchronous: bool = False
    ) -> bool:
        """Joint move to ``q`` (rad, 6 values); ``speed`` rad/s. False when refused."""
        self._need_link("moveJ", list(q), speed, acceleration, asynchronous)
        n = int(self.cell.n_joints)
        q = np.asarray(q, float).ravel()
        return self._command(lambda: self.cell.command_move_joints(q[:n], float(speed)))

    def moveL(  # noqa: N802
        self, pose, speed: float = 0.25, acceleration: float = 1.2, asynchronous: bool = False
    ) -> bool:
        """Linear move to ``pose`` ([x, y, z] m + rotation vector rad); ``speed`` m/s."""
        self._need_link("moveL", list(pose), speed, acceleration, asynchronous)
        pose = np.asarray(pose, float).ravel()
        if pose.size != 6:
            return self._refuse()
        xyz_mm = pose[:3] * 1000.0
        return self._command(lambda: self.cell.command_move_linear(xyz_mm, float(speed) * 1000.0))

    def stopJ(self, a: float = 2.0, asynchronous: bool = False) -> None:  # noqa: N802
        self._need_link("stopJ")
        with self.lock:
            self.cell.command_stop()
        self._sync()

    def stopL(self, a: float = 10.0, asynchronous: bool = False) -> None:  # noqa: N802
        self._need_link("stopL")
        with self.lock:
            self.cell.command_stop()
        self._sync()

    # -- internals ---------------------------------------------------------------------

    def _state(self):
        with self.lock:
            return self.cell.robot_state()

    def _command(self, fn) -> bool:
        if not self._script_running:
            return False  # ur-rtde: "RTDE control script is not running!"
        faults = getattr(self.cell, "faults", None)
        if faults is not None and faults.fires("pstop"):  # the move meets an obstacle
            with self.lock:
                self.cell.trigger_protective_stop()
        st = self._state()
        if st.protective_stop or st.emergency_stop or st.fault:
            return self._refuse()
        try:
            with self.lock:
                fn()
        except CellRefused:  # a stop, or a bad target: the script dies either way
            return self._refuse()
        self._sync()
        return True

    def _refuse(self) -> bool:
        self._script_running = False
        self._sync()
        return False

    def _sync(self) -> None:
        if self.server is not None:
            self.server.program_running = self._script_running
            self.server.publish(self._state())
