"""Physical (non-geometric) effects: what a geometric model leaves behind.

Each joint effect corrects one joint's angle per pose, θ_true = θ_reported + Δθ;
``thermal`` grows every link length; ``tracker_scale`` scales the instrument's
readings. Every ``delta`` returns exact partial derivatives (the corrections are
linear in their parameters), so the error model's Jacobian stays analytic.
"""

from __future__ import annotations

from dataclasses import replace
from typing import Any

import numpy as np

from ..data.dataset import Dataset
from ..model.gravity import gravity_torques, has_mass_model
from ..model.robot_model import RobotModel
from .base import Effect, EffectError, JointEffect

# typical sizes at the tool of a hidden effect when simulating: 0.05-0.5 mm
_TOOL_ERROR_MM = (0.08, 0.3)
_REACH_MM = 1000.0


def _angle_for_tool_error(rng: np.random.Generator) -> float:
    """A joint error (rad) that moves the tool by a realistic amount."""
    return float(rng.uniform(*_TOOL_ERROR_MM) / _REACH_MM * rng.choice([-1.0, 1.0]))


def derive_directions(q: np.ndarray) -> np.ndarray:
    """Approach direction of every joint from consecutive poses in capture order, (n, N);
    the first pose gets 0 (unknown)."""
    d = np.zeros(q.shape, int)
    d[1:] = np.sign(np.diff(q, axis=0)).astype(int)
    return d


class Compliance(JointEffect):
    """Joint deflection under gravity: Δθ_J = c · τ_J(q), with τ_J the gravity torque on
    joint J from the model's mass model (links + payload; the ``payload_kg`` column
    overrides the payload mass per pose). ``c`` in rad/(N·m): the inverse joint stiffness
    (harmonic drives: 1e-6 to 1e-5 rad/(N·m))."""

    family = "compliance"
    summary = "joint deflection proportional to the gravity torque on that joint"

    def __init__(self, model: RobotModel, joint: int | None = None,
                 order: int | None = None) -> None:
        super().__init__(model, joint, order)
        if not has_mass_model(model):
            raise EffectError(
                f"effect {self.label} needs a mass model: model {model.name} has no "
                "`links:` or `payload:` (see docs/formats.md §2)"
            )
        self.param_names = ["c"]
        self.units = ["rad/(N*m)"]
        self.scales = np.array([1e-6])

    def bind(self, data: Dataset, nominal: Any) -> np.ndarray:
        return gravity_torques(self.model, nominal, data.payload_kg)[:, self.joint - 1]

    def delta(self, p: np.ndarray, data: Dataset, tau: np.ndarray
              ) -> tuple[np.ndarray, np.ndarray]:
        return p[0] * tau, tau[:, None]

    def typical(self, rng: np.random.Generator) -> np.ndarray:
        # a joint carrying ~50 N·m, deflected by a realistic angle
        return np.array([abs(_angle_for_tool_error(rng)) / 50.0])


class Harmonic(JointEffect):
    """Periodic joint error (gear meshing, encoder poles, eccentricity):
    Δθ_J = a · sin(Kθ_J) + b · cos(Kθ_J), θ_J the reported joint angle, K cycles per turn
    (``harmonic:J`` is K = 1, ``harmonicK:J`` order K). ``a``, ``b`` in rad."""

    family = "harmonic"
    takes_order = True
    order: int  # 1 when the family is named without one
    summary = "periodic joint error a·sin(Kθ) + b·cos(Kθ) (gears, encoders)"

    def __init__(self, model: RobotModel, joint: int | None = None,
                 order: int | None = None) -> None:
        super().__init__(model, joint, order)
        self.order = 1 if order is None else int(order)
        if not 1 <= self.order <= 1000:
            raise EffectError(f"harmonic order must be 1..1000, got {self.order}")
        self.param_names = ["a", "b"]
        self.units = ["rad", "rad"]
        self.scales = np.array([1e-5, 1e-5])

    def bind(self, data: Dataset, nominal: Any) -> np.ndarray:
        k_theta = self.order * data.q[:, self.joint - 1]
        return np.column_stack([np.sin(k_theta), np.cos(k_theta)])

    def delta(self, p: np.ndarray, data: Dataset, basis: np.ndarray
              ) -> tuple[np.ndarray, np.ndarray]:
        return basis @ p, basis

    def typical(self, rng: np.random.Generator) -> np.ndarray:
        amp = abs(_angle_for_tool_error(rng))
        phase = rng.uniform(0, 2 * np.pi)
        return np.array([amp * np.cos(phase), amp * np.sin(phase)])


class Scale(JointEffect):
    """Joint angle scale error (gear ratio, encoder resolution): Δθ_J = s · θ_J,
    θ_J the reported angle (rad); ``s`` dimensionless."""

    family = "scale"
    summary = "joint angle scale error (gear ratio)"

    def __init__(self, model: RobotModel, joint: int | None = None,
                 order: int | None = None) -> None:
        super().__init__(model, joint, order)
        self.param_names = ["s"]
        self.units = ["1"]
        self.scales = np.array([1e-4])

    def bind(self, data: Dataset, nominal: Any) -> np.ndarray:
        return data.q[:, self.joint - 1].copy()

    def delta(self, p: np.ndarray, data: Dataset, theta: np.ndarray
              ) -> tuple[np.ndarray, np.ndarray]:
        return p[0] * theta, theta[:, None]

    def typical(self, rng: np.random.Generator) -> np.ndarray:
        return np.array([_angle_for_tool_error(rng) / 1.5])


class Backlash(JointEffect):
    """Lost motion in the drive: Δθ_J = b · dir_J, with dir_J = -1, 0, +1 the direction
    in which joint J approached the pose (``dirJ`` columns). Without them, the direction
    is derived from consecutive rows in capture order (file order), and a note says so.
    ``b`` in rad (half the backlash)."""

    family = "backlash"
    summary = "constant joint error whose sign follows the approach direction"

    def __init__(self, model: RobotModel, joint: int | None = None,
                 order: int | None = None) -> None:
        super().__init__(model, joint, order)
        self.param_names = ["b"]
        self.units = ["rad"]
        self.scales = np.array([1e-5])

    def prepare(self, data: Dataset) -> Dataset:
        if data.dirs is not None:
            return data
        return replace(
            data,
            dirs=derive_directions(data.q),
            meta={**data.meta, "dirs_derived": "consecutive rows in capture order"},
        )

    def bind(self, data: Dataset, nominal: Any) -> tuple[np.ndarray, bool]:
        derived = data.dirs is None or "dirs_derived" in data.meta
        dirs = derive_directions(data.q) if data.dirs is None else data.dirs
        return dirs[:, self.joint - 1].astype(float), derived

    def describe(self, state: tuple[np.ndarray, bool]) -> list[str]:
        if state[1]:
            return [
                f"{self.label}: the data have no dir columns; approach directions were "
                "derived from consecutive rows in capture order"
            ]
        return []

    def delta(self, p: np.ndarray, data: Dataset, state: tuple[np.ndarray, bool]
              ) -> tuple[np.ndarray, np.ndarray]:
        direction = state[0]
        return p[0] * direction, direction[:, None]

    def typical(self, rng: np.random.Generator) -> np.ndarray:
        return np.array([abs(_angle_for_tool_error(rng))])


class Coupling(JointEffect):
    """Joint error proportional to the previous joint's angle (wrist coupling, cable wind-up):
    Δθ_J = k · θ_{J-1}; ``k`` dimensionless. Needs J >= 2."""

    family = "coupling"
    summary = "joint error proportional to the previous joint's angle"

    def __init__(self, model: RobotModel, joint: int | None = None,
                 order: int | None = None) -> None:
        super().__init__(model, joint, order)
        if self.joint < 2:
            raise EffectError("coupling:J needs J >= 2 (it couples joint J to joint J-1)")
        self.param_names = ["k"]
        self.units = ["1"]
        self.scales = np.array([1e-4])

    def bind(self, data: Dataset, nominal: Any) -> np.ndarray:
        return data.q[:, self.joint - 2].copy()

    def delta(self, p: np.ndarray, data: Dataset, prev: np.ndarray
              ) -> tuple[np.ndarray, np.ndarray]:
        return p[0] * prev, prev[:, None]

    def typical(self, rng: np.random.Generator) -> np.ndarray:
        return np.array([_angle_for_tool_error(rng) / 1.5])


class Thermal(Effect):
    """Thermal growth: every link length (d, a) and the tool grow by k · (T - T_ref), with
    T the ``temp_c`` column and T_ref the ``temp_ref_c`` metadata (default 20 °C).
    ``k`` in 1/K (steel 11.5e-6, aluminium 23e-6)."""

    family = "thermal"
    stage = "length"
    summary = "all link lengths grow in proportion to temp_c - reference"

    def __init__(self, model: RobotModel, joint: int | None = None,
                 order: int | None = None) -> None:
        super().__init__(model, joint, order)
        self.param_names = ["k"]
        self.units = ["1/K"]
        self.scales = np.array([1e-5])

    def bind(self, data: Dataset, nominal: Any) -> np.ndarray:
        if data.temp_c is None:
            raise EffectError(f"{data.source}: effect thermal needs a temp_c column")
        t_ref = float(data.meta.get("temp_ref_c", 20.0))
        return data.temp_c - t_ref

    def length_scale(self, p: np.ndarray, data: Dataset, dT: np.ndarray
                     ) -> tuple[np.ndarray, np.ndarray]:
        return p[0] * dT, dT[:, None]

    def typical(self, rng: np.random.Generator) -> np.ndarray:
        return np.array([rng.uniform(10e-6, 25e-6)])


class TrackerScale(Effect):
    """Length scale error of the measuring instrument about its own origin:
    P_measured = (1 + s) · P; ``s`` dimensionless. With free geometric lengths and base
    it is exactly redundant (a uniformly larger robot further away looks the same), so it
    is only identifiable where the robot's lengths are known."""

    family = "tracker_scale"
    stage = "measure"
    summary = "length scale error of the measuring instrument"

    def __init__(self, model: RobotModel, joint: int | None = None,
                 order: int | None = None) -> None:
        super().__init__(model, joint, order)
        self.param_names = ["s"]
        self.units = ["1"]
        self.scales = np.array([1e-5])

    def measure(self, p: np.ndarray, P: np.ndarray) -> tuple[np.ndarray, float, np.ndarray]:
        return (1.0 + p[0]) * P, 1.0 + p[0], P[:, :, None].copy()

    def typical(self, rng: np.random.Generator) -> np.ndarray:
        return np.array([rng.choice([-1, 1]) * rng.uniform(2e-5, 8e-5)])


PHYSICAL = {
    cls.family: cls
    for cls in (Compliance, Harmonic, Scale, Backlash, Coupling, Thermal, TrackerScale)
}
