"""The automatic diagnosis on simulated robots with known hidden errors, and the control."""

import numpy as np
import pytest

from calibration import ErrorModel, identify, load_model
from calibration.diagnosis.auto_diagnosis import auto_diagnose, explain_effect
from calibration.effects import parse_effects
from calibration.fit.simulate import Bump, random_joints, realistic_truth, simulate

UR10E = load_model("ur10e")
SIGMA = 0.015
PERIODIC = "harmonic20:2,harmonic2:3,harmonic:1,harmonic8:5"


def _capture(hidden: str, seed: int, n: int = 1000, bumps=(), valid_every: int = 2):
    effects = parse_effects("geometric,base,tool" + ("," + hidden if hidden else ""), UR10E)
    effects += [Bump(UR10E, j, centre, width) for j, centre, width in bumps]
    em = ErrorModel(UR10E, effects)
    rng = np.random.default_rng(seed)
    x = realistic_truth(em, rng)
    q = random_joints(UR10E, n, rng)
    dirs = np.zeros((n, 6), int)
    dirs[1:] = np.sign(np.diff(q, axis=0))
    is_valid = (np.arange(n) % valid_every == 1) if valid_every else np.zeros(n, bool)
    return em, x, simulate(em, x, q, SIGMA, rng, dirs=dirs, is_valid=is_valid)


def _check_steps(result, start_heldout):
    before = start_heldout
    for s in result.steps:
        assert s.heldout_rms_mm < before  # never adds what does not lower held-out error
        assert s.n_params >= 1 and s.seconds > 0 and s.explanation
        before = s.heldout_rms_mm


def test_several_periodic_errors_and_local_bumps_are_found_down_to_the_noise_floor():
    em, x, data = _capture(PERIODIC, seed=7, bumps=[(2, 30.0, 4.0), (4, -60.0, 3.0)])
    fit = identify(ErrorModel(UR10E), data)
    floor = data.noise_floor_mm()
    assert fit.valid["rms_mm"] > 5 * floor
    result = auto_diagnose(fit, data)
    _check_steps(result, result.start_heldout_rms_mm)
    assert result.fit.valid["rms_mm"] < 1.10 * floor
    assert 4 <= len(result.steps) <= 12
    # what it added is what is hidden: harmonics of the right order on the right joint,
    # anything else only on a joint with a hidden bump or harmonic
    hidden = set(PERIODIC.split(","))
    for s in result.steps:
        eff = s.effect
        if eff.startswith("harmonic"):
            assert eff in hidden, eff
        else:
            assert eff.split(":")[1] in {"1", "2", "3", "4", "5"}, eff
    assert {"harmonic20:2", "harmonic2:3"} <= {s.effect for s in result.steps}
    assert "noise floor" in result.stop_reason
    doc = result.to_json("params.json")
    assert set(doc) == {"model", "start_effects", "steps", "effects", "stop_reason",
                        "params_file", "outliers"}
    assert doc["effects"] == result.effects and doc["start_effects"] == ["geometric", "base",
                                                                          "tool"]
    assert set(doc["steps"][0]) == {"effect", "n_params", "calib_rms_mm", "heldout_rms_mm",
                                    "range_blocked_rms_mm", "seconds", "explanation"}
    assert doc["outliers"] == [] and doc["params_file"] == "params.json"


@pytest.mark.parametrize("known_noise", [True, False])
def test_control_without_hidden_effect_adds_nothing(known_noise):
    _, _, data = _capture("", seed=3)
    if not known_noise:  # the F-test and held-out check alone, without the noise floor
        data.meta.pop("tracker_sigma_mm")
    fit = identify(ErrorModel(UR10E), data)
    result = auto_diagnose(fit, data)
    assert result.steps == [] and result.effects == ["geometric", "base", "tool"]
    assert ("noise floor" in result.stop_reason) == known_noise


def test_without_validation_rows_held_out_error_is_cross_validated():
    _, _, data = _capture("compliance:3,harmonic12:4", seed=21, n=500, valid_every=0)
    fit = identify(ErrorModel(UR10E), data)
    result = auto_diagnose(fit, data)
    assert "cross-validation" in result.heldout_method
    _check_steps(result, result.start_heldout_rms_mm)
    assert [s.effect for s in result.steps][:2] in (["compliance:3", "harmonic12:4"],
                                                     ["harmonic12:4", "compliance:3"])
    assert result.steps[-1].heldout_rms_mm < 1.15 * data.noise_floor_mm()


def test_max_steps_and_budget_stop_it_and_say_so():
    _, _, data = _capture("compliance:3,harmonic12:4,backlash:2", seed=22, n=600)
    fit = identify(ErrorModel(UR10E), data)
    one = auto_diagnose(fit, data, max_steps=1)
    assert len(one.steps) == 1 and "maximum of 1 steps" in one.stop_reason
    none = auto_diagnose(fit, data, budget_s=1e-9)
    assert none.steps == [] and "time budget" in none.stop_reason


def test_every_family_is_explained_in_its_own_words():
    texts = {name: explain_effect(name, UR10E) for name in (
        "harmonic20:2", "harmonic:1", "harmonic2:4", "compliance:3", "backlash:2", "scale:2",
        "coupling:5", "table3:4", "thermal", "tracker_scale")}
    assert "20-per-turn periodic error of joint 2" in texts["harmonic20:2"]
    assert "strain-wave gear's tooth meshing" in texts["harmonic20:2"]
    assert "once-per-turn" in texts["harmonic:1"] and "eccentric" in texts["harmonic:1"]
    assert "gravity torque" in texts["compliance:3"]
    assert "backlash" in texts["backlash:2"] and "gear-ratio" in texts["scale:2"]
    assert "joint 4's angle" in texts["coupling:5"] and "every 3°" in texts["table3:4"]
    assert "thermal expansion" in texts["thermal"] and "tracker" in texts["tracker_scale"]
    assert len(set(texts.values())) == len(texts)


def test_blunders_left_out_of_the_fit_do_not_stop_the_loop():
    """Millimetre blunders in the calibration rows: the start fit leaves them out, and so
    does the screening, which finds the same effects as on the clean data."""
    from calibration.fit.simulate import add_blunders

    em, x, data = _capture("compliance:3,harmonic2:4", seed=5, n=500)
    clean = auto_diagnose(identify(ErrorModel(UR10E), data), data)
    bad, truth = add_blunders(data, 0.02, np.random.default_rng(5), rows=~data.is_valid)
    assert len(truth.pose_id) >= 3
    fit = identify(ErrorModel(UR10E), bad)
    assert set(fit.outliers.ids) == set(truth.pose_id)
    result = auto_diagnose(fit, bad)
    assert [s.effect for s in result.steps] == [s.effect for s in clean.steps]
    assert {"compliance:3", "harmonic2:4"} <= set(result.effects)


def test_cross_validated_errors_of_fits_without_other_blunders_are_paired_by_pose():
    """Fewer validation rows than MIN_HELDOUT: held-out errors are cross-validated over each
    fit's own rows; a refit that leaves out other blunders is compared on the poses both
    kept (it used to crash on the mismatched lengths)."""
    from calibration.diagnosis.auto_diagnosis import Heldout, paired_gain

    ids = np.array([f"p{i}" for i in range(6)], dtype=object)
    before = Heldout(np.array([1.0, 2.0, 3.0, 4.0, 5.0, 6.0]), "cv", ids)
    after = Heldout(np.array([0.5, 1.5, 3.5, 5.5]), "cv", ids[[0, 1, 3, 5]])
    gain, se = paired_gain(before, after)
    d = np.array([0.5, 0.5, 0.5, 0.5])  # p0, p1, p3, p5
    assert gain == pytest.approx(d.mean()) and se == pytest.approx(0.0)
    # the same count, other poses: still paired by id
    after2 = Heldout(np.array([0.0, 0.0, 0.0, 0.0, 0.0, 0.0]), "cv", ids[::-1])
    assert paired_gain(before, after2)[0] == pytest.approx(3.5)
