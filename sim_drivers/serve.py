"""Run the whole simulated cell behind its wire protocols (``cellcal sim serve``).

:class:`SimStack` builds one :class:`~sim_drivers.cell.SimCell` and serves it as
a Modbus TCP robot, a line-protocol robot over TCP, the line-protocol
tracker over TCP and over a pty, and an emScon (Leica TPI) tracker over TCP (and, when
asked, as an ABB IRC5 over Robot Web Services: ``abb``), all on loopback, on the
configured ports (:data:`DEFAULT_PORTS`, or :func:`ports_from_base`): a port in use is an
error (:class:`PortInUse`) unless the configuration allows any port (``any_port``: a free
one instead); port 0 is any free port.

The truth is one parameter: ``truth_factory(seed, hidden) -> TrueRobot``
(default :func:`sim_drivers.inprocess.default_truth`, a ``ToyArm``).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

from sim_drivers.cell import SimCell
from sim_drivers.emscon_server import EmsconServer
from sim_drivers.faults import FaultInjector
from sim_drivers.inprocess import default_truth, with_thermal
from sim_drivers.modbus_server import ModbusRobotServer
from sim_drivers.robot_server import RobotLineServer
from sim_drivers.rtde_server import PortUnavailable, RtdeSimServer
from sim_drivers.rws_server import RwsServer
from sim_drivers.tracker_server import TrackerServer
from sim_drivers.truth import TrueRobot

#: preferred ports: Modbus robot, line robot, line tracker, emScon tracker (a real
#: emScon server listens on 700, a privileged port)
DEFAULT_PORTS = {"modbus": 15020, "line_robot": 15021, "tracker": 15700, "emscon": 15701}
#: the ABB robot's (Robot Web Services; a real IRC5 listens on 80), served when asked: port
#: ``abb`` of :attr:`ServeConfig.ports` (absent from ports a caller gives: any free port)
ABB_PORT = 15080

#: what each port serves, for messages
PORT_NAMES = {"modbus": "Modbus robot", "line_robot": "line-protocol robot",
              "tracker": "line-protocol tracker", "emscon": "emScon tracker",
              "abb": "ABB robot (RWS)"}


class PortInUse(ValueError):
    """A configured port is taken (another ``cellcal sim serve``, another program)."""


def ports_from_base(base: int) -> dict[str, int]:
    """Ports ``base`` .. ``base + 3``: Modbus robot, line robot, line tracker, emScon (the
    ABB robot, when served, takes ``base + 4``)."""
    return {name: base + k for k, name in enumerate(DEFAULT_PORTS)}


@dataclass
class ServeConfig:
    """What ``cellcal sim serve`` runs.

    ``hidden`` is passed to the truth factory unchanged; ``faults`` is a fault
    spec (:mod:`sim_drivers.faults`); ports of 0 mean "any free port"; ``any_port``: a
    port in use is replaced by a free one (else :class:`PortInUse`); ``thermal`` ("cold",
    "warm", None) gives the robot joint temperatures and their hidden effects
    (:mod:`sim_drivers.thermal`); ``abb``: also serve the robot as an ABB IRC5 over Robot
    Web Services (:mod:`sim_drivers.rws_server`), its URL after the others'.
    """

    seed: int = 0
    hidden: str | None = None
    faults: str | None = None
    time_scale: float = 0.0
    host: str = "127.0.0.1"
    ports: dict[str, int] = field(default_factory=lambda: {**DEFAULT_PORTS, "abb": ABB_PORT})
    pty: bool = True
    any_port: bool = False
    #: also serve RTDE (receive side) on the fixed port 30004 of ``host``, when it is free
    rtde: bool = False
    thermal: str | None = None
    abb: bool = False


class SimStack:
    """Every simulated server for one cell; ``start()``/``stop()`` or ``with``.

    Parameters
    ----------
    config : ServeConfig
    truth_factory : callable(seed, hidden) -> TrueRobot
    cell_kw : dict
        Extra :class:`SimCell` arguments.
    """

    def __init__(
        self,
        config: ServeConfig | None = None,
        *,
        truth_factory: Callable[[int, str | None], TrueRobot] = default_truth,
        **cell_kw,
    ) -> None:
        self.config = config or ServeConfig()
        c = self.config
        self.faults = FaultInjector(c.faults, seed=c.seed)  # parses: ValueError on a bad spec
        truth = truth_factory(c.seed, c.hidden)
        if c.thermal:
            truth = with_thermal(truth, c.seed)
            cell_kw = {"thermal": c.thermal, **cell_kw}
        self.cell = SimCell(
            truth,
            seed=c.seed,
            time_scale=c.time_scale,
            faults=self.faults,
            **cell_kw,
        )
        self.servers: list = []
        #: what could not be served (said by ``cellcal sim serve`` on stderr)
        self.notes: list[str] = []

    def _start_one(self, make, service: str):
        port = self.config.ports.get(service, 0)
        try:
            return make(port).start()
        except OSError as e:
            if port == 0:
                raise
            if not self.config.any_port:
                raise PortInUse(f"port {port} ({PORT_NAMES[service]}) on "
                                f"{self.config.host} is in use: another `cellcal sim serve`? "
                                "Choose other ports (--port-base N) or allow any free port "
                                "(--any-port)") from e
            return make(0).start()

    def start(self) -> SimStack:
        """Start every server on its configured port (:class:`PortInUse` when one is taken,
        unless ``any_port``)."""
        c, cell, f = self.config, self.cell, self.faults
        try:
            self.servers.append(
                self._start_one(
                    lambda p: ModbusRobotServer(cell, faults=f, host=c.host, port=p),
                    "modbus",
                )
            )
            self.servers.append(
                self._start_one(
                    lambda p: RobotLineServer(cell, faults=f, host=c.host, port=p),
                    "line_robot",
                )
            )
            self.servers.append(
                self._start_one(
                    lambda p: TrackerServer(cell, faults=f, host=c.host, port=p),
                    "tracker",
                )
            )
            if c.pty:
                self.servers.append(TrackerServer(cell, faults=f, transport="pty").start())
            self.servers.append(
                self._start_one(
                    lambda p: EmsconServer(cell, faults=f, host=c.host, port=p),
                    "emscon",
                )
            )
            if c.abb:
                self.servers.append(
                    self._start_one(
                        lambda p: RwsServer(cell, faults=f, host=c.host, port=p), "abb"))
            if c.rtde:
                try:
                    self.servers.append(
                        RtdeSimServer(cell, host=c.host, fallback_hosts=()).start())
                except PortUnavailable as e:  # a real controller or another sim has it
                    self.notes.append(f"no RTDE server: {e}")
        except BaseException:
            self.stop()
            raise
        return self

    def stop(self) -> None:
        """Stop every server (reverse order)."""
        while self.servers:
            self.servers.pop().stop()

    def __enter__(self) -> SimStack:
        return self.start()

    def __exit__(self, *exc) -> None:
        self.stop()

    @property
    def urls(self) -> list[str]:
        """One driver URL per server, in start order. The RTDE server's ``ur://`` URL is
        read-only: moving a UR needs its script server, which the simulator does not have
        (in-process tests drive it with :class:`~sim_drivers.fake_rtde_control.FakeRTDEControl`)."""
        return [s.url + ("?read_only=1" if isinstance(s, RtdeSimServer) else "")
                for s in self.servers]
