"""A simulated ABB IRC5 behind Robot Web Services: its panel, RAPID, mastership, event log,
and the RAPID server module (``drivers/abb/rapid/CellcalServer.mod``) run on the
simulated cell's robot.

:class:`SimIrc5` is the controller's state, driven by the HTTP server
(:mod:`sim_drivers.rws_server`) one request at a time; a refused request raises
:class:`RwsRefused` (an HTTP status, a code, a message). The RAPID task is evaluated when
someone looks (:meth:`SimIrc5.step` at each request), which is exact because the cell's
robot follows its own clock: the module serves a new request number as soon as RAPID
sees it, and acknowledges once the cell says the robot is in position and settled (zone
fine).

State faults (:mod:`sim_drivers.faults`, armed or scheduled; they fire when the module
starts a move, except ``mastership``, which fires on a RAPID data write):

==========  ===================================================================
pstop       the robot meets the safety circuit: a guard stop, RAPID stops
motoroff    the motors go off mid-move (``ctrlstate`` motoroff), RAPID stops
rapid       a RAPID error mid-move: the task stops, the event log says why
mastership  another client (the FlexPendant) takes the mastership: the write is
            refused (403) until :meth:`SimIrc5.release_mastership` by the operator
==========  ===================================================================

The simulator's own status codes (not ABB's return codes): :data:`CODES`.
"""

from __future__ import annotations

import threading
import time

import numpy as np

from drivers.abb import codec as C
from sim_drivers.cell import CellRefused, SimCell
from sim_drivers.faults import FaultInjector

#: the simulator's status codes on error answers (``_embedded.status.code``)
CODES = {"bad_value": -1001, "not_found": -1002, "mastership": -1003, "state": -1004,
         "bad_request": -1005}

#: who takes the mastership when the ``mastership`` fault fires
OTHER_CLIENT = "FlexPendant"

#: the module's persistent variables: RAPID type and start value (as in the .mod file)
MODULE_VARS = {
    C.VAR_SEQ: ("num", "0"), C.VAR_ACK: ("num", "0"), C.VAR_BUSY: ("num", "0"),
    C.VAR_KIND: ("num", "0"),
    C.VAR_JOINTS: ("jointtarget", C.jointtarget_text([0.0] * 6)),
    C.VAR_TIME: ("num", "1"), C.VAR_XYZ: ("pos", "[0,0,0]"),
    C.VAR_SPEED: ("speeddata", "[100,500,5000,1000]"), C.VAR_ZONE: ("zonedata", C.ZONE_FINE),
    C.VAR_TOOL: ("string", '"tool0"'), C.VAR_ERR: ("num", "0"), C.VAR_MSG: ("string", '""'),
}
_SIZES = {"pos": 3, "speeddata": 4, "zonedata": 7, "jointtarget": 12}


class RwsRefused(Exception):  # noqa: N818 - a refusal on the wire
    """A request the simulated controller refuses: HTTP ``status``, ``code``, ``msg``."""

    def __init__(self, status: int, code: str, msg: str) -> None:
        self.status, self.code, self.msg = status, CODES[code], msg
        super().__init__(f"{status} {msg}")


def _f32(x: float) -> float:
    """RAPID's num is a 32-bit float."""
    return float(np.float32(x))


def normalise(rapid_type: str, text: str) -> str:
    """``text`` as the controller stores a value of ``rapid_type`` (RwsRefused 400 when it
    is not one)."""
    try:
        if rapid_type == "num":
            return C.rapid_num(_f32(C.parse_num(text)))
        if rapid_type == "string":
            return C.string_text(C.parse_string(text))
        if rapid_type == "zonedata":
            head, _, rest = text.strip().lstrip("[").partition(",")
            if head.strip().upper() not in ("TRUE", "FALSE"):
                raise ValueError("finep must be TRUE or FALSE")
            v = C.parse_numbers("[" + rest)
            if len(v) != 6:
                raise ValueError("a zonedata has 7 components")
            return f"[{head.strip().upper()},{C.rapid_array(v)[1:]}"
        v = C.parse_numbers(text)
        if len(v) != _SIZES[rapid_type]:
            raise ValueError(f"a {rapid_type} has {_SIZES[rapid_type]} numbers")
        if rapid_type == "jointtarget":
            return C.jointtarget_text([_f32(x) for x in v[:6]], v[6:])
        return C.rapid_array(_f32(x) for x in v)
    except ValueError as e:
        raise RwsRefused(400, "bad_value", f"bad {rapid_type} value {text[:60]!r}: {e}") from e


class SimIrc5:
    """The simulated controller of ``cell``'s robot (one per server).

    ``opmode`` (``AUTO``, or ``MANR`` for the pendant's manual mode), ``motors_on``,
    ``running`` (RAPID executing: the module runs from power-up) and ``master`` (the
    session holding the mastership, or :data:`OTHER_CLIENT`) are the operator's to change
    too (:meth:`motors`, :meth:`release_mastership`).
    """

    def __init__(self, cell: SimCell, faults: FaultInjector | None = None) -> None:
        self.cell = cell
        self.faults = faults if faults is not None else (cell.faults or FaultInjector())
        self.lock = threading.RLock()
        self.opmode = "AUTO"
        self.speedratio = 100
        self.motors_on = True
        self.running = True
        self.master: str | None = None
        self.pers = {name: value for name, (_type, value) in MODULE_VARS.items()}
        self.elog: list[dict] = []
        self._elog_seq = 0
        self._serving: int | None = None  # the request number of the move under way
        self._pp_main = False  # the program pointer was reset to main
        self._stopped_by: str | None = None
        self.n_served = 0

    # -- what RWS reads ---------------------------------------------------------------------

    def ctrlstate(self) -> str:
        st = self.cell.robot_state()
        if st.emergency_stop:
            return "emergencystop"
        if st.protective_stop:
            return "guardstop"
        if st.fault:
            return "sysfail"
        return "motoron" if self.motors_on else "motoroff"

    def execstate(self) -> str:
        return "running" if self.running else "stopped"

    def symbol(self, name: str) -> str:
        if name not in self.pers:
            raise RwsRefused(400, "not_found", f"symbol {name} not found in "
                             f"RAPID/{C.TASK}/{C.MODULE}")
        return self.pers[name]

    def num(self, name: str) -> float:
        return C.parse_num(self.pers[name])

    # -- the RAPID task ---------------------------------------------------------------------

    def step(self) -> None:
        """Run the RAPID task up to now: a stop of the safety system stops it; a move in
        position is acknowledged; a new request number is served."""
        st = self.cell.robot_state()
        if self.running and (st.protective_stop or st.emergency_stop or st.fault):
            self._halt("guard stop" if st.protective_stop else "emergency stop",
                       20205, "Auto stop open" if st.protective_stop else "Emergency stop")
        if not self.running:
            return
        if self._serving is not None:
            if not st.moving and st.steady:
                self._finish(C.ERR_NONE, "")
            return
        if self.num(C.VAR_SEQ) != self.num(C.VAR_ACK):
            self._serve(st)

    def _set(self, name: str, value: str) -> None:
        self.pers[name] = normalise(MODULE_VARS[name][0], value)

    def _finish(self, err: int, msg: str) -> None:
        self._set(C.VAR_ERR, C.rapid_num(err))
        self._set(C.VAR_MSG, C.string_text(msg))
        self._set(C.VAR_BUSY, "0")
        self._set(C.VAR_ACK, self.pers[C.VAR_SEQ])
        self._serving = None

    def _serve(self, st) -> None:
        """Serve: check the target (LIMIT, UNREACHABLE: nothing moves), start the move;
        the state faults fire here."""
        seq = int(self.num(C.VAR_SEQ))
        kind = int(self.num(C.VAR_KIND))
        self.n_served += 1
        try:
            if kind == C.KIND_JOINTS:
                rob, _ext = C.parse_jointtarget(self.pers[C.VAR_JOINTS])
                q = np.deg2rad(rob[: self.cell.n_joints])
                seconds = self.num(C.VAR_TIME)
                dq = float(np.max(np.abs(q - st.q)))
                speed = dq / seconds if seconds > 0 and dq > 0 else 1.0
                self.cell.command_move_joints(q, speed)
            elif kind == C.KIND_LINEAR:
                xyz = np.array(C.parse_numbers(self.pers[C.VAR_XYZ]))
                v_tcp = C.parse_numbers(self.pers[C.VAR_SPEED])[0]
                self.cell.command_move_linear(xyz, v_tcp)
            else:
                self._finish(C.ERR_BAD_ARGUMENT,
                             "BAD_ARGUMENT: cc_kind must be 1 (MoveAbsJ) or 2 (MoveL)")
                return
        except CellRefused as e:
            if e.name == "LIMIT":
                self._finish(C.ERR_LIMIT, f"LIMIT: {e.detail}")
            elif e.name == "UNREACHABLE":
                self._finish(C.ERR_UNREACHABLE, f"UNREACHABLE: ERR_ROBLIMIT, {e.detail}")
            else:
                self._finish(C.ERR_BAD_ARGUMENT, f"{e.name}: {e.detail}")
            return
        self._set(C.VAR_BUSY, "1")
        self._serving = seq
        f = self.faults
        if f.fires("pstop"):
            self.cell.trigger_protective_stop()
            self.step()
        elif f.fires("motoroff"):
            self.cell.command_stop()
            self.motors_on = False
            self._halt("motors off", 10011, "Motors OFF state")
        elif f.fires("rapid"):
            self.cell.command_stop()
            self._halt("RAPID error", 41617, f"Execution error in {C.MODULE}: simulated "
                       "RAPID error during the move")

    def _halt(self, why: str, code: int, title: str) -> None:
        """RAPID stops (the program pointer stays in the move) and logs why."""
        if self.running:
            self.cell.command_stop()
        self.running = False
        self._stopped_by = why
        self.log_event(3 if why not in ("motors off",) else 1, code, title)

    def log_event(self, msgtype: int, code: int, title: str, desc: str = "") -> None:
        self._elog_seq += 1
        self.elog.append({"seqnum": self._elog_seq, "msgtype": msgtype, "code": code,
                          "tstamp": time.strftime("%Y-%m-%d T  %H:%M:%S"), "title": title,
                          "desc": desc or title})

    # -- what RWS writes (``session``: who asks) ----------------------------------------------

    def _check_master(self, session: str) -> None:
        if self.master not in (None, session):
            raise RwsRefused(403, "mastership", f"mastership held by another client "
                             f"({self.master})")

    def set_symbol(self, session: str, name: str, value: str) -> None:
        if self.faults.fires("mastership"):
            self.master = OTHER_CLIENT
        self._check_master(session)
        self.symbol(name)
        self._set(name, value)
        self.step()

    def request_mastership(self, session: str) -> None:
        self._check_master(session)
        self.master = session

    def release_mastership(self, session: str | None = None) -> None:
        """Release it (``session`` None: the operator frees it, whoever holds it)."""
        if session is None or self.master == session:
            self.master = None

    def start(self, session: str) -> None:
        self._check_master(session)
        if self.ctrlstate() != "motoron":
            raise RwsRefused(400, "state", f"cannot start RAPID: controller {self.ctrlstate()}")
        if self.opmode != "AUTO":
            raise RwsRefused(403, "state", f"cannot start RAPID remotely in {self.opmode}")
        if self.running:
            return
        self.running = True
        if self._pp_main:  # from main: forget what was not served
            self._pp_main = False
            self._serving = None
            self._set(C.VAR_BUSY, "0")
            self._set(C.VAR_ACK, self.pers[C.VAR_SEQ])
        else:  # continue: the interrupted move is served again
            self._serving = None
        self.step()

    def stop(self, session: str) -> None:
        self._check_master(session)
        if self.running:
            self.cell.command_stop()
        self.running = False

    def resetpp(self, session: str) -> None:
        self._check_master(session)
        if self.running:
            raise RwsRefused(400, "state", "cannot reset the program pointer: RAPID is running")
        self._pp_main = True

    def set_ctrlstate(self, session: str, state: str) -> None:
        self._check_master(session)
        if state not in ("motoron", "motoroff"):
            raise RwsRefused(400, "bad_value", f"ctrl-state must be motoron or motoroff, "
                             f"got {state!r}")
        if self.opmode != "AUTO":
            raise RwsRefused(403, "state", f"motors are switched on at the pendant in "
                             f"{self.opmode}")
        if state == "motoroff" and self.motors_on:
            self.cell.command_stop()
            self.running = False
        self.motors_on = state == "motoron"

    # -- the operator -----------------------------------------------------------------------

    def pendant_stop(self) -> None:
        """The operator stops RAPID at the pendant."""
        with self.lock:
            if self.running:
                self.cell.command_stop()
            self.running = False

    def motors(self, on: bool) -> None:
        """The operator switches the motors on or off (off stops RAPID)."""
        with self.lock:
            if not on:
                self.cell.command_stop()
                self.running = False
            self.motors_on = bool(on)
