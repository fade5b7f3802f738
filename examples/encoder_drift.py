"""A user-defined effect: a joint encoder that drifts while the robot warms up.

Load it with ``--effect-file examples/encoder_drift.py`` and name it like a built-in:
``--effects geometric,base,tool,drift:2``. It needs the ``t_s`` column.
"""

import numpy as np

from calibration.effects import EffectError, JointEffect


class EncoderDrift(JointEffect):
    """Δθ_J = d · (t - t0): a joint reading that drifts linearly in time (rad/s)."""

    family = "drift"
    summary = "joint encoder drift proportional to time"

    def __init__(self, model, joint=None, order=None):
        super().__init__(model, joint, order)
        self.param_names, self.units, self.scales = ["d"], ["rad/s"], np.array([1e-8])

    def bind(self, data, nominal):
        if data.t_s is None:
            raise EffectError(f"{data.source}: effect {self.label} needs a t_s column")
        return data.t_s - data.t_s.min()

    def delta(self, p, data, t):
        return p[0] * t, t[:, None]  # the correction and its exact derivative
