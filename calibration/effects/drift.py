"""Drift effects: what changes while the robot warms up (or the cell moves) during a capture.

A robot is not the same machine cold and warm: its links grow as they warm and its joint
zeros wander with the temperature of the drives. Where the controller reports its joint
temperatures (``joint_temp1..N`` columns), two families model that directly:

``thermal_growth``  every link length (and the tool) grows by k · ΔT̄, ΔT̄ the mean rise of
                    the joint temperatures over the reference (``temp_ref_c``, 20 °C);
``thermal_zero:J``  joint J's zero moves by z · ΔT_J, its own temperature rise.

Where only the time is known (``t_s``), two families see the drift as a smooth function
of time over the capture (a polynomial of order K, held at its end value after it):

``time_growthK``    every link length grows by g(t) — the warming arm, seen in time;
``base_driftK``     the base translates in the measurement frame — a settling stand or floor.

All four are linear in their parameters, so their partial derivatives are exact.
"""

from __future__ import annotations

from dataclasses import replace
from typing import Any

import numpy as np

from ..data.dataset import Dataset
from ..model.robot_model import RobotModel
from .base import Effect, EffectError, JointEffect

#: the reference temperature (°C) when the data's metadata name none (``temp_ref_c``)
DEFAULT_TEMP_REF_C = 20.0
#: the highest polynomial order of ``base_driftK``
MAX_DRIFT_ORDER = 4
#: metadata key of the capture's time window ("t0,t1", s), set by :meth:`Drift.prepare`
DRIFT_WINDOW_KEY = "drift_window_s"


def joint_temperature_rise(data: Dataset, family: str, temp_ref_c: float | None = None
                           ) -> np.ndarray:
    """Each joint's temperature over the reference (``temp_ref_c``: the calibration's,
    else the data's ``temp_ref_c`` metadata, else 20 °C), (n, N) K; EffectError without
    joint temperatures."""
    if data.joint_temp is None:
        raise EffectError(f"{data.source}: effect {family} needs the joint temperatures "
                          "(joint_temp1..N columns)")
    if temp_ref_c is None:
        temp_ref_c = float(data.meta.get("temp_ref_c", DEFAULT_TEMP_REF_C))
    return data.joint_temp - temp_ref_c


class _OneParameter(Effect):
    """An effect with one parameter, named in ``parameter``: (name, internal unit, scale)."""

    parameter: tuple[str, str, float] = ("", "", 1.0)
    #: the reference temperature (°C) of a model read from a params.json (its ``thermal``
    #: record), which the data's own ``temp_ref_c`` does not override; None: the data's
    temp_ref_c: float | None = None

    def __init__(self, model: RobotModel, joint: int | None = None,
                 order: int | None = None) -> None:
        super().__init__(model, joint, order)
        name, unit, scale = self.parameter
        self.param_names, self.units, self.scales = [name], [unit], np.array([scale])


class ThermalGrowth(_OneParameter):
    """Thermal growth read from the joints: every link length (d, a) and the tool grow by
    k · ΔT̄, ΔT̄ the mean of the joint temperatures (``joint_temp1..N``) minus the
    reference ``temp_ref_c`` (default 20 °C). The links sit between the drives that heat
    them, so their rise follows the drives'. ``k`` in 1/K: aluminium 23e-6 at the link's
    own temperature; the links warm less than the drives, so k is typically 8-20e-6."""

    family = "thermal_growth"
    stage = "length"
    summary = ("every link grows in proportion to the joints' mean temperature rise — thermal "
               "expansion of the arm as it warms up")

    parameter = ("k", "1/K", 1e-5)

    def bind(self, data: Dataset, nominal: Any) -> np.ndarray:
        return joint_temperature_rise(data, self.family, self.temp_ref_c).mean(axis=1)

    def length_scale(self, p: np.ndarray, data: Dataset, dT: np.ndarray
                     ) -> tuple[np.ndarray, np.ndarray]:
        return p[0] * dT, dT[:, None]

    def typical(self, rng: np.random.Generator) -> np.ndarray:
        return np.array([rng.uniform(10e-6, 20e-6)])


class ThermalZero(_OneParameter, JointEffect):
    """Joint zero drift with temperature: Δθ_J = z · ΔT_J, ΔT_J joint J's temperature
    (``joint_tempJ``) minus the reference ``temp_ref_c`` (default 20 °C) — the encoder and
    gear of a warming drive shift against each other. ``z`` in rad/K (a few µrad/K)."""

    family = "thermal_zero"
    summary = ("the joint's zero moves in proportion to its temperature rise — a warming "
               "drive shifts its encoder against the gear")

    parameter = ("z", "rad/K", 1e-6)

    def bind(self, data: Dataset, nominal: Any) -> np.ndarray:
        return joint_temperature_rise(data, self.label, self.temp_ref_c)[:, self.joint - 1]

    def delta(self, p: np.ndarray, data: Dataset, dT: np.ndarray
              ) -> tuple[np.ndarray, np.ndarray]:
        return p[0] * dT, dT[:, None]

    def typical(self, rng: np.random.Generator) -> np.ndarray:
        return np.array([rng.uniform(2e-6, 6e-6) * rng.choice([-1.0, 1.0])])


def _window(data: Dataset) -> tuple[float, float] | None:
    """The capture's time window from the data's metadata ("t0,t1" s), or None."""
    text = data.meta.get(DRIFT_WINDOW_KEY)
    if text is None:
        return None
    try:
        t0, t1 = (float(v) for v in text.split(","))
    except ValueError:
        raise EffectError(f"{data.source}: metadata {DRIFT_WINDOW_KEY}: {text!r} is not "
                          "t0,t1 (s)") from None
    return t0, t1


class _OverTime(Effect):
    """An effect that is a smooth function of the capture's time: a polynomial basis
    s^k, k = 1..K, of s = (t - t0) / (t1 - t0), the time ``t_s`` scaled to the capture (the
    calibration rows' first and last time; 0 before, 1 after: held at its end value, no
    polynomial is extrapolated). ``familyK`` is order K (1 ... 4), ``family`` K = 1."""

    takes_order = True
    #: per order k, parameters ``{component}{k}`` in ``unit``, of typical size ``scale``
    components: tuple[str, ...] = ()
    unit, scale = "", 1.0
    order: int  # always given (1 when the family is named without one)

    def __init__(self, model: RobotModel, joint: int | None = None,
                 order: int | None = None) -> None:
        super().__init__(model, joint, order)
        self.order = 1 if order is None else int(order)
        if not 1 <= self.order <= MAX_DRIFT_ORDER:
            raise EffectError(f"{self.family} order must be 1..{MAX_DRIFT_ORDER}, "
                              f"not {self.order}")
        self.param_names = [f"{c}{k}" for k in range(1, self.order + 1) for c in self.components]
        self.units = [self.unit] * len(self.param_names)
        self.scales = np.full(len(self.param_names), self.scale)
        #: the window of the last data bound with one: rows bound later without one (a
        #: held-out subset) use it, so every subset of one capture shares its time scale
        self._window: tuple[float, float] | None = None
        #: the calibration's window of a model read from a params.json (its ``thermal``
        #: record): new data are measured against it, not against their own span
        self.calibrated_window: tuple[float, float] | None = None

    def prepare(self, data: Dataset) -> Dataset:
        """Record the time window in the metadata (before any split): the calibration's
        of a reloaded model, else the calibration rows' first and last time."""
        if data.t_s is None or data.n == 0 or _window(data) is not None:
            return data
        if self.calibrated_window is not None:
            t0, t1 = self.calibrated_window
        else:
            calib = data.t_s[~data.is_valid] if (~data.is_valid).any() else data.t_s
            t0, t1 = float(calib.min()), float(calib.max())
        return replace(data, meta={**data.meta, DRIFT_WINDOW_KEY: f"{t0!r},{t1!r}"})

    def bind(self, data: Dataset, nominal: Any) -> np.ndarray:
        """The basis, (n, K)."""
        if data.t_s is None:
            raise EffectError(f"{data.source}: effect {self.label} needs the time of each "
                              "measurement (t_s column)")
        window = self.calibrated_window or _window(data) or self._window
        if window is None and data.n:
            window = (float(data.t_s.min()), float(data.t_s.max()))
        self._window = window
        if window is None:
            return np.zeros((data.n, self.order))
        t0, t1 = window
        s = np.clip((data.t_s - t0) / (t1 - t0), 0.0, 1.0) if t1 > t0 else np.zeros(data.n)
        return s[:, None] ** np.arange(1, self.order + 1)


class TimeGrowth(_OverTime):
    """Warm-up growth seen in time only: every link length (d, a) and the tool grow by
    g(t) = Σ_k g_k · s^k over the capture (see the basis of ``base_drift``), for data without
    joint temperatures. Parameters ``gk`` (dimensionless): the relative growth each term
    reaches at the end of the capture (a warming arm: 1e-4 to 4e-4)."""

    family = "time_growth"
    stage = "length"
    summary = ("every link grows smoothly over the capture — the arm warming up, seen in time "
               "(joint temperatures say more where they are recorded)")

    components, unit, scale = ("g",), "1", 1e-4

    def length_scale(self, p: np.ndarray, data: Dataset, basis: np.ndarray
                     ) -> tuple[np.ndarray, np.ndarray]:
        return basis @ np.asarray(p, float), basis

    def typical(self, rng: np.random.Generator) -> np.ndarray:
        out = np.zeros(self.n_params)
        out[0] = rng.uniform(1e-4, 3e-4)
        return out


class BaseDrift(_OverTime):
    """A slow drift of the robot's base in the measurement frame over the capture:
    ΔP(t) = Σ_k c_k · s^k, k = 1..K, s = (t - t0) / (t1 - t0) the time ``t_s`` scaled to the
    capture (the calibration rows' first and last time; 0 before, 1 after: the drift is held
    at its end value, no polynomial is extrapolated). ``base_drift`` is K = 1 (linear in
    time), ``base_driftK`` order K (up to 4). Parameters ``xk, yk, zk`` (mm) per order: the
    translation each term reaches at the end of the capture: a settling floor or tracker
    stand, a slowly moving fixture."""

    family = "base_drift"
    stage = "drift"
    summary = ("the robot's base moves slowly against the tracker over the capture — a "
               "settling floor, stand or fixture")

    components, unit, scale = ("x", "y", "z"), "mm", 0.05

    def drift(self, p: np.ndarray, data: Dataset,
              basis: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The drift of every pose and its partials.

        Returns
        -------
        delta : (n, 3) mm, added to the point in the measurement frame
        partials : (n, 3, 3K), d delta / d p
        """
        n, K = basis.shape
        delta = basis @ np.asarray(p, float).reshape(K, 3)
        partials = np.zeros((n, 3, 3 * K))
        for c in range(3):
            partials[:, c, c::3] = basis
        return delta, partials

    def typical(self, rng: np.random.Generator) -> np.ndarray:
        direction = rng.normal(size=3)
        out = np.zeros(self.n_params)
        out[:3] = direction / np.linalg.norm(direction) * rng.uniform(0.1, 0.3)
        return out


DRIFT = {cls.family: cls for cls in (ThermalGrowth, ThermalZero, TimeGrowth, BaseDrift)}
