"""The simulated line-protocol robot controller (docs/line-robot-protocol.md).

:class:`RobotLineServer` serves a :class:`~sim_drivers.cell.SimCell`'s robot over
loopback TCP (``socket://host:port``) or a pty (``serial:///dev/pts/N``).
"""

from __future__ import annotations

import numpy as np

from sim_drivers.cell import CellRefused, SimCell
from sim_drivers.faults import FaultInjector
from sim_drivers.line_server import LineServer

#: ERR name → code on the wire
ROBOT_ERROR_CODES = {
    "BAD_COMMAND": 10,
    "BAD_ARGUMENT": 11,
    "LIMIT": 20,
    "UNREACHABLE": 21,
    "PROTECTIVE_STOP": 30,
    "EMERGENCY_STOP": 31,
    "FAULT": 32,
    "BUSY": 40,
}

#: what the simulated controller says in HELLO (its serial number is the cell's,
#: :meth:`SimCell.serial`; ``sim=1`` declares it a simulator)
MODEL, FIRMWARE = "SIMBOT-1", "1.0.0"


def err(name: str, detail: str = "") -> str:
    """``ERR <code> <NAME> [detail]``."""
    return f"ERR {ROBOT_ERROR_CODES.get(name, 99)} {name}" + (f" {detail}" if detail else "")


class RobotSession:
    """Protocol state of one robot connection (stateless apart from the cell)."""

    def __init__(self, cell: SimCell, faults: FaultInjector) -> None:
        self.cell = cell
        self.faults = faults

    def _numbers(self, words: list[str], n: int) -> np.ndarray | None:
        if len(words) != n:
            return None
        try:
            v = np.array([float(w) for w in words])
        except ValueError:
            return None
        return v if np.all(np.isfinite(v)) else None

    def handle(self, line: str) -> list[str]:
        words = line.split()
        cmd, args = words[0].upper(), words[1:]
        c = self.cell
        n = c.n_joints
        try:
            if cmd == "HELLO" and not args:
                return [f"OK HELLO {MODEL} {c.serial('robot')} {FIRMWARE} joints={n} sim=1 "
                        f"kinematics={c.kinematics or 'unknown'}"]
            if cmd == "POS?" and not args:
                q = np.rad2deg(c.robot_state().q)
                return ["OK POS " + " ".join(f"{v:.6f}" for v in q)]
            if cmd == "TCP?" and not args:
                return ["OK TCP " + " ".join(f"{v:.4f}" for v in c.robot_state().tcp)]
            if cmd == "TEMPS?" and not args:
                temps = c.joint_temperatures()
                if temps is None:  # as a controller without temperature readings answers
                    return [err("BAD_COMMAND", "no joint temperatures on this controller")]
                return ["OK TEMPS " + " ".join(f"{v:.2f}" for v in temps)]
            if cmd == "STATUS?" and not args:
                s = c.robot_state()
                return [
                    f"OK STATUS moving={int(s.moving)} inpos={int(s.in_position)} "
                    f"steady={int(s.steady)} fault={int(s.fault)} pstop={int(s.protective_stop)} "
                    f"estop={int(s.emergency_stop)} err={s.error_code} t={s.timestamp:.3f}"
                ]
            if cmd == "MOVEJ":
                v = self._numbers(args, n + 1)
                if v is None:
                    need = f"MOVEJ needs {n} joints (deg) and a speed (deg/s)"
                    return [err("BAD_ARGUMENT", need)]
                if self.faults.fires("pstop"):
                    c.trigger_protective_stop()
                c.command_move_joints(np.deg2rad(v[:n]), float(np.deg2rad(v[n])))
                return ["OK MOVEJ"]
            if cmd == "MOVEL":
                v = self._numbers(args, 4)
                if v is None:
                    return [err("BAD_ARGUMENT", "MOVEL needs x y z (mm) and a speed (mm/s)")]
                if self.faults.fires("pstop"):
                    c.trigger_protective_stop()
                c.command_move_linear(v[:3], float(v[3]))
                return ["OK MOVEL"]
            if cmd == "STOP" and not args:
                c.command_stop()
                return ["OK STOP"]
            if cmd == "RESET" and not args:
                c.clear_protective_stop()
                return ["OK RESET"]
        except CellRefused as e:
            return [err(e.name, e.detail)]
        return [err("BAD_COMMAND", f"unknown command {line[:40]!r}")]


class RobotLineServer(LineServer):
    """Line-protocol robot server for ``cell`` (TCP or pty).

    Parameters
    ----------
    cell : SimCell
    faults : FaultInjector or None
        Defaults to the cell's injector (or none).
    transport : {"tcp", "pty"}
    host, port : str, int
        TCP address (port 0: a free one).
    """

    def __init__(
        self,
        cell: SimCell,
        *,
        faults: FaultInjector | None = None,
        transport: str = "tcp",
        host: str = "127.0.0.1",
        port: int = 0,
    ) -> None:
        faults = faults if faults is not None else (cell.faults or FaultInjector())
        self.cell = cell
        super().__init__(
            lambda: RobotSession(cell, faults),
            faults=faults,
            host=host,
            port=port,
            transport=transport,
            name="sim-robot",
        )

    @property
    def url(self) -> str:
        """The driver URL: ``socket://host:port`` or ``serial:///dev/pts/N``."""
        if self.transport == "tcp":
            return f"socket://{self.host}:{self.port}"
        return f"serial://{self.pty_path}"
