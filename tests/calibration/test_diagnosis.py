"""Diagnosis on simulated data with a known hidden effect (0.05-0.5 mm at the tool)."""

import numpy as np
import pytest

from calibration import ErrorModel, identify, load_model
from calibration.diagnosis.diagnosis import diagnose
from calibration.fit.simulate import random_joints, realistic_truth, simulate

UR10E = load_model("ur10e")
SIGMA = 0.015


def _capture(hidden: str, seed: int, n: int = 600, geometric: bool = True):
    spec = ("geometric,base,tool" if geometric else "base,tool") + (
        "," + hidden if hidden else "")
    em = ErrorModel(UR10E, spec)
    rng = np.random.default_rng(seed)
    x = realistic_truth(em, rng)
    q = random_joints(UR10E, n, rng)
    cols = {"is_valid": np.arange(n) % 2 == 1,  # interleaved, as a capture would do
            "temp_c": 20 + 6 * np.sin(np.linspace(0, 3, n)) + rng.normal(0, 0.1, n),
            "t_s": np.arange(n) * 8.0}
    dirs = np.zeros((n, 6), int)
    dirs[1:] = np.sign(np.diff(q, axis=0))
    cols["dirs"] = dirs
    return em, x, simulate(em, x, q, SIGMA, rng, **cols)


HIDDEN = ["compliance:3", "compliance:2", "harmonic:1", "harmonic12:4", "table:2", "scale:2",
          "backlash:3", "coupling:5", "thermal"]


@pytest.mark.parametrize("hidden", HIDDEN)
def test_hidden_effect_is_found_first_and_adding_it_reaches_the_floor(hidden):
    _, _, data = _capture(hidden, seed=HIDDEN.index(hidden) + 10)
    fit = identify(ErrorModel(UR10E), data)
    floor = data.noise_floor_mm()
    assert fit.valid["rms_mm"] > 1.2 * floor  # the geometric model leaves it behind
    diag = diagnose(fit, data)
    best = diag.candidates[0]
    assert best.effect == hidden, [c.effect for c in diag.candidates[:3]]
    assert best.significant and best.confirmed
    assert diag.best is best and diag.next_effects().endswith("," + hidden)
    if best.family == "harmonic":
        assert best.order == (int(hidden.split(":")[0][8:] or 1))
    refit = identify(ErrorModel(UR10E, diag.next_effects()), data)
    assert refit.valid["rms_mm"] < 1.10 * floor


def test_control_without_hidden_effect_has_nothing_significant():
    _, _, data = _capture("", seed=3)
    fit = identify(ErrorModel(UR10E), data)
    diag = diagnose(fit, data)
    assert diag.at_floor
    assert not any(c.significant for c in diag.candidates)
    assert diag.best is None and "noise floor" in diag.recommendation()
    assert diag.next_effects() == "geometric,base,tool"


def test_two_hidden_effects_are_found_one_after_the_other():
    _, _, data = _capture("compliance:3,harmonic12:4", seed=21)
    fit = identify(ErrorModel(UR10E), data)
    first = diagnose(fit, data).best
    assert first is not None and first.effect in ("compliance:3", "harmonic12:4")
    fit2 = identify(ErrorModel(UR10E, "geometric,base,tool," + first.effect), data)
    second = diagnose(fit2, data).best
    other = ({"compliance:3", "harmonic12:4"} - {first.effect}).pop()
    assert second is not None and second.effect == other
    fit3 = identify(ErrorModel(UR10E, "geometric,base,tool,compliance:3,harmonic12:4"), data)
    assert fit3.valid["rms_mm"] < 1.10 * data.noise_floor_mm()
    assert diagnose(fit3, data).best is None


def test_tracker_scale_is_found_where_the_robot_lengths_are_known():
    # with free link lengths a tracker scale is exactly redundant (a larger robot further
    # away looks the same); with a robot of known geometry it is found
    _, _, data = _capture("tracker_scale", seed=5, geometric=False)
    fit = identify(ErrorModel(UR10E, "base,tool"), data)
    diag = diagnose(fit, data)
    assert diag.best is not None and diag.best.effect == "tracker_scale"
    with_geometry = diagnose(identify(ErrorModel(UR10E), data), data)
    assert with_geometry.at_floor and with_geometry.best is None


def test_where_it_fails_points_at_the_bad_joint_and_the_worst_poses():
    _, _, data = _capture("backlash:3", seed=8)
    fit = identify(ErrorModel(UR10E), data)
    diag = diagnose(fit, data)
    w = diag.where
    assert w.error_mm.shape == (fit.data.n,)
    ids = [p for p, _, _ in w.worst]
    assert len(ids) == 5 and ids[0] == fit.data.pose_id[int(np.argmax(w.error_mm))]
    # the joint-equivalent residual of joint 3 splits by approach direction
    jr = w.joint_residual_rad[:, 2]
    d = fit.data.dirs[:, 2]
    assert abs(np.median(jr[d > 0]) - np.median(jr[d < 0])) > 5e-5
    assert set(w.periodogram) == set(range(1, 7)) and len(w.periodogram[1][0]) == 60
    doc = diag.to_json()
    for key in ("model", "effects", "rms_mm", "noise_floor_mm", "candidates"):
        assert key in doc
    c = doc["candidates"][0]
    for key in ("effect", "family", "joint", "rms_after_mm", "explained_fraction", "p_value",
                "significant"):
        assert key in c
