"""A robot warming up during its capture, with a known truth (issue 26).

The true robot's links grow with the joints' mean temperature rise and its joint zeros move
with each joint's own (hidden ``thermal_growth`` and ``thermal_zero:J``, a few tenths of a
mm over a 40-minute cold start). Calibrated from the cold capture with the geometric model,
it is visibly worse at the warm state than calibrated from a warm capture; ``diagnose
--auto`` on the cold capture adds the thermal effects and comes back to the noise floor at
the warm state; a warm robot's capture gets no drift effect, across seeds.
"""

import numpy as np
import pytest

from calibration import ErrorModel, identify, load_model
from calibration.diagnosis.auto_diagnosis import auto_diagnose
from calibration.fit.simulate import random_joints, realistic_truth, simulate, warmup_temperatures

UR = load_model("ur10e")
SIGMA = 0.015
THERMAL = "thermal_growth," + ",".join(f"thermal_zero:{j}" for j in range(1, 7))
DRIFT_FAMILIES = ("thermal_growth", "thermal_zero", "time_growth", "base_drift")
N, DT_S = 300, 8.0  # a 40-minute capture
WARM_S = 4 * 3600.0  # four hours of work later


def _robot(seed):
    rng = np.random.default_rng(seed)
    em = ErrorModel(UR, "geometric,base,tool," + THERMAL)
    return em, realistic_truth(em, rng), rng


def _capture(em, x, rng, start_s, **cols):
    t = start_s + np.arange(N) * DT_S
    return simulate(em, x, random_joints(UR, N, rng), SIGMA, rng, t_s=t,
                    joint_temp=warmup_temperatures(t, 6), **cols)


@pytest.mark.parametrize("seed", [1, 4])
def test_cold_start_calibrates_worse_unless_the_drift_is_modelled(seed):
    em, x, rng = _robot(seed)
    cold = _capture(em, x, rng, 0.0)
    warm = _capture(em, x, rng, WARM_S)
    valid = _capture(em, x, rng, WARM_S + 3600.0, is_valid=np.ones(N, bool))
    floor = cold.noise_floor_mm()
    # the drift over the cold capture: a few tenths of a mm
    no_heat = x.copy()
    no_heat[em.slices[3].start:] = 0.0
    P, P0 = (em.evaluate(v, em.bind(cold), False)[0] for v in (x, no_heat))
    moved = np.linalg.norm((P - P0) - (P - P0)[0], axis=1).max()
    assert 0.1 < moved < 0.5

    def at_warm(effects, data):
        return identify(ErrorModel(UR, effects), data.concat(valid)).valid["rms_mm"]

    geometric = "geometric,base,tool"
    assert at_warm(geometric, warm) < 1.1 * floor
    assert at_warm(geometric, cold) > 2.5 * floor  # visibly worse without warm-up
    auto = auto_diagnose(identify(ErrorModel(UR), cold), cold)
    added = auto.effects[3:]
    assert "thermal_growth" in added, auto.stop_reason
    assert all(e.startswith(("thermal_growth", "thermal_zero")) for e in added), added
    assert at_warm(",".join(auto.effects), cold) <= 1.15 * floor


@pytest.mark.parametrize("seed", [11, 12, 13, 14])
def test_a_warm_robot_never_gets_a_drift_effect(seed):
    em, x, rng = _robot(seed)
    t = WARM_S + np.arange(N) * DT_S
    warm = simulate(em, x, random_joints(UR, N, rng), SIGMA, rng, t_s=t,
                    joint_temp=warmup_temperatures(t, 6) + rng.normal(0, 0.2, (N, 6)))
    auto = auto_diagnose(identify(ErrorModel(UR), warm), warm)
    assert not [e for e in auto.effects if e.startswith(DRIFT_FAMILIES)], auto.effects
