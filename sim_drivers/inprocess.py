"""In-process simulated drivers reachable by URL: ``sim://robot?model=ur10e&seed=1``,
``sim://tracker?seed=1``.

:func:`register` registers the ``sim`` scheme with :mod:`drivers.urls` (importing this
module does not: the application registers ``sim`` when it starts,
:mod:`cellcal.url_schemes`, and a test after unregistering it). Robot and
tracker URLs with the same ``seed`` and ``name`` share one
:class:`~sim_drivers.cell.SimCell`, so the tracker sees the robot move. Query
parameters used when the cell is first created: ``time_scale`` (default 0)
and ``faults`` (only ``beam``, ``pstop`` and ``blunder`` apply in process).

The simulated robot is the calibration-backed true robot of a model
(:class:`~sim_drivers.model_truth.ModelTruth`: the nominal model with realistic hidden
errors, ``hidden=`` effects): ``model=NAME|PATH`` is required where the cell is created
(a URL without it is refused: there is no default robot to mistake for the one meant);
a tracker URL may leave it out once its robot's cell exists. Other query parameters used
when the cell is first created: ``tool=X,Y,Z`` (the controller's TCP, mm, default the SMR
on a 60 mm holder), ``time_scale`` (default 0), ``faults`` (only ``beam``, ``pstop`` and
``blunder`` apply in process) and ``reflector`` (the mounted reflector's type, e.g. ``360``
for one with no facing limit; :data:`calibration.cell.cell.REFLECTOR_ACCEPTANCE_DEG`) and
``thermal=cold|warm`` (the robot warms up with its work, from cold or already warm, and its
joint zeros and links drift with the temperatures: :mod:`sim_drivers.thermal`; off by
default: the joints then report the air's temperature, constant, and nothing drifts).

The drivers identify themselves as simulators (:meth:`SimRobot.identify`).
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable
from urllib.parse import parse_qs, urlsplit

import numpy as np

from drivers import urls
from drivers.errors import CommandRejected, CommandTimeout, ConnectionLost
from drivers.line_robot import ROBOT_ERRORS
from drivers.line_tracker import TRACKER_ERRORS
from drivers.protocols import (
    DeviceIdentity,
    Environment,
    JointReading,
    Measurement,
    Readiness,
    Reflector,
    RobotStatus,
    TrackerStatus,
    measure_both_faces,
)
from drivers.settle import poll_until_settled, poll_until_still, settle_move
from sim_drivers.cell import CellRefused, SimCell
from sim_drivers.faults import FaultInjector
from sim_drivers.truth import ToyArm, TrueRobot


def default_truth(seed: int, hidden: str | None) -> TrueRobot:
    """The stand-in truth: a :class:`~sim_drivers.truth.ToyArm` (``hidden`` is ignored)."""
    return ToyArm()


#: builds the true robot of a new cell; replace to plug in another truth
truth_factory: Callable[[int, str | None], TrueRobot] = default_truth

_cells: dict[tuple[str, int], SimCell] = {}
_lock = threading.Lock()


def get_cell(name: str = "default", seed: int = 0, model: str | None = None,
             tool_mm=None, **kw) -> SimCell:
    """The shared cell for ``(name, seed)``, created with ``kw`` on first use.

    ``model`` (a model name or YAML path) makes its truth a
    :class:`~sim_drivers.model_truth.ModelTruth` of that model (``tool_mm`` the
    controller's TCP); without it :data:`truth_factory` builds it. ``thermal`` ("cold",
    "warm") gives the robot joint temperatures and their hidden effects. An existing cell
    of another model is a ValueError.
    """
    with _lock:
        key = (name, seed)
        if key not in _cells:
            hidden = kw.pop("hidden", None)
            spec = kw.pop("faults", None)
            if model is not None:
                from sim_drivers.model_truth import DEFAULT_TOOL_MM, ModelTruth

                truth = ModelTruth.from_spec(model, hidden, seed,
                                             DEFAULT_TOOL_MM if tool_mm is None else tool_mm)
            else:
                truth = truth_factory(seed, hidden)
            if kw.get("thermal"):
                truth = with_thermal(truth, seed)
            _cells[key] = SimCell(truth, seed=seed, faults=FaultInjector(spec, seed=seed), **kw)
        cell = _cells[key]
    if model is not None and cell.kinematics != _model_name(model):
        raise ValueError(f"simulated cell {name!r} (seed {seed}) moves a {cell.kinematics}, "
                         f"not a {model}")
    return cell


def with_thermal(truth: TrueRobot, seed: int) -> TrueRobot:
    """``truth`` with its hidden thermal effects (a ModelTruth's); ValueError for a truth
    that has none to add (the toy arm)."""
    if not hasattr(truth, "with_thermal"):
        raise ValueError(f"the simulated {getattr(truth, 'name', 'robot')} has no thermal "
                         "model (use a robot model, e.g. model=ur10e)")
    return truth.with_thermal(seed)


def _model_name(model: str) -> str:
    from calibration import load_model

    return load_model(model).name


def reset_cells() -> None:
    """Forget every shared cell (tests)."""
    with _lock:
        _cells.clear()


def _refused(e: CellRefused, device: str, command: str, table: dict) -> Exception:
    cls = table.get(e.name, CommandRejected)
    return cls(device, command, f"{e.name} {e.detail}".strip())


def _need_link(driver, command: str) -> None:
    """ConnectionLost "not connected" before ``connect`` and after ``close`` (as over a
    wire)."""
    if not driver.connected:
        raise ConnectionLost(driver._dev, command, "not connected")


class SimRobot:
    """RobotDriver (+ ``read_tcp``) acting directly on a :class:`SimCell`."""

    def __init__(self, url: str, cell: SimCell, poll_s: float = 0.005) -> None:
        self.url = url
        self.cell = cell
        self.poll_s = poll_s
        self.n_joints = cell.n_joints
        self.connected = False
        self._dev = f"robot {url}"

    def connect(self, timeout: float = 5.0) -> None:
        self.connected = True

    def close(self) -> None:
        self.connected = False

    def __enter__(self) -> SimRobot:
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def read_joints(self, timeout: float = 1.0) -> JointReading:
        """Reported joints (rad)."""
        _need_link(self, "read_joints")
        return JointReading(q=self.cell.robot_state().q, timestamp=time.time())

    def read_tcp(self, timeout: float = 1.0) -> np.ndarray:
        """Nominal TCP (mm, base frame)."""
        _need_link(self, "read_tcp")
        return self.cell.robot_state().tcp

    def joint_temperatures(self, timeout: float = 1.0) -> tuple[float, ...]:
        """Each joint's temperature (°C): the thermal model's, else the air's (constant);
        CommandRejected from a cell whose controller reports none."""
        _need_link(self, "joint_temperatures")
        temps = self.cell.joint_temperatures()
        if temps is None:
            raise CommandRejected(self._dev, "joint_temperatures",
                                  "the simulated robot reports no joint temperatures")
        return tuple(float(v) for v in temps)

    def status(self, timeout: float = 1.0) -> RobotStatus:
        _need_link(self, "status")
        s = self.cell.robot_state()
        return RobotStatus(
            connected=self.connected,
            moving=s.moving,
            in_position=s.in_position and s.steady,
            fault=s.fault,
            protective_stop=s.protective_stop,
            emergency_stop=s.emergency_stop,
            error_code=s.error_code,
            message=f"error code {s.error_code}" if s.error_code else "",
            timestamp=s.timestamp,
        )

    def _move(self, command: str, fn, timeout: float) -> None:
        deadline = time.monotonic() + timeout
        _need_link(self, command)
        faults = self.cell.faults
        if faults is not None and faults.fires("pstop"):
            self.cell.trigger_protective_stop()
        try:
            fn()
        except CellRefused as e:
            raise _refused(e, self._dev, command, ROBOT_ERRORS) from e
        settle_move(self.wait_settled, self.stop, self._dev, command, deadline)

    def move_joints(self, q, speed: float = 0.5, timeout: float = 60.0) -> None:
        """Joint move to ``q`` (rad) at ``speed`` rad/s; returns once settled."""
        q = np.asarray(q, float)
        self._move("move_joints", lambda: self.cell.command_move_joints(q, speed), timeout)

    def move_linear(self, xyz, speed: float = 100.0, timeout: float = 60.0) -> None:
        """Linear TCP move to ``xyz`` (mm) at ``speed`` mm/s; returns once settled."""
        xyz = np.asarray(xyz, float)
        self._move("move_linear", lambda: self.cell.command_move_linear(xyz, speed), timeout)

    def wait_settled(self, timeout: float = 30.0) -> None:
        poll_until_settled(self.status, self._dev, timeout, self.poll_s)

    def stop(self, timeout: float = 2.0) -> None:
        _need_link(self, "stop")
        self.cell.command_stop()
        poll_until_still(self.status, self._dev, "stop", time.monotonic() + timeout,
                         self.poll_s)

    def identify(self, timeout: float = 2.0) -> DeviceIdentity:
        """A simulator of the cell's robot model."""
        c = self.cell
        return DeviceIdentity("robot", "SIMBOT-inprocess", c.serial("robot"), "1.0.0",
                              simulator=True, kinematics=c.kinematics, n_joints=c.n_joints)

    def clear_protective_stop(self, timeout: float = 2.0) -> None:
        _need_link(self, "clear_protective_stop")
        self.cell.clear_protective_stop()


class SimTracker:
    """TrackerDriver acting directly on a :class:`SimCell` (initialises on connect), with
    the ready gate, environment, reflector and two-face capabilities."""

    def __init__(self, url: str, cell: SimCell) -> None:
        self.url = url
        self.cell = cell
        self.connected = False
        self._dev = f"tracker {url}"

    def connect(self, timeout: float = 5.0) -> None:
        self.cell.tracker_init()
        self.connected = True

    def close(self) -> None:
        self.connected = False

    def identify(self, timeout: float = 2.0) -> DeviceIdentity:
        """A simulated tracker."""
        return DeviceIdentity("tracker", "SIMTRACK-inprocess", self.cell.serial("tracker"),
                              "1.0.0", simulator=True)

    def __enter__(self) -> SimTracker:
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def status(self, timeout: float = 1.0) -> TrackerStatus:
        _need_link(self, "status")
        c = self.cell
        return TrackerStatus(
            connected=self.connected,
            initialised=c.tracker_initialised,
            warmed_up=c.tracker_warmed_up(),
            beam_ok=c.beam_ok,
            timestamp=time.time(),
        )

    def measure(self, duration_s: float = 0.5, timeout: float = 10.0) -> Measurement:
        """Measure the target (mm, tracker frame); CommandTimeout when the measurement
        would take longer than ``timeout`` at the cell's time scale."""
        _need_link(self, "measure")
        if duration_s * self.cell.time_scale > timeout:
            raise CommandTimeout(self._dev, "measure",
                                 f"a {duration_s} s measurement takes "
                                 f"{duration_s * self.cell.time_scale:.3g} s here, over the "
                                 f"{timeout} s timeout")
        faults = self.cell.faults
        try:
            if faults is not None and faults.fires("beam"):
                raise CellRefused("BEAM_BROKEN", "beam interrupted during measurement")
            r = self.cell.tracker_measure(duration_s)
        except CellRefused as e:
            raise _refused(e, self._dev, "measure", TRACKER_ERRORS) from e
        return Measurement(
            xyz=r.xyz,
            std=r.std,
            n=r.n,
            timestamp=r.timestamp,
            env={
                "temp_c": r.temp_c,
                "pressure_hpa": r.pressure_hpa,
                "humidity_pct": r.humidity_pct,
            },
            reflector=r.reflector,
            face=r.face,
        )

    def ready(self, timeout: float = 2.0) -> Readiness:
        _need_link(self, "ready")
        c = self.cell
        return Readiness.of(c.tracker_initialised, c.tracker_warmed_up(), c.weather_station,
                            c.tracker_target_visible())

    def check_ready(self, timeout: float = 2.0) -> Readiness:
        return self.ready(timeout).raise_if_not_ok(self._dev)

    def environment(self, timeout: float = 2.0) -> Environment:
        _need_link(self, "environment")
        return Environment(*self.cell.tracker_environment())

    def set_environment(self, temp_c, pressure_hpa, humidity_pct, timeout: float = 2.0) -> None:
        _need_link(self, "set_environment")
        try:
            self.cell.set_tracker_environment(temp_c, pressure_hpa, humidity_pct)
        except CellRefused as e:
            raise _refused(e, self._dev, "set_environment", TRACKER_ERRORS) from e

    def reflectors(self, timeout: float = 2.0) -> list[Reflector]:
        _need_link(self, "reflectors")
        from sim_drivers.tracker_optics import TRACKER_REFLECTORS

        return [Reflector(r.name, r.id, r.target_type, r.surface_offset_mm)
                for r in TRACKER_REFLECTORS]

    def reflector(self, timeout: float = 2.0) -> Reflector:
        _need_link(self, "reflector")
        r = self.cell.tracker_reflector
        return Reflector(r.name, r.id, r.target_type, r.surface_offset_mm)

    def set_reflector(self, name: str, timeout: float = 2.0) -> Reflector:
        _need_link(self, "set_reflector")
        try:
            self.cell.select_reflector(name)
        except CellRefused as e:
            raise _refused(e, self._dev, "set_reflector", TRACKER_ERRORS) from e
        return self.reflector()

    def face(self, timeout: float = 2.0) -> int:
        _need_link(self, "face")
        return self.cell.tracker_face

    def change_face(self, timeout: float = 30.0) -> int:
        _need_link(self, "change_face")
        try:
            return self.cell.tracker_change_face()
        except CellRefused as e:
            raise _refused(e, self._dev, "change_face", TRACKER_ERRORS) from e

    def measure_faces(self, duration_s: float = 0.5, timeout: float = 60.0):
        return measure_both_faces(self, duration_s, timeout)


def open_sim(url: str, kind: str, **kw):
    """Factory registered for ``sim://``: ``sim://robot?...`` or ``sim://tracker?...``."""
    parts = urlsplit(url)
    what = parts.netloc or parts.path.strip("/")
    if what not in ("robot", "tracker"):
        raise ValueError(f"bad URL {url!r}: expected sim://robot?... or sim://tracker?...")
    if what != kind:
        raise ValueError(f"bad URL {url!r}: a {what} URL where a {kind} is wanted")
    q = {k: v[-1] for k, v in parse_qs(parts.query, keep_blank_values=True).items()}
    unknown = set(q) - {"seed", "name", "time_scale", "faults", "hidden", "model", "tool",
                        "reflector", "thermal"}
    if unknown:
        raise ValueError(f"bad URL {url!r}: unknown parameter(s) {sorted(unknown)}")
    try:
        seed = int(q.get("seed", "0"))
        time_scale = float(q.get("time_scale", "0"))
        tool = None if "tool" not in q else [float(v) for v in q["tool"].split(",")]
    except ValueError as e:
        raise ValueError(f"bad URL {url!r}: {e}") from None
    if tool is not None and (len(tool) != 3 or not np.all(np.isfinite(tool))):
        raise ValueError(f"bad URL {url!r}: tool=X,Y,Z takes 3 finite numbers (mm)")
    name, model = q.get("name", "default"), q.get("model") or None
    with _lock:
        exists = (name, seed) in _cells
    if model is None and not exists:
        raise ValueError(f"bad URL {url!r}: a simulated cell needs model=NAME|PATH (the robot "
                         f"model it moves), e.g. sim://robot?model=ur10e&seed={seed}")
    extra = {}
    if q.get("thermal"):
        from sim_drivers.thermal import STARTS

        if q["thermal"] not in STARTS:
            raise ValueError(f"bad URL {url!r}: thermal={q['thermal']}: expected "
                             f"{' or '.join(STARTS)}")
        extra["thermal"] = q["thermal"]
    if q.get("reflector"):
        from calibration.cell.cell import CellSpec, Smr

        extra["cell"] = CellSpec(smr=Smr(reflector=q["reflector"]))
    try:
        cell = get_cell(name, seed, model, tool, time_scale=time_scale, faults=q.get("faults"),
                        hidden=q.get("hidden"), **extra)
    except (ValueError, OSError) as e:  # unknown model, bad hidden effects, another model
        raise ValueError(f"bad URL {url!r}: {e}") from None
    return SimRobot(url, cell, **kw) if kind == "robot" else SimTracker(url, cell, **kw)


def register() -> None:
    """Register the ``sim`` URL scheme with :mod:`drivers.urls`."""
    urls.register_scheme("sim", open_sim)
