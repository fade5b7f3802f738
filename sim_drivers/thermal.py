"""The simulated robot warms up: joint temperatures driven by motion, on the cell's clock.

Each joint is a first-order thermal system: its temperature T_J relaxes towards
``ambient + rise_J · h_J`` with time constant ``tau_J`` (tens of minutes), where the heat
input ``h_J`` is ``rest`` while the arm stands powered (holding torque) and grows with the
joint's speed while it moves (``h = rest + (1 - rest) · min(|q̇_J| / ref_speed, 1.5)``).
Inputs are piecewise constant (one per move), so the temperatures are integrated exactly,
lazily, on the simulated clock: under ``time_scale`` < 1 the robot warms up faster in wall
time, as everything else in the cell does.

What the temperatures do to the robot is the true robot's business: with the thermal
model on, :meth:`~sim_drivers.model_truth.ModelTruth.with_thermal` adds the hidden effects
:data:`THERMAL_EFFECTS` (links that grow with the joints' mean temperature rise, joint zeros
that move with each joint's own), fed by :attr:`~sim_drivers.truth.PoseContext.joint_temp`.

Off unless asked for (``thermal="cold"`` or ``"warm"`` on :class:`~sim_drivers.cell.SimCell`,
``sim://robot?...&thermal=cold``, ``ServeConfig(thermal=...)``): without it nothing drifts,
and the controllers report the air's temperature for every joint, constant, over every wire
(RTDE, Modbus, the line protocol, in process), as a real UR reports its joints'
temperatures whether or not they change; ``SimCell(joint_temps=False)`` is a controller
that reports none.
"""

from __future__ import annotations

import numpy as np

from calibration.fit.simulate import WARM_RISE_K, WARMUP_TAU_S, per_joint

#: the thermal starts a simulated cell knows: from cold (at the air's temperature), or warm
#: (at the equilibrium of a capture's typical work)
STARTS = ("cold", "warm")
#: heat input of a powered robot standing still, as a fraction of working heat: the drives'
#: electronics and holding currents warm a robot that only stands powered on
REST_HEAT = 0.6
#: joint speed (rad/s) at which a joint heats as it does at work
REF_SPEED_RAD_S = 0.5
#: the heat input a capture's alternation of moves and measurements averages to (warm start)
WORKING_HEAT = 0.7


def thermal_effects(n_joints: int) -> list[str]:
    """The hidden effects of a warming robot: link growth and every joint's zero drift."""
    return ["thermal_growth"] + [f"thermal_zero:{j}" for j in range(1, n_joints + 1)]


class JointThermal:
    """Joint temperatures (°C) of a simulated robot over simulated time (s).

    Parameters
    ----------
    n_joints : number of joints
    start : "cold" (every joint at ``ambient_c``) or "warm" (at the equilibrium of
        :data:`WORKING_HEAT`)
    ambient_c : the air's temperature, °C
    rise_k, tau_s : per joint, the equilibrium rise at working heat (K) and the time
        constant (s); six-joint defaults from :mod:`calibration.fit.simulate`
    """

    def __init__(self, n_joints: int, start: str = "cold", *, ambient_c: float = 20.0,
                 rise_k=WARM_RISE_K, tau_s=WARMUP_TAU_S) -> None:
        if start not in STARTS:
            raise ValueError(f"thermal start {start!r}: expected one of {', '.join(STARTS)}")
        self.n_joints = int(n_joints)
        self.start = start
        self.ambient_c = float(ambient_c)
        self.rise = per_joint(rise_k, self.n_joints)
        self.tau = per_joint(tau_s, self.n_joints)
        heat = WORKING_HEAT if start == "warm" else 0.0
        self._T = self.ambient_c + self.rise * heat
        self._t = 0.0
        #: the move under way: (start s, end s, heat per joint), then the robot rests
        self._move: tuple[float, float, np.ndarray] | None = None

    def _relax(self, T: np.ndarray, heat, dt: float) -> np.ndarray:
        if dt <= 0:
            return T
        target = self.ambient_c + self.rise * heat
        return target + (T - target) * np.exp(-dt / self.tau)

    def _advance(self, T: np.ndarray, t_from: float, t_to: float) -> np.ndarray:
        """Temperatures at ``t_to`` from ``T`` at ``t_from`` (the move, then rest)."""
        if self._move is not None:
            m0, m1, heat = self._move
            a, b = max(t_from, m0), min(t_to, m1)
            if b > a:
                T = self._relax(T, REST_HEAT, a - t_from)
                T = self._relax(T, heat, b - a)
                t_from = b
        return self._relax(T, REST_HEAT, t_to - t_from)

    def at(self, t_s: float) -> np.ndarray:
        """Every joint's temperature at simulated time ``t_s`` (°C); a time before the last
        event gives the temperatures then."""
        return self._advance(self._T.copy(), self._t, max(float(t_s), self._t))

    def _settle_to(self, t_s: float) -> None:
        t = max(float(t_s), self._t)
        self._T, self._t = self._advance(self._T, self._t, t), t

    def moved(self, t0_s: float, t1_s: float, speeds_rad_s: np.ndarray) -> None:
        """A move from ``t0_s`` to ``t1_s`` at these joint speeds (rad/s, per joint)."""
        self._settle_to(t0_s)
        pace = np.minimum(np.abs(np.asarray(speeds_rad_s, float)) / REF_SPEED_RAD_S, 1.5)
        self._move = (float(t0_s), float(t1_s), REST_HEAT + (1.0 - REST_HEAT) * pace)

    def stopped(self, t_s: float) -> None:
        """The move under way ends at ``t_s`` (a stop)."""
        self._settle_to(t_s)
        self._move = None


def thermal_model(spec: str | None, n_joints: int, ambient_c: float = 20.0
                  ) -> JointThermal | None:
    """A :class:`JointThermal` from a start name ("cold", "warm"); None for none ("" too)."""
    if not spec:
        return None
    return JointThermal(n_joints, spec.strip().lower(), ambient_c=ambient_c)
