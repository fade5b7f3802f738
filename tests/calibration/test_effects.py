"""Every effect family: exact Jacobian columns, and the physics they add."""

import numpy as np
import pytest

from calibration import Dataset, ErrorModel, identify, load_model
from calibration.effects import REGISTRY, EffectError, load_effect_file, parse_effects
from calibration.fit.simulate import random_joints, realistic_truth, simulate
from tests.shared_data import ROOT

MODEL = load_model("ur10e").with_changes(payload={"mass_kg": 4.0, "com": [0.0, 0.0, 40.0]})
FAMILIES = ["compliance:2", "harmonic:1", "harmonic12:4", "table:3", "scale:2", "backlash:3",
            "coupling:5", "thermal", "tracker_scale"]


def _data(n, rng, **extra):
    cols = {"temp_c": rng.uniform(15, 35, n), "dirs": rng.choice([-1, 1], (n, 6)),
            "t_s": np.arange(n) * 10.0, **extra}
    return Dataset(q=random_joints(MODEL, n, rng), tracker_p_smr=np.zeros((n, 3)), **cols)


@pytest.mark.parametrize("effect", FAMILIES)
def test_jacobian_columns_match_finite_differences(effect):
    em = ErrorModel(MODEL, "geometric,base,tool," + effect)
    rng = np.random.default_rng(1)
    bound = em.bind(_data(30, rng))
    x = realistic_truth(em, rng, length_mm=1.0, angle_deg=0.2)
    _, J = em.evaluate(x, bound)
    Jn = em.numeric_jacobian(x, bound)
    # relative to the column, with a floor for columns that barely move the point
    # (finite differences of a 3 m vector lose ~1e-5 mm to rounding)
    col = np.abs(J).max(axis=(0, 1))
    err = np.abs(J - Jn).max(axis=(0, 1)) / np.maximum(col, 1.0)
    worst = int(np.argmax(err))
    assert err.max() < 1e-5, f"{em.names[worst]}: relative error {err.max():.1e}"


def test_every_family_of_formats_is_registered():
    for fam in ("geometric", "base", "tool", "compliance", "harmonic", "table", "scale",
                "backlash", "coupling", "thermal", "tracker_scale"):
        assert fam in REGISTRY
        assert REGISTRY[fam].__doc__  # the physics and units, in words


@pytest.mark.parametrize("spec, message", [
    ("compliance", "needs a joint"),
    ("compliance:9", "joints 1..6"),
    ("thermal:2", "not per joint"),
    ("coupling:1", "J >= 2"),
    ("wobble:1", "unknown effect family"),
    ("scale:2,scale:2", "given twice"),
])
def test_bad_effect_names(spec, message):
    with pytest.raises(EffectError, match=message):
        parse_effects(spec, MODEL)


def test_compliance_needs_a_mass_model():
    with pytest.raises(EffectError, match="mass model"):
        parse_effects("compliance:2", load_model("rv16"))


def test_thermal_needs_temperatures():
    em = ErrorModel(MODEL, "geometric,base,tool,thermal")
    rng = np.random.default_rng(0)
    with pytest.raises(EffectError, match="temp_c"):
        em.bind(Dataset(q=random_joints(MODEL, 5, rng), tracker_p_smr=np.zeros((5, 3))))


def test_backlash_derives_directions_from_capture_order_and_says_so():
    em = ErrorModel(MODEL, "geometric,base,tool,backlash:2")
    rng = np.random.default_rng(3)
    x = realistic_truth(em, rng)
    q = random_joints(MODEL, 400, rng)
    dirs = np.zeros((400, 6), int)
    dirs[1:] = np.sign(np.diff(q, axis=0))
    data = simulate(em, x, q, 0.015, rng, dirs=dirs)
    data.dirs = None  # as from a CSV without dir columns
    fit = identify(em, data)
    assert any("derived from consecutive rows" in n for n in fit.notes)
    b, sb = fit.param("backlash.j2.b")
    assert abs(b - x[em.index("backlash.j2.b")]) < 3 * sb


def test_table_pins_knots_without_data_and_chooses_its_smoothing():
    em = ErrorModel(MODEL, "geometric,base,tool,table:2")
    rng = np.random.default_rng(4)
    x = realistic_truth(em, rng)
    data = simulate(em, x, random_joints(MODEL, 500, rng, max_abs_deg=150), 0.015, rng,
                    is_valid=np.arange(500) >= 300)
    fit = identify(em, data)
    table = em.effects[-1]
    assert table.smoothing is not None and len(table.cv_curve) >= 4
    pinned = [n for n, why in fit.identifiability.fixed.items() if "no data" in why]
    assert "table.j2.km360" in pinned and "table.j2.kp360" in pinned
    assert "table.j2.kp000" not in pinned
    assert fit.valid["rms_mm"] < 1.1 * data.noise_floor_mm()


def test_user_defined_effect_file(tmp_path):
    load_effect_file(ROOT / "examples" / "encoder_drift.py")
    em = ErrorModel(MODEL, "geometric,base,tool,drift:2")
    rng = np.random.default_rng(5)
    x = realistic_truth(em, rng)
    x[em.index("drift.j2.d")] = 3e-8  # rad/s: 0.1 mm at the tool after an hour
    n = 600
    data = simulate(em, x, random_joints(MODEL, n, rng), 0.015, rng,
                    t_s=np.arange(n) * 6.0, is_valid=np.arange(n) % 2 == 1)
    bound = em.bind(data)
    _, J = em.evaluate(x, bound)
    np.testing.assert_allclose(J, em.numeric_jacobian(x, bound), rtol=0,
                               atol=1e-5 * np.abs(J).max())
    fit = identify(em, data)
    d, sd = fit.param("drift.j2.d")
    assert abs(d - 3e-8) < 3 * sd
    assert fit.valid["rms_mm"] < 1.05 * data.noise_floor_mm()
    bad = tmp_path / "broken.py"
    bad.write_text("raise RuntimeError('boom')\n")
    with pytest.raises(EffectError, match="boom"):
        load_effect_file(bad)
