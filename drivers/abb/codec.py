"""ABB Robot Web Services 1.0 (IRC5, RobotWare 6): the resources cellcal uses, their JSON,
RAPID's text for data values, and the protocol of the RAPID server module.

Shared by the driver (:mod:`drivers.abb.driver`) and the simulator's server
(``sim_drivers.rws_server``), so both speak one dialect. Sources (docs/abb.md lists each
call): the RWS reference, ABB Application Manual *Robot Web Services* 3HAC050973-001
(developercenter.robotstudio.com/api/rwsApi), and the client ``abb-robot-client`` 0.4.0
(``abb_robot_client/rws.py``), whose URLs, form fields and JSON keys are used here as it
uses them.

JSON (``?json=1``): every answer is ``{"_links": ..., "_embedded": {"_state": [ITEM, ...]}}``,
each item a dict with ``_type`` and ``_title`` and the resource's fields as strings; an
error is ``{"_embedded": {"status": {"code": N, "msg": "..."}}}`` with an HTTP status of
400 or more. Writes are HTML form posts (``application/x-www-form-urlencoded``) answered
with 204 No Content.

RAPID values travel as RAPID text: a ``num`` as ``12.5``, a ``jointtarget`` as
``[[j1,..,j6],[e1,..,e6]]`` (degrees; ``9E+09`` marks an external axis not in use), a
``pos`` as ``[x,y,z]`` (mm), a ``speeddata`` as ``[v_tcp,v_ori,v_leax,v_reax]``, a
``zonedata`` as its seven components (``fine``: ``[TRUE,0,0,0,0,0,0]``), a ``string`` in
double quotes.
"""

from __future__ import annotations

import math
import re
from collections.abc import Iterable, Sequence

#: RWS listens on HTTP port 80 of the controller's WAN (or service) port
DEFAULT_PORT = 80
#: the user every IRC5 has out of the factory (and its password): the URL may name another
DEFAULT_USER, DEFAULT_PASSWORD = "Default User", "robotics"
#: the realm of RWS 1.0's digest authentication
REALM = "validusers@robapi.abb"

#: RAPID's "no external axis here"
EAX_UNUSED = 9e9

# -- resources (relative to the controller's root, as abb-robot-client writes them) ---------

CTRLSTATE = "rw/panel/ctrlstate"
OPMODE = "rw/panel/opmode"
SPEEDRATIO = "rw/panel/speedratio"
EXECUTION = "rw/rapid/execution"
EXEC_START = "rw/rapid/execution?action=start"
EXEC_STOP = "rw/rapid/execution?action=stop"
EXEC_RESETPP = "rw/rapid/execution?action=resetpp"
TASKS = "rw/rapid/tasks"
MASTERSHIP = "rw/mastership"
MASTERSHIP_REQUEST = "rw/mastership?action=request"
MASTERSHIP_RELEASE = "rw/mastership?action=release"
SYSTEM = "rw/system"
ROBOTTYPE = "rw/system/robottype"
IDENTITY = "ctrl/identity"
ELOG = "rw/elog/0"
LOGOUT = "logout"

#: the form of ``rw/rapid/execution?action=start`` (as abb-robot-client's ``RWS.start``)
START_FORM = {"regain": "continue", "execmode": "continue", "cycle": "forever",
              "condition": "none", "stopatbp": "disabled", "alltaskbytsp": "false"}
#: the form of ``rw/rapid/execution?action=stop``
STOP_FORM = {"stopmode": "stop"}

#: controller states (``rw/panel/ctrlstate``): the robot moves only in ``motoron``
CTRL_STATES = ("init", "motoron", "motoroff", "guardstop", "emergencystop",
               "emergencystopreset", "sysfail")
#: operating modes (``rw/panel/opmode``): RAPID is started remotely only in ``AUTO``
OPMODES = ("INIT", "AUTO_CH", "MANF_CH", "MANR", "MANF", "AUTO", "UNDEF")


def jointtarget_path(mechunit: str) -> str:
    """The mechanical unit's joints now (``ms-jointtarget``: ``rax_1``..``rax_6`` deg)."""
    return f"rw/motionsystem/mechunits/{mechunit}/jointtarget"


def robtarget_path(mechunit: str, tool: str, wobj: str, coordinate: str = "Base") -> str:
    """Its TCP now (``ms-robtargets``: ``x y z`` mm, ``q1..q4``) for ``tool`` in ``wobj``."""
    return (f"rw/motionsystem/mechunits/{mechunit}/robtarget?tool={tool}&wobj={wobj}"
            f"&coordinate={coordinate}")


def symbol_path(task: str, module: str, name: str) -> str:
    """A RAPID data symbol (``rap-data``: its ``value`` as RAPID text)."""
    return f"rw/rapid/symbol/data/RAPID/{task}/{module}/{name}"


def symbol_set_path(task: str, module: str, name: str) -> str:
    """Write a RAPID data symbol: form ``value=<RAPID text>``."""
    return symbol_path(task, module, name) + "?action=set"


def with_json(path: str) -> str:
    """``path`` asking for JSON (``json=1``), as abb-robot-client asks."""
    return path + ("&" if "?" in path else "?") + "json=1"


# -- JSON -----------------------------------------------------------------------------------

def states(doc: dict | None) -> list[dict]:
    """The items of an answer (``_embedded._state``); [] for none."""
    if not isinstance(doc, dict):
        return []
    items = (doc.get("_embedded") or {}).get("_state") or []
    return [i for i in items if isinstance(i, dict)]


def field(doc: dict | None, key: str, type_: str | None = None) -> str:
    """The first item's ``key`` (of the first item of ``_type`` ``type_``); KeyError naming
    what is missing."""
    for item in states(doc):
        if (type_ is None or item.get("_type") == type_) and key in item:
            return str(item[key])
    raise KeyError(f"no {key!r}" + (f" in a {type_!r} item" if type_ else ""))


def status_of(doc: dict | None) -> tuple[int, str]:
    """The ``(code, msg)`` of an error answer ((0, "") when it carries none)."""
    if not isinstance(doc, dict):
        return 0, ""
    st = (doc.get("_embedded") or {}).get("status") or {}
    try:
        code = int(st.get("code", 0))
    except (TypeError, ValueError):
        code = 0
    return code, str(st.get("msg", ""))


def state_doc(base: str, items: Iterable[dict]) -> dict:
    """An answer holding ``items`` (the server's side)."""
    return {"_links": {"base": {"href": base}}, "_embedded": {"_state": list(items)}}


def error_doc(code: int, msg: str) -> dict:
    """An error answer (the server's side)."""
    return {"_links": {}, "_embedded": {"status": {"code": int(code), "msg": msg}}}


# -- RAPID text -------------------------------------------------------------------------------

def rapid_num(x: float) -> str:
    """A ``num`` as RAPID writes it (``9E+09`` for the unused-axis mark)."""
    x = float(x)
    if not math.isfinite(x):
        raise ValueError(f"a RAPID num must be finite, got {x}")
    if abs(x) >= 1e9:
        return f"{x:.0E}"
    text = f"{x:.6f}".rstrip("0").rstrip(".")
    return "0" if text in ("-0", "") else text


def rapid_array(values: Iterable[float]) -> str:
    return "[" + ",".join(rapid_num(v) for v in values) + "]"


def jointtarget_text(robax_deg: Sequence[float], extax: Sequence[float] | None = None) -> str:
    """``[[robax],[extax]]``: six robot axes (deg; fewer are padded with 0) and six external
    axes (default: none in use)."""
    rob = list(robax_deg) + [0.0] * (6 - len(robax_deg))
    ext = list(extax) if extax is not None else [EAX_UNUSED] * 6
    if len(rob) != 6 or len(ext) != 6:
        raise ValueError("a jointtarget has 6 robot and 6 external axes")
    return f"[{rapid_array(rob)},{rapid_array(ext)}]"


def pos_text(xyz: Sequence[float]) -> str:
    """A ``pos`` (mm)."""
    if len(xyz) != 3:
        raise ValueError("a pos has 3 components")
    return rapid_array(xyz)


def speeddata_text(v_tcp: float, v_ori: float = 500.0, v_leax: float = 5000.0,
                   v_reax: float = 1000.0) -> str:
    """A ``speeddata``: TCP mm/s, orientation deg/s, linear and rotating external axes."""
    return rapid_array((v_tcp, v_ori, v_leax, v_reax))


#: ``fine``: a stop point, the robot in position before the instruction ends
ZONE_FINE = "[TRUE,0,0,0,0,0,0]"


def string_text(s: str) -> str:
    """A RAPID ``string`` literal (double quotes; a quote or backslash doubled)."""
    return '"' + s.replace("\\", "\\\\").replace('"', '""') + '"'


def parse_string(text: str) -> str:
    """The text of a RAPID ``string`` literal."""
    t = text.strip()
    if len(t) < 2 or t[0] != '"' or t[-1] != '"':
        raise ValueError(f"not a RAPID string: {text!r}")
    return t[1:-1].replace('""', '"').replace("\\\\", "\\")


_NUMBER = r"[-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?"


def parse_numbers(text: str) -> list[float]:
    """Every number of a RAPID aggregate, in order (``[[1,2],[3]]`` → [1, 2, 3]); ValueError
    for text that is not numbers in brackets and commas."""
    t = text.strip()
    if not t or re.sub(_NUMBER, "", t).strip("[], \t") != "":
        raise ValueError(f"not a RAPID aggregate of numbers: {text[:80]!r}")
    return [float(m) for m in re.findall(_NUMBER, t)]


def parse_num(text: str) -> float:
    """A RAPID ``num``."""
    v = parse_numbers(text)
    if len(v) != 1 or text.strip().startswith("["):
        raise ValueError(f"not a RAPID num: {text!r}")
    return v[0]


def parse_jointtarget(text: str) -> tuple[list[float], list[float]]:
    """(robax deg, extax) of a ``jointtarget``."""
    v = parse_numbers(text)
    if len(v) != 12 or not text.strip().startswith("[["):
        raise ValueError(f"not a RAPID jointtarget: {text[:80]!r}")
    return v[:6], v[6:]


# -- the RAPID server module (drivers/abb/rapid/CellcalServer.mod) -----------------------------

#: the module and its task
MODULE, TASK, MECHUNIT = "CellcalServer", "T_ROB1", "ROB_1"

#: the module's persistent variables, by role
VAR_SEQ = "cc_seq"          # num: the request number; the driver writes it last
VAR_ACK = "cc_ack"          # num: the request number last served (done or refused)
VAR_BUSY = "cc_busy"        # num: 1 while a move runs (until it is in position, fine)
VAR_KIND = "cc_kind"        # num: KIND_JOINTS or KIND_LINEAR
VAR_JOINTS = "cc_joints"    # jointtarget: MoveAbsJ's target (deg)
VAR_TIME = "cc_time"        # num: MoveAbsJ's duration (s), \T: sets the leading joint's speed
VAR_XYZ = "cc_xyz"          # pos: MoveL's target (mm, wobj), the orientation kept
VAR_SPEED = "cc_speed"      # speeddata: MoveL's speed
VAR_ZONE = "cc_zone"        # zonedata: both moves' zone (fine)
VAR_TOOL = "cc_toolname"    # string: the tooldata MoveL and the limits check use
VAR_ERR = "cc_err"          # num: how the last request ended (ERR_*)
VAR_MSG = "cc_msg"          # string: in words

KIND_JOINTS, KIND_LINEAR = 1, 2

#: cc_err: how a request ended
ERR_NONE, ERR_LIMIT, ERR_UNREACHABLE, ERR_BAD_ARGUMENT = 0, 1, 2, 3
ERR_NAMES = {ERR_NONE: "NONE", ERR_LIMIT: "LIMIT", ERR_UNREACHABLE: "UNREACHABLE",
             ERR_BAD_ARGUMENT: "BAD_ARGUMENT"}

#: RAPID's num is a 32-bit float: a request number stays an exact integer below 2**23
SEQ_WRAP = 8_000_000


def next_seq(seq: int) -> int:
    """The request number after ``seq`` (1..SEQ_WRAP-1, never 0: the module's start value)."""
    return seq + 1 if 0 < seq + 1 < SEQ_WRAP else 1
