"""The simulated PLC-style controller: a pymodbus TCP server over a :class:`SimCell`.

Holding registers laid out by :class:`drivers.modbus_robot.RegisterMap`
(docs/modbus-register-map.md). A pymodbus ``SimDevice`` action hook refreshes
the status block on every read (the heartbeat counts reads) and executes a
command when the ``command`` register is written. Runs its own asyncio loop on
a background thread; ``start()``/``stop()`` or ``with``.

Joint temperatures (``joint_temps``) are served as the cell's controller reports them (its
thermal model's, else the air's, constant); from a cell whose controller reports none
(``SimCell(joint_temps=False)``) a read that touches them gets exception 2
(ILLEGAL_DATA_ADDRESS), as from a controller that does not have them.

Faults (per request): ``modbus`` → exception 4 (SERVER_DEVICE_FAILURE),
``slow`` → the response is held back ``delay`` s, ``drop`` → every client
connection is closed, ``stale`` → the heartbeat does not count on that read,
``pstop`` → a move command triggers a protective stop.
"""

from __future__ import annotations

import asyncio
import threading
from types import SimpleNamespace

import numpy as np
from pymodbus import ModbusDeviceIdentification
from pymodbus.constants import ExcCodes
from pymodbus.pdu.device import DeviceInformationFactory
from pymodbus.pdu.mei_message import ReadDeviceInformationRequest, ReadDeviceInformationResponse
from pymodbus.server import ModbusTcpServer
from pymodbus.simulator import DataType, SimData, SimDevice

from drivers.modbus_robot import (
    CMD_CLEAR_FAULT,
    CMD_MOVE_JOINTS,
    CMD_MOVE_LINEAR,
    CMD_NONE,
    CMD_STOP,
    ERR_BAD_ARGUMENT,
    ERR_BAD_COMMAND,
    ID_KINEMATICS,
    ID_SERIAL,
    SIMULATOR_PRODUCT_NAME,
    RegisterMap,
)
from sim_drivers.cell import CellRefused, SimCell
from sim_drivers.faults import FaultInjector
from sim_drivers.robot_server import ROBOT_ERROR_CODES


def _identity_request(identity: ModbusDeviceIdentification) -> type:
    """A Read Device Identification request class answering with this server's own
    ``identity`` (pymodbus keeps one identity per process; each simulated controller
    needs its own)."""

    class SimIdentityRequest(ReadDeviceInformationRequest):
        async def datastore_update(self, context, device_id):
            if not (0 <= self.read_code <= 4 and 0 <= self.object_id <= 0xFF):
                return await super().datastore_update(context, device_id)
            info = DeviceInformationFactory.get(SimpleNamespace(Identity=identity),
                                                self.read_code, self.object_id)
            return ReadDeviceInformationResponse(read_code=self.read_code, information=info,
                                                 dev_id=device_id,
                                                 transaction_id=self.transaction_id)

    return SimIdentityRequest


def sim_identity(cell: SimCell) -> ModbusDeviceIdentification:
    """What the simulated controller answers to Read Device Identification: it names
    itself a simulator (ProductName), its serial (0x80) and the robot model it moves
    (0x81)."""
    return ModbusDeviceIdentification(info={
        0x00: "cellcal", 0x01: "SIMPLC-1", 0x02: "1.0", 0x04: SIMULATOR_PRODUCT_NAME,
        0x05: "SIMPLC-1", ID_SERIAL: cell.serial("robot"),
        ID_KINEMATICS: cell.kinematics or "unknown"})


class ModbusRobotServer:
    """Modbus TCP server for ``cell``'s robot.

    Parameters
    ----------
    cell : SimCell
    faults : FaultInjector or None
        Defaults to the cell's injector (or none).
    register_map : RegisterMap or None
        Default: the documented map.
    host, port : str, int
        Address (port 0: a free one; see :attr:`port` after :meth:`start`).
    """

    def __init__(
        self,
        cell: SimCell,
        *,
        faults: FaultInjector | None = None,
        register_map: RegisterMap | None = None,
        host: str = "127.0.0.1",
        port: int = 0,
    ) -> None:
        self.cell = cell
        self.faults = faults if faults is not None else (cell.faults or FaultInjector())
        self.map = register_map or RegisterMap()
        if cell.n_joints > self.map.n_joints:
            raise ValueError(
                f"register map has {self.map.n_joints} joint slots, robot has {cell.n_joints}"
            )
        self.host, self.port = host, port
        self._thread: threading.Thread | None = None
        self._loop: asyncio.AbstractEventLoop | None = None
        self._stop: asyncio.Event | None = None
        self._server: ModbusTcpServer | None = None
        self._ready = threading.Event()
        self._error: BaseException | None = None
        self._stopping = False
        self._heartbeat = 0
        self._ack = 0
        self._error_code = 0

    @property
    def url(self) -> str:
        """The driver URL ``modbus+tcp://host:port?unit=1``."""
        return f"modbus+tcp://{self.host}:{self.port}?unit=1"

    # ------------------------------------------------------------ lifecycle
    def start(self) -> ModbusRobotServer:
        """Start serving on a background thread; returns self once listening."""
        self._ready.clear()
        self._error = None
        self._stopping = False
        self._thread = threading.Thread(target=self._run, name="sim-modbus", daemon=True)
        self._thread.start()
        self._ready.wait(10.0)
        if self._error is not None:
            self._thread.join(5.0)
            self._thread = None
            raise OSError(f"Modbus server on {self.host}:{self.port}: {self._error}")
        return self

    def stop(self) -> None:
        """Stop serving, close connections and join the thread (idempotent)."""
        self._stopping = True
        if self._thread is not None and self._loop is not None and self._stop is not None:
            self._loop.call_soon_threadsafe(self._stop.set)
        if self._thread is not None:
            self._thread.join(10.0)
            self._thread = None

    def __enter__(self) -> ModbusRobotServer:
        return self.start()

    def __exit__(self, *exc) -> None:
        self.stop()

    def _run(self) -> None:
        try:
            asyncio.run(self._main())
        except BaseException as e:  # report start-up failures to start()
            self._error = e
            self._ready.set()

    async def _main(self) -> None:
        self._loop = asyncio.get_running_loop()
        self._stop = asyncio.Event()
        device = SimDevice(
            id=0,
            simdata=[SimData(0, count=self.map.size, values=0, datatype=DataType.REGISTERS)],
            action=self._action,
        )
        server = ModbusTcpServer(device, address=(self.host, self.port))
        # this server's own device identification (function 43/14)
        request = _identity_request(sim_identity(self.cell))
        sub = {k: dict(v) for k, v in server.decoder.pdu_sub_table.items()}
        sub.setdefault(request.function_code, {})[request.sub_function_code] = (
            request, ReadDeviceInformationResponse)
        server.decoder.pdu_sub_table = sub
        await server.serve_forever(background=True)
        if server.transport is None:
            raise OSError("could not listen")
        self.port = server.transport.sockets[0].getsockname()[1]
        self._server = server
        self._ready.set()
        try:
            await self._stop.wait()
        finally:
            await server.shutdown()
            self._server = None

    # --------------------------------------------------------------- faults
    def drop_all(self) -> None:
        """Close every client connection (call from any thread)."""
        if self._loop is not None and self._server is not None:
            self._loop.call_soon_threadsafe(self._drop)

    def _drop(self) -> None:
        if self._server is not None:
            for conn in list(self._server.active_connections.values()):
                conn.close()

    async def _sleep(self, seconds: float) -> None:
        end = asyncio.get_running_loop().time() + seconds
        while not self._stopping and asyncio.get_running_loop().time() < end:
            await asyncio.sleep(0.02)

    # -------------------------------------------------------------- registers
    async def _action(self, fc, start, address, count, regs, values):
        f = self.faults
        f.begin_command()
        if f.fires("drop"):
            self._drop()
            return ExcCodes.DEVICE_FAILURE  # never delivered: the link is gone
        if f.fires("slow"):
            await self._sleep(f.delay_s)
        if f.fires("modbus"):
            return ExcCodes.DEVICE_FAILURE
        if values is None:
            temps = self.map.fields().get("joint_temps")
            if (temps is not None and address < temps[0] + temps[1]
                    and temps[0] < address + count and self.cell.joint_temperatures() is None):
                return ExcCodes.ILLEGAL_ADDRESS  # as a controller without them answers
            self._refresh(regs, start, stale=f.fires("stale"))
            return None
        image = list(regs)
        image[address - start : address - start + count] = list(values)
        if address <= self.map.command < address + count:
            result = self._execute(image, start)
            self._refresh(regs, start, stale=False)
            if result is not None:
                return result
        return None

    def _put(self, regs, start: int, name: str, values) -> None:
        a, c = self.map.fields()[name]
        regs[a - start : a - start + c] = list(values)[:c]

    def _refresh(self, regs, start: int, *, stale: bool) -> None:
        m = self.map
        s = self.cell.robot_state()
        bits = m.bits
        status = (
            (s.in_position << bits.in_position)
            | (s.moving << bits.busy)
            | (s.fault << bits.fault)
            | (s.protective_stop << bits.protective_stop)
            | (s.emergency_stop << bits.emergency_stop)
            | (s.steady << bits.steady)
        )
        if not stale:
            self._heartbeat = (self._heartbeat + 1) % 65536
        err = s.error_code or self._error_code
        q = np.zeros(m.n_joints)
        q[: self.cell.n_joints] = s.q
        self._put(regs, start, "status", [int(status)])
        self._put(regs, start, "error_code", [int(err)])
        self._put(regs, start, "heartbeat", [self._heartbeat])
        self._put(regs, start, "command_ack", [self._ack])
        self._put(regs, start, "joint_count", [self.cell.n_joints])
        self._put(regs, start, "actual_joints", m.pack_floats(q))
        self._put(regs, start, "actual_tcp", m.pack_floats(s.tcp))
        if m.joint_temps is not None and s.joint_temp is not None:
            temps = np.zeros(m.n_joints)
            temps[: self.cell.n_joints] = s.joint_temp
            self._put(regs, start, "joint_temps", m.pack_temps(temps))

    def _execute(self, image, start: int):
        """Run the command in ``image`` (the registers after this write); ExcCodes or None."""
        m = self.map
        f = m.fields()

        def get(name):
            a, c = f[name]
            return image[a - start : a - start + c]

        code, seq = get("command")[0], get("command_seq")[0]
        speed = float(m.unpack_floats(get("speed"))[0])
        self._error_code = 0
        try:
            if code == CMD_NONE:
                return None
            if code in (CMD_MOVE_JOINTS, CMD_MOVE_LINEAR) and self.faults.fires("pstop"):
                self.cell.trigger_protective_stop()
            if code == CMD_MOVE_JOINTS:
                q = m.unpack_floats(get("target_joints"))[: self.cell.n_joints]
                self.cell.command_move_joints(q, speed)
            elif code == CMD_MOVE_LINEAR:
                self.cell.command_move_linear(m.unpack_floats(get("target_xyz")), speed)
            elif code == CMD_STOP:
                self.cell.command_stop()
            elif code == CMD_CLEAR_FAULT:
                self.cell.clear_protective_stop()
            else:
                self._error_code = ERR_BAD_COMMAND
                return ExcCodes.ILLEGAL_VALUE
        except CellRefused as e:
            self._error_code = ROBOT_ERROR_CODES.get(e.name, ERR_BAD_ARGUMENT)
            if e.name in ("PROTECTIVE_STOP", "EMERGENCY_STOP", "FAULT"):
                self._ack = seq  # accepted, refused by the robot's state: see error_code
                return None
            return ExcCodes.ILLEGAL_VALUE
        self._ack = seq
        return None
