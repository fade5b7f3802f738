"""The simulated cell: one true robot, its controller, a laser tracker, a clock.

:class:`SimCell` is the single source of truth behind every simulated server
(line robot, Modbus, RTDE, tracker) and the in-process ``sim://`` drivers.
Units: joints in rad, lengths in mm, times in s, temperatures in °C.

Time
    The cell keeps a *simulated* clock. A move lasts
    ``max|Δq| / speed + settle_s`` simulated seconds, a measurement
    ``duration_s``. Wall time = simulated time × ``time_scale``: with
    ``time_scale=0`` (the test default) everything is instantaneous and the
    simulated clock jumps; with ``time_scale>0`` the simulated clock follows the
    wall clock (``sim = wall / time_scale``). Readings carry wall-clock timestamps, except
    in a cell with a thermal model: there the robot's and the tracker's timestamps are on
    the simulated clock (the epoch at the cell's creation + simulated time), so a warm-up
    of tens of simulated minutes under a small ``time_scale`` spans tens of minutes in the
    data too, as the joint temperatures do.

Tracker
    Noise per axis ``σ(L) = 0.5·(0.015 mm + 0.006 mm/m · L)``, L the distance
    from the tracker origin (half the MPE ±(15 µm + 6 µm/m)). Range
    ``tracker_range_mm`` (default 800 mm – 30 m): outside it the tracker finds
    no target. Line of sight (:mod:`sim_drivers.beam`, always on when the true
    robot has the geometry, as :class:`~sim_drivers.model_truth.ModelTruth` does):
    the beam breaks when the SMR faces away from the tracker by more than the mounted
    reflector's acceptance half-angle, when it passes through one of the true robot's
    link capsules, or through a fixture of the cell (``cell``, boxes and cylinders
    in the robot base frame). Optional occlusions: spheres
    ``(centre_xyz_mm, radius_mm)`` in the tracker frame that break the beam too.
    Blunders (fault ``blunder``): a reading displaced by 0.5-5 mm, along the
    line of sight or in a random direction, drawn from the cell's own seeded generator;
    :attr:`SimCell.blunder_log` records which readings they were.

Tracker metrology
    Refraction: the tracker turns optical path into distance with the air it is
    given, read from its weather station (``weather_station=True``: the cell's
    true air, no error) or set by hand (:meth:`SimCell.set_tracker_environment`,
    used only without a station). Distances scale by ``n_true / n_used``
    (:func:`refractive_index`, the NIST shop-floor equation): 1 °C too warm
    reads ~0.93 µm/m long. Face: the head can measure in face 1 or 2
    (:meth:`SimCell.tracker_change_face`); a collimation error
    ``tracker_collimation_rad`` turns the point by ``+c`` about the vertical (z)
    axis in face 1 and ``-c`` in face 2, so the mean of both faces is free of
    it. Reflectors: :data:`TRACKER_REFLECTORS` (names and constants invented
    for the simulator); measuring with one selected that is not the mounted one
    shifts the distance by the difference of their distance constants.

Length: over 500 lines because the cell is one state machine (robot motion, tracker
metrology, line of sight, faults share one lock and one clock); the pure physics lives
in :mod:`sim_drivers.beam` and :mod:`sim_drivers.tracker_optics`.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from calibration.cell.cell import REFLECTOR_ACCEPTANCE_DEG, CellSpec
from calibration.fit.simulate import blunder_offsets
from sim_drivers.beam import BeamPhysics
from sim_drivers.refusals import CellRefused
from sim_drivers.six_dof import SixDofMeasuring, SixDofTarget
from sim_drivers.thermal import JointThermal, thermal_model
from sim_drivers.tracker_optics import TRACKER_REFLECTORS, SimReflector, tracker_reads
from sim_drivers.truth import PoseContext, TrueRobot


@dataclass(frozen=True)
class RobotState:
    """The simulated controller's view of the robot at one instant.

    ``q`` (rad, shape (n,)) are the reported joints, ``qd`` (rad/s) their
    velocity, ``tcp`` (mm, shape (3,)) the controller's nominal TCP in the base
    frame, ``timestamp`` epoch seconds (wall clock) and ``sim_time`` the
    simulated clock (s); ``joint_temp`` each joint's temperature (°C) as the controller
    reports it (the air's, constant, without a thermal model), None for a controller that
    reports none (``joint_temps=False``).
    """

    q: np.ndarray
    qd: np.ndarray
    tcp: np.ndarray
    moving: bool
    in_position: bool
    steady: bool
    protective_stop: bool
    emergency_stop: bool
    fault: bool
    error_code: int
    timestamp: float
    sim_time: float = 0.0
    joint_temp: np.ndarray | None = None


@dataclass(frozen=True)
class TrackerReading:
    """One simulated stationary measurement (mm, °C, hPa, %, epoch s)."""

    xyz: np.ndarray
    std: np.ndarray
    n: int
    temp_c: float
    pressure_hpa: float
    humidity_pct: float
    timestamp: float
    face: int = 1
    reflector: str = ""
    seq: int = 0


@dataclass(frozen=True)
class SimBlunder:
    """The truth about one blunder the simulated tracker returned.

    ``measurement`` is the cell's 1-based measurement count of that reading (``MEAS``
    replies over every server and the in-process driver, in order), ``true_xyz`` the
    target's true position (mm), ``offset_mm`` the displacement added on top of the
    noise, ``along_beam`` whether it lies along the line of sight, ``sim_time`` (s).
    """

    measurement: int
    true_xyz: np.ndarray
    offset_mm: np.ndarray
    along_beam: bool
    sim_time: float


#: error codes the controller reports (shared by every robot protocol)
ERROR_CODES = {
    "NONE": 0,
    "PROTECTIVE_STOP": 30,
    "EMERGENCY_STOP": 31,
    "FAULT": 32,
}


class SimCell(SixDofMeasuring):
    """A simulated robotic cell around a :class:`~sim_drivers.truth.TrueRobot`.

    Parameters
    ----------
    truth : TrueRobot
        The robot as it really is.
    seed : int
        Seed of every random draw in the cell.
    time_scale : float
        Wall seconds per simulated second; 0 makes motion and measurement
        instantaneous.
    faults : FaultInjector or None
        Shared with servers built on this cell (they consult it per command).
    q0 : array-like, shape (n,), optional
        Start joints (rad); default the middle of the limits.
    settle_s : float
        Settling time after each move (simulated s).
    joint_noise_rad : float
        σ of the per-joint arrival error (repeatability), rad.
    temp0_c, temp_drift_c_per_h : float
        Robot/air temperature at t=0 and its drift (°C per simulated hour).
    pressure_hpa, humidity_pct : float
        Environment reported by the tracker.
    tracker_range_mm : (float, float)
        Minimum and maximum tracker distance (mm).
    occlusions : sequence of (centre, radius)
        Spheres (mm, tracker frame) that block the line of sight.
    warmup_s : float
        Simulated seconds after start before the tracker is warmed up.
    tracker_initialised : bool
        Whether the tracker starts initialised.
    weather_station : bool
        Whether a weather station feeds the tracker the true air.
    tracker_collimation_rad : float
        The tracker's two-face (collimation) error, rad.
    reflector : str
        Name of the reflector mounted on the robot (and selected at start); its
        acceptance half-angle (:data:`calibration.cell.cell.REFLECTOR_ACCEPTANCE_DEG`) limits
        how far the SMR may face away from the tracker.
    cell : CellSpec, optional
        The cell's fixtures (base frame); its SMR's acceptance half-angle (its reflector
        type's, or ``acceptance_deg``) replaces the mounted reflector's.
    thermal : JointThermal or str, optional
        The robot's joint temperatures (:mod:`sim_drivers.thermal`): a model, or its start
        ("cold", "warm"); None (the default): they stay at the air's temperature
        (``temp0_c``), constant, as a real controller's at rest in a steady cell, and
        nothing drifts. The true robot's hidden thermal effects
        (``ModelTruth.with_thermal``) see them.
    joint_temps : bool
        Whether the controller reports its joints' temperatures (True, the default: a UR
        always does, and so does every simulated wire); False: a controller without them,
        whose requests for them are refused (a cell with a thermal model always has them).
    six_dof : SixDofTarget, optional
        A 6-DoF target (a T-Mac) on the tool (:mod:`sim_drivers.six_dof`): the tracker
        measures its pose too, and the line of sight uses its axis and acceptance cone.
        None (the default): an SMR, as before.
    """

    def __init__(
        self,
        truth: TrueRobot,
        *,
        seed: int = 0,
        time_scale: float = 0.0,
        faults=None,
        q0: Sequence[float] | None = None,
        settle_s: float = 0.5,
        joint_noise_rad: float = 1e-5,
        temp0_c: float = 20.0,
        temp_drift_c_per_h: float = 0.0,
        pressure_hpa: float = 1013.25,
        humidity_pct: float = 45.0,
        tracker_range_mm: tuple[float, float] = (800.0, 30000.0),
        occlusions: Sequence[tuple[Sequence[float], float]] = (),
        warmup_s: float = 0.0,
        tracker_initialised: bool = False,
        weather_station: bool = True,
        tracker_collimation_rad: float = 0.0,
        reflector: str = "RRR 1.5in",
        cell: CellSpec | None = None,
        thermal: JointThermal | str | None = None,
        six_dof: SixDofTarget | None = None,
        joint_temps: bool = True,
    ) -> None:
        if time_scale < 0:
            raise ValueError(f"time_scale must be >= 0, got {time_scale}")
        self.truth = truth
        self.seed = seed
        self.time_scale = float(time_scale)
        self.faults = faults
        self.settle_s = float(settle_s)
        self.joint_noise_rad = float(joint_noise_rad)
        self.temp0_c = float(temp0_c)
        self.temp_drift_c_per_h = float(temp_drift_c_per_h)
        self.pressure_hpa = float(pressure_hpa)
        self.humidity_pct = float(humidity_pct)
        self.tracker_range_mm = (float(tracker_range_mm[0]), float(tracker_range_mm[1]))
        self.occlusions = [(np.asarray(c, float), float(r)) for c, r in occlusions]
        self.warmup_s = float(warmup_s)
        #: the robot's joint temperatures (None: the cell has no thermal model)
        self.thermal = (thermal_model(thermal, truth.n_joints, self.temp0_c)
                        if isinstance(thermal, str) else thermal)
        #: the controller reports its joints' temperatures (with a thermal model: always)
        self.reports_joint_temps = bool(joint_temps) or self.thermal is not None
        self._rng = np.random.default_rng(seed)
        self._lock = threading.RLock()
        self._epoch0 = time.time()
        n = truth.n_joints
        limits = np.asarray(truth.limits, float)
        self._q = np.asarray(q0, float).copy() if q0 is not None else limits.mean(axis=1)
        if self._q.shape != (n,):
            raise ValueError(f"q0 must have shape ({n},), got {self._q.shape}")
        self._q_from = self._q.copy()
        self._q_to = self._q.copy()
        self._q_cmd = self._q.copy()
        self._t_start = 0.0
        self._t_move_end = 0.0
        self._t_settled = 0.0
        self._direction = np.zeros(n)
        self._pstop = False
        self._estop = False
        self._fault = False
        self._error_code = 0
        self._sim_t = 0.0
        self._wall0 = time.monotonic()
        self.tracker_initialised = bool(tracker_initialised)
        self.tracker_mode_ms = 500
        self.beam_ok = True
        self.weather_station = bool(weather_station)
        self.manual_environment = (20.0, 1013.25, 50.0)
        self.tracker_collimation_rad = float(tracker_collimation_rad)
        self.tracker_face = 1
        self.mounted_reflector = self.find_reflector(reflector)
        self.tracker_reflector = self.mounted_reflector
        #: the honest line of sight (None for a true robot without geometry, e.g. ToyArm)
        self.beam: BeamPhysics | None = None
        geometry = getattr(truth, "beam_geometry", None)
        if geometry is not None:
            model, tracker_T_base, smr_axis = geometry()
            acceptance = (cell.smr.half_angle_deg if cell is not None else
                          REFLECTOR_ACCEPTANCE_DEG.get(self.mounted_reflector.name, 30.0))
            if six_dof is not None:  # a T-Mac faces the tracker with its own axis and cone
                smr_axis, acceptance = six_dof.facing_axis, six_dof.acceptance_deg
            self.beam = BeamPhysics(model, tracker_T_base, smr_axis, acceptance, cell)
            if q0 is None:
                self._place(self._facing_start(model, tracker_T_base, smr_axis))
        self.n_moves = 0
        self.n_measurements = 0
        #: every blunder returned so far (fault ``blunder``), in measurement order
        self.blunder_log: list[SimBlunder] = []
        self._blunder_rng = np.random.default_rng([seed, 0xB1])
        self._last_meas_t = 0.0
        self._init_six_dof(six_dof, seed)

    # ------------------------------------------------------------------ clock
    @property
    def n_joints(self) -> int:
        """Number of joints of the simulated robot."""
        return int(self.truth.n_joints)

    @property
    def kinematics(self) -> str:
        """The robot model the simulated robot is built on (its truth's ``name``), or ""."""
        return str(getattr(self.truth, "name", ""))

    def serial(self, kind: str) -> str:
        """The serial number the simulated ``kind`` ("robot" or "tracker") reports: one per
        simulated cell (the robot model and the seed make its hidden truth)."""
        if kind == "robot":
            return f"SIM-{self.kinematics or 'robot'}-{self.seed}"
        return f"SIMTRK-{self.seed}"

    def now(self) -> float:
        """Simulated time (s)."""
        with self._lock:
            if self.time_scale > 0:
                return self._sim_t + (time.monotonic() - self._wall0) / self.time_scale
            return self._sim_t

    def stamp(self, t_s: float | None = None) -> float:
        """The timestamp (epoch s) of a reading at simulated time ``t_s`` (default now): the
        wall clock, or in a cell with a thermal model the simulated clock (module
        docstring)."""
        if self.thermal is None:
            return time.time()
        return self._epoch0 + (self.now() if t_s is None else t_s)

    def advance(self, dt_s: float) -> None:
        """Let ``dt_s`` simulated seconds pass (sleeps ``dt_s × time_scale`` wall s)."""
        if dt_s <= 0:
            return
        if self.time_scale > 0:
            time.sleep(dt_s * self.time_scale)
        else:
            with self._lock:
                self._sim_t += dt_s

    def temperature(self, t_s: float | None = None) -> float:
        """Cell temperature (°C) at simulated time ``t_s`` (default now)."""
        t = self.now() if t_s is None else t_s
        return self.temp0_c + self.temp_drift_c_per_h * t / 3600.0

    # ------------------------------------------------------------------ robot
    def _check_free(self) -> None:
        if self._estop:
            raise CellRefused("EMERGENCY_STOP", "emergency stop active")
        if self._pstop:
            raise CellRefused("PROTECTIVE_STOP", "protective stop active, clear it first")
        if self._fault:
            raise CellRefused("FAULT", f"controller fault {self._error_code}")

    def _current_q(self, t: float) -> np.ndarray:
        if t >= self._t_move_end or self._t_move_end <= self._t_start:
            return self._q_to.copy()
        f = (t - self._t_start) / (self._t_move_end - self._t_start)
        return self._q_from + f * (self._q_to - self._q_from)

    def command_move_joints(self, q: Sequence[float], speed: float) -> None:
        """Start a joint move to ``q`` (rad, shape (n,)) at ``speed`` (rad/s, fastest joint).

        Raises :class:`CellRefused` (``BAD_ARGUMENT``, ``LIMIT``, ``PROTECTIVE_STOP``...).
        """
        q = np.asarray(q, float)
        n = self.n_joints
        if q.shape != (n,) or not np.all(np.isfinite(q)):
            raise CellRefused("BAD_ARGUMENT", f"expected {n} finite joint values, got {q.tolist()}")
        if not (np.isfinite(speed) and speed > 0):
            raise CellRefused("BAD_ARGUMENT", f"speed must be > 0, got {speed}")
        lim = np.asarray(self.truth.limits, float)
        bad = np.nonzero((q < lim[:, 0]) | (q > lim[:, 1]))[0]
        if bad.size:
            raise CellRefused("LIMIT", f"joint(s) {(bad + 1).tolist()} outside limits")
        with self._lock:
            self._check_free()
            t = self.now()
            q_now = self._current_q(t)
            dq = q - q_now
            duration = float(np.max(np.abs(dq))) / speed if dq.size else 0.0
            arrive = q + self._rng.normal(0.0, self.joint_noise_rad, n)
            # approach direction from the commanded path (not the arrival noise)
            step = np.sign(np.where(np.abs(q - self._q_cmd) > 1e-9, q - self._q_cmd, 0.0))
            self._q_cmd = q.copy()
            self._direction = np.where(step != 0, step, self._direction)
            self._q_from, self._q_to = q_now, arrive
            self._t_start = t
            self._t_move_end = t + duration
            self._t_settled = self._t_move_end + self.settle_s
            if self.thermal is not None:
                self.thermal.moved(t, self._t_move_end, np.abs(dq) / duration if duration > 0
                                   else np.zeros(n))
            self.n_moves += 1
            if self.time_scale == 0:
                self._sim_t = self._t_settled

    def command_move_linear(self, xyz: Sequence[float], speed: float) -> None:
        """Move the nominal TCP to ``xyz`` (mm, base frame) at ``speed`` (mm/s).

        Solved with ``truth.nominal_ik`` nearest the current joints; the joint
        speed is chosen so the move takes ``|Δxyz| / speed``.
        """
        xyz = np.asarray(xyz, float)
        if xyz.shape != (3,) or not np.all(np.isfinite(xyz)):
            raise CellRefused("BAD_ARGUMENT", f"expected x y z, got {xyz.tolist()}")
        if not (np.isfinite(speed) and speed > 0):
            raise CellRefused("BAD_ARGUMENT", f"speed must be > 0, got {speed}")
        with self._lock:
            self._check_free()
            q_now = self._current_q(self.now())
            try:
                q = np.asarray(self.truth.nominal_ik(xyz, q_now), float)
            except ValueError as e:
                raise CellRefused("UNREACHABLE", str(e)) from e
            dist = float(np.linalg.norm(xyz - self.truth.nominal_tcp(q_now)))
            dq = float(np.max(np.abs(q - q_now))) if q.size else 0.0
            t_move = dist / speed
            joint_speed = dq / t_move if t_move > 0 and dq > 0 else 1.0
            self.command_move_joints(q, joint_speed)

    def command_stop(self) -> None:
        """Stop where the robot is now (the move ends immediately, then settles)."""
        with self._lock:
            t = self.now()
            q = self._current_q(t)
            self._q_from = self._q_to = q
            self._t_start = self._t_move_end = min(t, self._t_move_end)
            self._t_settled = self._t_move_end + (self.settle_s if t < self._t_settled else 0.0)
            if self.thermal is not None:
                self.thermal.stopped(self._t_move_end)

    def trigger_protective_stop(self) -> None:
        """Protective stop now (fault injection): motion halts, commands are refused."""
        with self._lock:
            self.command_stop()
            self._pstop = True
            self._error_code = ERROR_CODES["PROTECTIVE_STOP"]

    def clear_protective_stop(self) -> None:
        """Clear a protective stop or fault (as an operator would)."""
        with self._lock:
            self._pstop = False
            self._fault = False
            self._error_code = 0

    def robot_state(self) -> RobotState:
        """The controller's state now (see :class:`RobotState`)."""
        with self._lock:
            t = self.now()
            q = self._current_q(t)
            moving = t < self._t_move_end
            qd = (
                (self._q_to - self._q_from) / (self._t_move_end - self._t_start)
                if moving
                else np.zeros(self.n_joints)
            )
            steady = t >= self._t_settled
            return RobotState(
                q=q,
                qd=qd,
                tcp=np.asarray(self.truth.nominal_tcp(q), float),
                moving=moving,
                in_position=not moving and not self._pstop,
                steady=steady and not moving,
                protective_stop=self._pstop,
                emergency_stop=self._estop,
                fault=self._fault,
                error_code=self._error_code,
                timestamp=self.stamp(t),
                sim_time=t,
                joint_temp=self.joint_temperatures(t),
            )

    def pose_context(self) -> PoseContext:
        """What the hidden physics sees now: approach directions, temperature, time."""
        with self._lock:
            t = self.now()
            return PoseContext(direction=self._direction.copy(), temp_c=self.temperature(t), t_s=t,
                               joint_temp=self.joint_temperatures(t))

    def joint_temperatures(self, t_s: float | None = None) -> np.ndarray | None:
        """Each joint's temperature (°C) at simulated time ``t_s`` (default now): the
        thermal model's, else the air's (``temp0_c``), constant; None for a controller that
        reports none (``joint_temps=False``)."""
        if not self.reports_joint_temps:
            return None
        if self.thermal is None:
            return np.full(self.truth.n_joints, self.temp0_c)
        with self._lock:
            return self.thermal.at(self.now() if t_s is None else t_s)

    # ---------------------------------------------------------------- tracker
    def tracker_sigma(self, xyz: Sequence[float]) -> float:
        """Per-axis noise σ (mm) of a measurement at ``xyz`` (mm, tracker frame)."""
        dist_m = float(np.linalg.norm(np.asarray(xyz, float))) / 1000.0
        return 0.5 * (0.015 + 0.006 * dist_m)

    def true_point(self) -> np.ndarray:
        """The target's true position now (mm, tracker frame), noise-free."""
        with self._lock:
            q = self._current_q(self.now())
            return np.asarray(self.truth.true_point(q, self.pose_context()), float)

    def tracker_warmed_up(self) -> bool:
        """Whether the tracker's warm-up time has passed."""
        return self.now() >= self.warmup_s

    def beam_blocked(self) -> str | None:
        """Why the beam cannot reach the target now (facing, a link, a fixture, an occluding
        sphere), or None when the line of sight is clear."""
        with self._lock:
            q = self._current_q(self.now())
            p = np.asarray(self.truth.true_point(q, self.pose_context()), float)
            for c, r in self.occlusions:
                denom = float(p @ p)
                s = 0.0 if denom == 0 else float(np.clip((c @ p) / denom, 0.0, 1.0))
                if np.linalg.norm(c - s * p) < r:
                    return "an obstacle in the beam"
            return None if self.beam is None else self.beam.blocked(q, p)

    def _facing_start(self, model, tracker_T_base, smr_axis) -> np.ndarray:
        """Where the simulated robot stands when the cell starts: a posture whose SMR faces
        the tracker in the clear, as at a real cell, where the operator locks the beam on
        the SMR before a run (the middle of the limits when none is found)."""
        from calibration.cell.visibility import solve_facing

        T = np.asarray(tracker_T_base, float)
        tracker = -T[:3, :3].T @ T[:3, 3]
        az = np.arctan2(tracker[1], tracker[0])
        for radius, height, turn in ((800.0, 500.0, 0.0), (700.0, 700.0, 0.3),
                                     (900.0, 300.0, -0.3), (600.0, 600.0, 0.6)):
            p = np.array([[radius * np.cos(az + turn), radius * np.sin(az + turn), height]])
            q, ok = solve_facing(model, p, tracker[None] - p, np.zeros(1), self._q[None],
                                 smr_axis)
            if not ok[0]:
                continue
            keep = self._q.copy()
            self._place(q[0])
            blocked = self.beam_blocked()
            self._place(keep)
            if blocked is None:
                return q[0]
        return self._q

    def _place(self, q: np.ndarray) -> None:
        """Stand the robot still at ``q`` (rad) (before any motion)."""
        self._q = np.asarray(q, float).copy()
        self._q_from, self._q_to, self._q_cmd = self._q.copy(), self._q.copy(), self._q.copy()

    # ---------------------------------------------------- tracker metrology
    @staticmethod
    def find_reflector(name_or_id: str | int) -> SimReflector:
        """The reflector of :data:`TRACKER_REFLECTORS` with this name or id (KeyError)."""
        for r in TRACKER_REFLECTORS:
            if r.id == name_or_id or r.name == name_or_id:
                return r
        raise KeyError(f"no reflector {name_or_id!r}")

    def select_reflector(self, name_or_id: str | int) -> SimReflector:
        """Make the tracker measure with this reflector (CellRefused BAD_ARGUMENT if unknown)."""
        try:
            r = self.find_reflector(name_or_id)
        except KeyError as e:
            raise CellRefused("BAD_ARGUMENT", str(e)) from None
        with self._lock:
            self.tracker_reflector = r
        return r

    def tracker_environment(self) -> tuple[float, float, float, str]:
        """The air the tracker corrects with: (°C, hPa, %RH, "station" or "manual")."""
        with self._lock:
            if self.weather_station:
                return self.temperature(), self.pressure_hpa, self.humidity_pct, "station"
            return (*self.manual_environment, "manual")

    def set_tracker_environment(self, temp_c: float, pressure_hpa: float,
                                humidity_pct: float) -> None:
        """Set the air by hand (used while no weather station is connected)."""
        vals = (float(temp_c), float(pressure_hpa), float(humidity_pct))
        if not (np.all(np.isfinite(vals)) and -50 < vals[0] < 100 and 300 < vals[1] < 1300
                and 0 <= vals[2] <= 100):
            raise CellRefused("BAD_ARGUMENT", f"environment out of range: {vals}")
        with self._lock:
            self.manual_environment = vals

    def tracker_change_face(self, duration_s: float = 3.0) -> int:
        """Turn the head to the other face (takes ``duration_s`` simulated s); the new face."""
        with self._lock:
            if not self.tracker_initialised:
                raise CellRefused("NOT_INITIALISED", "send INIT first")
            self.tracker_face = 2 if self.tracker_face == 1 else 1
            face = self.tracker_face
        self.advance(duration_s)
        return face

    def _tracker_reads(self, p: np.ndarray) -> np.ndarray:
        """Where the tracker puts the true point ``p``: refraction, reflector, face."""
        t, pr, h, _ = self.tracker_environment()
        return tracker_reads(
            p, used_air=(t, pr, h),
            true_air=(self.temperature(), self.pressure_hpa, self.humidity_pct),
            constant_mm=self.mounted_reflector.constant_mm - self.tracker_reflector.constant_mm,
            collimation_rad=self.tracker_collimation_rad * (1 if self.tracker_face == 1 else -1),
        )

    def tracker_target_visible(self) -> bool:
        """Whether the beam can lock on the target now (beam fault, range, line of sight)."""
        with self._lock:
            p = self.true_point()
            lo, hi = self.tracker_range_mm
            return (self.beam_ok and lo <= float(np.linalg.norm(p)) <= hi
                    and self.beam_blocked() is None)

    def tracker_init(self) -> None:
        """Initialise the tracker (home, find the target)."""
        with self._lock:
            self.tracker_initialised = True

    def tracker_measure(self, duration_s: float = 0.5) -> TrackerReading:
        """Measure the stationary target for ``duration_s`` (simulated) seconds.

        Raises :class:`CellRefused` with ``NOT_INITIALISED``, ``NOT_WARMED_UP``,
        ``NOT_STABLE`` (robot moving), ``BEAM_BROKEN`` (occluded or beam fault),
        ``NO_TARGET`` (out of range).
        """
        if not (np.isfinite(duration_s) and duration_s > 0):
            raise CellRefused("BAD_ARGUMENT", f"duration must be > 0, got {duration_s}")
        with self._lock:
            if not self.tracker_initialised:
                raise CellRefused("NOT_INITIALISED", "send INIT first")
            if not self.tracker_warmed_up():
                raise CellRefused("NOT_WARMED_UP", f"warm-up ends at t={self.warmup_s:.0f} s")
            state = self.robot_state()
            if state.moving:
                raise CellRefused("NOT_STABLE", "target is moving")
            p = self.true_point()
            dist = float(np.linalg.norm(p))
            lo, hi = self.tracker_range_mm
            if not lo <= dist <= hi:
                raise CellRefused("NO_TARGET", f"target at {dist:.0f} mm, range {lo:.0f}-{hi:.0f}")
            if not self.beam_ok:
                raise CellRefused("BEAM_BROKEN", "line of sight blocked")
            blocked = self.beam_blocked()
            if blocked is not None:
                raise CellRefused("BEAM_BROKEN", blocked)
            sigma = self.tracker_sigma(p)
            n = max(1, int(round(duration_s * 1000.0)))
            xyz = self._tracker_reads(p) + self._rng.normal(0.0, sigma, 3)
            std = sigma * (1.0 + 0.05 * self._rng.standard_normal(3)).clip(0.5)
            temp_noise = 0.01 * float(self._rng.standard_normal())
            env_t, env_p, env_h, source = self.tracker_environment()
            temp = env_t + temp_noise if source == "station" else env_t
            face, reflector = self.tracker_face, self.tracker_reflector.name
            self.n_measurements += 1
            seq = self.n_measurements
            # the tracker's clock: later than any earlier measurement (µs steps)
            stamp = max(self.stamp(), self._last_meas_t + 1e-6)
            self._last_meas_t = stamp
            if self.faults is not None and self.faults.fires("blunder"):
                offset, along = blunder_offsets(p, self._blunder_rng)
                xyz = xyz + offset[0]
                self.blunder_log.append(SimBlunder(self.n_measurements, p.copy(), offset[0],
                                                   bool(along[0]), self.now()))
        self.advance(duration_s)
        return TrackerReading(
            xyz=xyz,
            std=std,
            n=n,
            temp_c=temp,
            pressure_hpa=env_p,
            humidity_pct=env_h,
            timestamp=stamp,
            face=face,
            reflector=reflector,
            seq=seq,
        )
