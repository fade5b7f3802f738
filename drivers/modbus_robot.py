"""A PLC-style robot controller over Modbus TCP (docs/modbus-register-map.md).

All data lives in holding registers (function codes 3 and 16). Floats are
IEEE-754 float32 in two registers, high word first unless the map says
``word_order: little``. Joints in rad, lengths in mm, speeds in rad/s (joint
moves) or mm/s (linear moves).

A command is: write the targets and the speed, then write ``[command, seq]``
(``seq`` a counter the driver bumps); the controller answers by copying
``seq`` into ``command_ack`` and the result into ``error_code``. A
``heartbeat`` register that stops counting for ``stale_after_s`` means the
data are stale: :class:`~drivers.errors.ConnectionLost`.

Length: over 500 lines because the register map, its validation and the driver that
reads it are one vendor edge; splitting them would scatter the map's meaning.
"""

from __future__ import annotations

import contextlib
import logging
import struct
import time
from collections.abc import Callable, Iterable
from pathlib import Path
from typing import Any, ClassVar, Literal

import numpy as np
import yaml
from pydantic import BaseModel, ConfigDict, Field, ValidationError, model_validator
from pymodbus.client import ModbusTcpClient
from pymodbus.exceptions import ConnectionException, ModbusException, ModbusIOException

from drivers.errors import (
    CommandRejected,
    CommandTimeout,
    ConnectionLost,
    DriverError,
    LimitError,
    NotReady,
    ProtectiveStop,
    ProtocolError,
)
from drivers.protocols import DeviceIdentity, JointReading, RobotStatus
from drivers.settle import poll_until_settled, poll_until_still, settle_move

# pymodbus reports every failure through logging as well as by its return
# values; we turn those into exceptions, so keep its lines out of stderr unless
# the application configures logging itself.
logging.getLogger("pymodbus").addHandler(logging.NullHandler())
#: the registers read and written, decoded (field names, values), at DEBUG; the connection,
#: reconnects and Modbus exceptions at INFO
log = logging.getLogger(__name__)

#: command register values
CMD_NONE, CMD_MOVE_JOINTS, CMD_MOVE_LINEAR, CMD_STOP, CMD_CLEAR_FAULT = 0, 1, 2, 3, 4
#: command register value -> name (in the log)
CMD_NAMES = {CMD_NONE: "NONE", CMD_MOVE_JOINTS: "MOVE_JOINTS", CMD_MOVE_LINEAR: "MOVE_LINEAR",
             CMD_STOP: "STOP", CMD_CLEAR_FAULT: "CLEAR_FAULT"}

#: error_code register values (same codes as the line protocol)
ERR_NONE, ERR_BAD_ARGUMENT, ERR_LIMIT, ERR_UNREACHABLE = 0, 11, 20, 21
ERR_PROTECTIVE_STOP, ERR_EMERGENCY_STOP, ERR_FAULT, ERR_BAD_COMMAND = 30, 31, 32, 10

#: Read Device Identification (function 43/14) objects: the standard ones and the private
#: objects a cellcal simulator adds (serial number, the robot model it moves)
ID_VENDOR, ID_PRODUCT_CODE, ID_REVISION, ID_PRODUCT_NAME, ID_MODEL_NAME = 0, 1, 2, 4, 5
ID_SERIAL, ID_KINEMATICS = 0x80, 0x81
#: the product name with which a simulated controller declares itself
SIMULATOR_PRODUCT_NAME = "cellcal simulated controller"

#: Modbus exception code → (error class, name)
MODBUS_EXCEPTIONS: dict[int, tuple[type[DriverError], str]] = {
    1: (CommandRejected, "ILLEGAL_FUNCTION"),
    2: (CommandRejected, "ILLEGAL_DATA_ADDRESS"),
    3: (CommandRejected, "ILLEGAL_DATA_VALUE"),
    4: (CommandRejected, "SERVER_DEVICE_FAILURE"),
    5: (NotReady, "ACKNOWLEDGE"),
    6: (NotReady, "SERVER_DEVICE_BUSY"),
    10: (ConnectionLost, "GATEWAY_PATH_UNAVAILABLE"),
    11: (ConnectionLost, "GATEWAY_TARGET_FAILED_TO_RESPOND"),
}


class StatusBits(BaseModel):
    """Bit numbers (0 = least significant) in the status register."""

    model_config = ConfigDict(extra="forbid")
    in_position: int = Field(0, ge=0, le=15)
    busy: int = Field(1, ge=0, le=15)
    fault: int = Field(2, ge=0, le=15)
    protective_stop: int = Field(3, ge=0, le=15)
    emergency_stop: int = Field(4, ge=0, le=15)
    steady: int = Field(5, ge=0, le=15)


#: the address fields of a register map (a map that places any of them is a custom layout)
_ADDRESS_FIELDS = ("command", "command_seq", "speed", "target_joints", "target_xyz", "status",
                   "error_code", "heartbeat", "command_ack", "joint_count", "actual_joints",
                   "actual_tcp")
#: a joint temperature register: signed 16 bit, °C × this
TEMP_SCALE = 100.0


class RegisterMap(BaseModel):
    """Where each datum lives (holding-register addresses). Defaults: the documented map.

    ``n_joints`` is the number of joint slots (float32 pairs) in the target
    and actual blocks; the robot may use fewer (``joint_count`` register).
    ``joint_temps``: the joint temperatures, one signed 16-bit register per slot (°C ×
    :data:`TEMP_SCALE`), read on their own; None for a controller without them. The
    default map has them at 22; a map that places any other field (a custom layout) has
    them only where it says.
    """

    model_config = ConfigDict(extra="forbid")
    n_joints: int = Field(6, ge=1, le=12)
    word_order: Literal["big", "little"] = "big"
    # written by the driver
    command: int = Field(0, ge=0)
    command_seq: int = Field(1, ge=0)
    speed: int = Field(2, ge=0)
    target_joints: int = Field(4, ge=0)
    target_xyz: int = Field(16, ge=0)
    # written by the controller
    status: int = Field(32, ge=0)
    error_code: int = Field(33, ge=0)
    heartbeat: int = Field(34, ge=0)
    command_ack: int = Field(35, ge=0)
    joint_count: int = Field(36, ge=0)
    actual_joints: int = Field(40, ge=0)
    actual_tcp: int = Field(52, ge=0)
    joint_temps: int | None = Field(22, ge=0)
    bits: StatusBits = StatusBits()

    @model_validator(mode="before")
    @classmethod
    def _custom_layout_names_its_temperatures(cls, data: Any) -> Any:
        if isinstance(data, dict) and "joint_temps" not in data and any(
                k in data for k in _ADDRESS_FIELDS):
            data = {**data, "joint_temps": None}
        return data

    def fields(self) -> dict[str, tuple[int, int]]:
        """name → (first address, number of registers)."""
        n = self.n_joints
        return {
            "command": (self.command, 1),
            "command_seq": (self.command_seq, 1),
            "speed": (self.speed, 2),
            "target_joints": (self.target_joints, 2 * n),
            "target_xyz": (self.target_xyz, 6),
            "status": (self.status, 1),
            "error_code": (self.error_code, 1),
            "heartbeat": (self.heartbeat, 1),
            "command_ack": (self.command_ack, 1),
            "joint_count": (self.joint_count, 1),
            "actual_joints": (self.actual_joints, 2 * n),
            "actual_tcp": (self.actual_tcp, 6),
            **({} if self.joint_temps is None else {"joint_temps": (self.joint_temps, n)}),
        }

    #: the fields a status read covers
    READ_FIELDS: ClassVar[tuple[str, ...]] = (
        "status",
        "error_code",
        "heartbeat",
        "command_ack",
        "joint_count",
        "actual_joints",
        "actual_tcp",
    )

    @model_validator(mode="after")
    def _no_overlap(self) -> RegisterMap:
        spans = sorted((a, a + c, name) for name, (a, c) in self.fields().items())
        for (a0, e0, n0), (a1, _e1, n1) in zip(spans, spans[1:], strict=False):
            if a1 < e0:
                raise ValueError(f"register map: {n0} ({a0}..{e0 - 1}) overlaps {n1} (at {a1})")
        lo, hi = self.read_span()
        if hi - lo > 125:
            raise ValueError(f"register map: status block spans {hi - lo} registers (max 125)")
        bits = list(self.bits.model_dump().values())
        if len(set(bits)) != len(bits):
            raise ValueError("register map: two status flags share a bit")
        return self

    def read_span(self) -> tuple[int, int]:
        """[first, end) addresses of the block read for status and positions."""
        f = self.fields()
        lo = min(f[k][0] for k in self.READ_FIELDS)
        hi = max(f[k][0] + f[k][1] for k in self.READ_FIELDS)
        return lo, hi

    @property
    def size(self) -> int:
        """Registers needed to hold the whole map (highest address + 1)."""
        return max(a + c for a, c in self.fields().values())

    @classmethod
    def from_yaml(cls, path: str | Path) -> RegisterMap:
        """Load a map from YAML (keys as the fields of this model; missing keys default).

        ValueError in one line naming the file and the field (``register map m.yaml:
        speed: Input should be a valid integer``)."""
        try:
            if not Path(path).is_file():
                raise ValueError("no such file" if not Path(path).exists() else
                                 "not a regular file")
            raw = Path(path).read_bytes()
            if len(raw) > 1 << 20:
                raise ValueError("larger than 1 MB: not a register map")
            data = yaml.safe_load(raw.decode("utf-8-sig")) or {}
        except UnicodeDecodeError:
            raise ValueError(f"register map {path}: not UTF-8 text") from None
        except yaml.YAMLError as e:
            raise ValueError(f"register map {path}: not valid YAML: "
                             f"{' '.join(str(e).split())}") from None
        except (OSError, ValueError) as e:
            raise ValueError(f"register map {path}: {e}") from None
        if not isinstance(data, dict):
            raise ValueError(f"register map {path}: expected a mapping of field: address")
        try:
            return cls.model_validate(data)
        except ValidationError as e:
            parts = []
            for err in e.errors()[:3]:
                loc = ".".join(str(x) for x in err["loc"]) or "(map)"
                msg = err["msg"].removeprefix("Value error, ")
                if err["type"] == "extra_forbidden":
                    msg = "unknown field"
                parts.append(f"{loc}: {msg}")
            raise ValueError(f"register map {path}: " + "; ".join(parts)) from None

    # -------------------------------------------------------- float helpers
    def pack_floats(self, values: Iterable[float]) -> list[int]:
        """float32 values → registers (two per value, in this map's word order)."""
        out: list[int] = []
        for v in values:
            hi, lo = struct.unpack(">HH", struct.pack(">f", float(v)))
            out += [hi, lo] if self.word_order == "big" else [lo, hi]
        return out

    @staticmethod
    def pack_temps(values: Iterable[float]) -> list[int]:
        """Temperatures (°C) → registers (signed 16 bit, °C × :data:`TEMP_SCALE`)."""
        return [int(np.clip(round(float(v) * TEMP_SCALE), -32768, 32767)) & 0xFFFF
                for v in values]

    @staticmethod
    def unpack_temps(regs: Iterable[int]) -> np.ndarray:
        """Registers (signed 16 bit) → temperatures (°C)."""
        return np.array([(r - 65536 if r >= 32768 else r) / TEMP_SCALE for r in regs], float)

    def unpack_floats(self, regs: Iterable[int]) -> np.ndarray:
        """Registers (two per value) → float64 array."""
        regs = list(regs)
        out = []
        for i in range(0, len(regs) - 1, 2):
            a, b = regs[i], regs[i + 1]
            hi, lo = (a, b) if self.word_order == "big" else (b, a)
            out.append(struct.unpack(">f", struct.pack(">HH", hi, lo))[0])
        return np.array(out, float)


class ModbusRobot:
    """RobotDriver (+ ``read_tcp``) for a controller exposing :class:`RegisterMap` over Modbus TCP.

    Parameters
    ----------
    url : str
        Driver URL for messages (``modbus+tcp://host:port?unit=1``).
    host, port : str, int
        Controller address.
    unit : int
        Modbus unit (device) id.
    map_file : str or None
        YAML register map; None for the default map.
    register_map : RegisterMap or None
        A map object (wins over ``map_file``).
    stale_after_s : float
        Heartbeat unchanged for this long → ConnectionLost.
    poll_s : float
        Status polling period of :meth:`wait_settled` (s).
    """

    def __init__(
        self,
        url: str,
        host: str,
        port: int = 502,
        *,
        unit: int = 1,
        map_file: str | None = None,
        register_map: RegisterMap | None = None,
        stale_after_s: float = 2.0,
        poll_s: float = 0.01,
    ) -> None:
        self.url = url
        self.host, self.port, self.unit = host, port, unit
        self.map = register_map or (RegisterMap.from_yaml(map_file) if map_file else RegisterMap())
        self.stale_after_s = stale_after_s
        self.poll_s = poll_s
        self.n_joints = 0
        self._client: ModbusTcpClient | None = None
        self._seq = 0
        self._hb: int | None = None
        self._hb_changed = 0.0
        self._dev = f"robot {url}"

    # ----------------------------------------------------------- connection
    def connect(self, timeout: float = 5.0) -> None:
        """Connect and read the status block (learns the joint count)."""
        self.close()
        client = ModbusTcpClient(self.host, port=self.port, timeout=timeout, retries=0)
        if not client.connect():
            client.close()
            log.info("%s: cannot reach %s:%s", self._dev, self.host, self.port)
            raise ConnectionLost(self._dev, "connect", f"cannot reach {self.host}:{self.port}")
        log.info("%s: connected to %s:%s, unit %d", self._dev, self.host, self.port, self.unit)
        self._client = client
        self._hb = None
        try:
            blk = self._read_block("connect", time.monotonic() + timeout)
        except DriverError:
            self.close()
            raise
        n = blk["joint_count"]
        if not 1 <= n <= self.map.n_joints:
            self.close()
            raise ProtocolError(
                self._dev, "connect", f"joint_count {n} outside 1..{self.map.n_joints}"
            )
        self.n_joints = n
        self._seq = blk["command_ack"]
        log.info("%s: %d joints, last command acknowledged %d", self._dev, n, self._seq)

    def identify(self, timeout: float = 2.0) -> DeviceIdentity:
        """Who the controller is, from Read Device Identification (function 43/14,
        extended objects): model (ModelName, else ProductCode), firmware
        (MajorMinorRevision), serial (private object 0x80). A simulator names itself by
        its ProductName and gives the robot model it moves (0x81). A controller that does
        not answer function 43 is an unknown real device."""
        deadline = time.monotonic() + timeout
        log.debug("%s: > identify: read device identification (43/14, extended)", self._dev)
        try:
            rr = self._call("identify", deadline,
                            self._client_method("read_device_information"), read_code=3)
            info = {int(k): (v.decode("utf-8", "replace") if isinstance(v, bytes) else str(v))
                    for k, v in dict(getattr(rr, "information", {}) or {}).items()}
        except DriverError:
            info = {}
        log.debug("%s: < identify: %s", self._dev, info)
        sim = info.get(ID_PRODUCT_NAME, "") == SIMULATOR_PRODUCT_NAME
        return DeviceIdentity(
            "robot", info.get(ID_MODEL_NAME) or info.get(ID_PRODUCT_CODE, ""),
            info.get(ID_SERIAL, ""), info.get(ID_REVISION, ""), simulator=sim,
            kinematics=info.get(ID_KINEMATICS, "") if sim else "", n_joints=self.n_joints)

    def close(self) -> None:
        """Close the connection (idempotent)."""
        client, self._client = self._client, None
        if client is not None:
            log.info("%s: connection closed", self._dev)
            client.close()

    def __enter__(self) -> ModbusRobot:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    # ------------------------------------------------------------- plumbing
    def _call(self, command: str, deadline: float, fn: Callable[..., Any], *args: Any,
              **kw: Any) -> Any:
        """Run one pymodbus request; every failure becomes a typed error."""
        client = self._client
        if client is None:
            raise ConnectionLost(self._dev, command, "not connected")
        left = deadline - time.monotonic()
        if left <= 0:
            raise CommandTimeout(self._dev, command, "no time left")
        client.comm_params.timeout_connect = left
        try:
            rr = fn(*args, device_id=self.unit, **kw)
        except ConnectionException as e:
            log.info("%s: %s: connection lost: %s", self._dev, command, e)
            self.close()
            raise ConnectionLost(self._dev, command, str(e)) from e
        except ModbusIOException as e:
            # no (complete) response in time: close the socket so a late reply
            # cannot be taken for the answer to the next request; pymodbus
            # reopens it on the next request
            log.info("%s: %s: no reply within %.3f s", self._dev, command, left)
            client.close()
            raise CommandTimeout(self._dev, command, f"no reply within {left:.3f} s") from e
        except (ModbusException, OSError) as e:
            log.info("%s: %s: connection lost: %s", self._dev, command, e)
            self.close()
            raise ConnectionLost(self._dev, command, str(e)) from e
        if rr.isError():
            code = int(getattr(rr, "exception_code", 0))
            cls, name = MODBUS_EXCEPTIONS.get(code, (CommandRejected, "UNKNOWN"))
            log.info("%s: %s: Modbus exception %d %s", self._dev, command, code, name)
            raise cls(self._dev, command, f"Modbus exception {code} {name}")
        return rr

    def _read(self, command: str, deadline: float, address: int, count: int, *,
              retry: bool = True) -> list[int]:
        """Read ``count`` holding registers; reconnect and retry once after a lost link."""
        was_connected = self._client is not None  # never reopen a link the caller closed
        read = self._client_method("read_holding_registers")
        log.debug("%s: > %s: read %d registers at %d", self._dev, command, count, address)
        try:
            rr = self._call(command, deadline, read, address, count=count)
        except ConnectionLost:
            if not (retry and was_connected) or time.monotonic() >= deadline:
                raise
            log.info("%s: %s: reconnecting to retry once", self._dev, command)
            self._reconnect(deadline)
            rr = self._call(command, deadline, read, address, count=count)
        regs = list(rr.registers)
        log.debug("%s: < %s: %s", self._dev, command, regs)
        if len(regs) != count:
            raise ProtocolError(self._dev, command, f"read {len(regs)} registers, wanted {count}")
        return regs

    def _read_block(self, command: str, deadline: float, *,
                    retry: bool = True) -> dict[str, Any]:
        lo, hi = self.map.read_span()
        regs = self._read(command, deadline, lo, hi - lo, retry=retry)
        f = self.map.fields()

        def get(name: str) -> list[int]:
            a, c = f[name]
            return regs[a - lo : a - lo + c]

        hb = get("heartbeat")[0]
        now = time.monotonic()
        if hb != self._hb:
            self._hb, self._hb_changed = hb, now
        elif now - self._hb_changed > self.stale_after_s:
            stuck = now - self._hb_changed
            raise ConnectionLost(
                self._dev, command, f"stale data: heartbeat stuck at {hb} for {stuck:.1f} s"
            )
        n = self.n_joints or self.map.n_joints
        blk: dict[str, Any] = {
            "status": get("status")[0],
            "error_code": get("error_code")[0],
            "heartbeat": hb,
            "command_ack": get("command_ack")[0],
            "joint_count": get("joint_count")[0],
            "q": self.map.unpack_floats(get("actual_joints"))[:n],
            "tcp": self.map.unpack_floats(get("actual_tcp")),
        }
        if log.isEnabledFor(logging.DEBUG):
            flags = [k for k, on in self._flags(blk["status"]).items() if on]
            log.debug("%s: < %s: status 0x%04x %s, error %d, heartbeat %d, ack %d, joints %d, "
                      "q %s rad, tcp %s mm", self._dev, command, blk["status"],
                      ",".join(flags) or "-", blk["error_code"], hb, blk["command_ack"],
                      blk["joint_count"], np.round(blk["q"], 6).tolist(),
                      np.round(blk["tcp"], 4).tolist())
        return blk

    def _client_method(self, name: str) -> Callable[..., Any]:
        def call(*args: Any, **kw: Any) -> Any:
            client = self._client
            if client is None:
                raise ConnectionException("not connected")
            return getattr(client, name)(*args, **kw)

        return call

    def _reconnect(self, deadline: float) -> None:
        client = ModbusTcpClient(
            self.host, port=self.port, timeout=max(deadline - time.monotonic(), 0.05), retries=0
        )
        if not client.connect():
            client.close()
            log.info("%s: reconnect: cannot reach %s:%s", self._dev, self.host, self.port)
            raise ConnectionLost(self._dev, "reconnect", f"cannot reach {self.host}:{self.port}")
        log.info("%s: reconnected to %s:%s", self._dev, self.host, self.port)
        self._client = client

    def _write(self, command: str, deadline: float, address: int, values: list[int]) -> None:
        if log.isEnabledFor(logging.DEBUG):
            log.debug("%s: > %s: write %s", self._dev, command, self._decode(address, values))
        self._call(command, deadline, self._client_method("write_registers"), address, values)

    def _decode(self, address: int, values: list[int]) -> str:
        """Registers written at ``address``, named by the map's fields (floats decoded)."""
        floats = ("speed", "target_joints", "target_xyz")
        parts, a, end = [], address, address + len(values)
        spans = sorted((start, name, count) for name, (start, count) in self.map.fields().items())
        for start, name, count in spans:
            if start < a or start >= end:
                continue
            regs = values[start - address:start - address + count]
            shown = (np.round(self.map.unpack_floats(regs), 6).tolist() if name in floats
                     else regs[0] if len(regs) == 1 else regs)
            if name == "command":
                shown = f"{shown} {CMD_NAMES.get(regs[0], '?')}"
            parts.append(f"{name}={shown}")
        return f"{', '.join(parts) or values} (at {address})"

    def _flags(self, status: int) -> dict[str, bool]:
        return {k: bool(status >> b & 1) for k, b in self.map.bits.model_dump().items()}

    # --------------------------------------------------------------- queries
    def read_joints(self, timeout: float = 1.0) -> JointReading:
        """Actual joints (rad, shape (n_joints,)) and the time they were read (epoch s)."""
        blk = self._read_block("read_joints", time.monotonic() + timeout)
        return JointReading(q=blk["q"], timestamp=time.time())

    def read_tcp(self, timeout: float = 1.0) -> np.ndarray:
        """The controller's nominal TCP position (mm, base frame), shape (3,)."""
        return self._read_block("read_tcp", time.monotonic() + timeout)["tcp"]

    def joint_temperatures(self, timeout: float = 1.0) -> tuple[float, ...]:
        """Each joint's temperature (°C) from the ``joint_temps`` registers; CommandRejected
        when the map has none or the controller refuses them (exception 2)."""
        if self.map.joint_temps is None:
            raise CommandRejected(self._dev, "joint_temperatures",
                                  "the register map has no joint_temps")
        n = self.n_joints or self.map.n_joints
        regs = self._read("joint_temperatures", time.monotonic() + timeout,
                          self.map.joint_temps, n)
        return tuple(float(v) for v in self.map.unpack_temps(regs))

    def status(self, timeout: float = 1.0) -> RobotStatus:
        """Status bits, error code and heartbeat freshness."""
        blk = self._read_block("status", time.monotonic() + timeout)
        fl = self._flags(blk["status"])
        return RobotStatus(
            connected=True,
            moving=fl["busy"],
            in_position=fl["in_position"] and fl["steady"],
            fault=fl["fault"],
            protective_stop=fl["protective_stop"],
            emergency_stop=fl["emergency_stop"],
            error_code=blk["error_code"],
            message=f"status=0x{blk['status']:04x} error={blk['error_code']} hb={blk['heartbeat']}",
            timestamp=time.time(),
        )

    # --------------------------------------------------------------- motion
    def _command(self, name: str, code: int, deadline: float) -> None:
        m = self.map
        self._seq = (self._seq + 1) % 65536 or 1
        if m.command_seq == m.command + 1:
            self._write(name, deadline, m.command, [code, self._seq])
        else:
            self._write(name, deadline, m.command_seq, [self._seq])
            self._write(name, deadline, m.command, [code])
        while True:
            blk = self._read_block(name, deadline, retry=False)
            if blk["command_ack"] == self._seq:
                break
            if time.monotonic() >= deadline:
                raise CommandTimeout(self._dev, name, f"command {self._seq} not acknowledged")
            time.sleep(self.poll_s)
        err, fl = blk["error_code"], self._flags(blk["status"])
        log.debug("%s: < %s: command %d acknowledged, error code %d", self._dev, name,
                  self._seq, err)
        if err in (ERR_PROTECTIVE_STOP, ERR_EMERGENCY_STOP) or (
            code in (CMD_MOVE_JOINTS, CMD_MOVE_LINEAR)
            and (fl["protective_stop"] or fl["emergency_stop"])
        ):
            raise ProtectiveStop(self._dev, name, f"error code {err}")
        if err == ERR_LIMIT:
            raise LimitError(self._dev, name, f"error code {err} LIMIT")
        if err != ERR_NONE:
            raise CommandRejected(self._dev, name, f"error code {err}")

    def _refine(self, e: CommandRejected, name: str, deadline: float) -> DriverError:
        """After an ILLEGAL_DATA_VALUE on a command, read error_code to name the cause."""
        if "ILLEGAL_DATA_VALUE" not in str(e):
            return e
        try:
            err = self._read_block(name, deadline, retry=False)["error_code"]
        except DriverError:
            return e
        if err == ERR_LIMIT:
            return LimitError(self._dev, name, f"{e.detail}, error code {err} LIMIT")
        return CommandRejected(self._dev, name, f"{e.detail}, error code {err}")

    def move_joints(self, q: np.ndarray, speed: float = 0.5, timeout: float = 60.0) -> None:
        """Joint move to ``q`` (rad, shape (n_joints,)) at ``speed`` rad/s: the command, its
        acknowledgement, then the status block until settled; returns once the robot has
        arrived and settled within ``timeout`` (else STOP and CommandTimeout)."""
        deadline = time.monotonic() + timeout
        q = np.asarray(q, float)
        if q.shape != (self.n_joints,):
            raise CommandRejected(self._dev, "move_joints", f"expected {self.n_joints} joints")
        padded = np.zeros(self.map.n_joints)
        padded[: self.n_joints] = q
        cmd_deadline = min(deadline, time.monotonic() + 5.0)
        try:
            self._write("move_joints", cmd_deadline, self.map.speed, self.map.pack_floats([speed]))
            self._write(
                "move_joints", cmd_deadline, self.map.target_joints, self.map.pack_floats(padded)
            )
            self._command("move_joints", CMD_MOVE_JOINTS, cmd_deadline)
        except CommandRejected as e:
            raise self._refine(e, "move_joints", cmd_deadline) from e
        settle_move(self.wait_settled, self.stop, self._dev, "move_joints", deadline)

    def move_linear(self, xyz: np.ndarray, speed: float = 100.0, timeout: float = 60.0) -> None:
        """Linear TCP move to ``xyz`` (mm, base frame, shape (3,)) at ``speed`` mm/s; returns
        once settled (as :meth:`move_joints`)."""
        deadline = time.monotonic() + timeout
        xyz = np.asarray(xyz, float)
        if xyz.shape != (3,):
            raise CommandRejected(self._dev, "move_linear", "expected x y z")
        cmd_deadline = min(deadline, time.monotonic() + 5.0)
        try:
            self._write("move_linear", cmd_deadline, self.map.speed, self.map.pack_floats([speed]))
            self._write("move_linear", cmd_deadline, self.map.target_xyz, self.map.pack_floats(xyz))
            self._command("move_linear", CMD_MOVE_LINEAR, cmd_deadline)
        except CommandRejected as e:
            raise self._refine(e, "move_linear", cmd_deadline) from e
        settle_move(self.wait_settled, self.stop, self._dev, "move_linear", deadline)

    def wait_settled(self, timeout: float = 30.0) -> None:
        """Poll the status block until in position and steady; raise on stops or faults."""
        poll_until_settled(lambda t: self.status(timeout=t), self._dev, timeout, self.poll_s)

    def stop(self, timeout: float = 2.0) -> None:
        """Command STOP, then poll the status block until the robot stands still."""
        deadline = time.monotonic() + timeout
        self._command("stop", CMD_STOP, deadline)
        poll_until_still(lambda t: self.status(timeout=t), self._dev, "stop", deadline,
                         self.poll_s)

    def clear_protective_stop(self, timeout: float = 2.0) -> None:
        """Command CLEAR_FAULT (clears a protective stop or fault)."""
        deadline = time.monotonic() + timeout
        # the ack may still carry the old error code: the flags decide
        with contextlib.suppress(ProtectiveStop):
            self._command("clear_protective_stop", CMD_CLEAR_FAULT, deadline)
        st = self.status(max(deadline - time.monotonic(), 0.01))
        if st.protective_stop or st.emergency_stop:
            raise ProtectiveStop(self._dev, "clear_protective_stop", st.message)
