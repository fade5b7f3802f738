import json

import numpy as np
import pytest

from calibration import ErrorModel, identify, load_model
from calibration.params_io import ParamsError, fit_to_dict, load_params, save_params
from calibration.simulate import random_joints, realistic_truth, simulate


def test_params_round_trip(tmp_path):
    m = load_model("ur5e")
    em = ErrorModel(m)
    rng = np.random.default_rng(0)
    data = simulate(em, realistic_truth(em, rng), random_joints(m, 100, rng), 0.02, rng)
    fit = identify(em, data)
    p = tmp_path / "params.json"
    save_params(fit, p)
    doc = json.loads(p.read_text())
    row = next(r for r in doc["parameters"] if r["name"] == "geometric.j2.alpha")
    assert row["unit"] == "deg"
    em2, x, std = load_params(p)
    assert em2.names == em.names and em2.model == m
    np.testing.assert_allclose(x, fit.values, rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(std, fit.std, rtol=1e-12, atol=1e-15)
    # the loaded parameters predict what the fit predicts
    np.testing.assert_allclose(em2.evaluate(x, em2.bind(data), False)[0], fit.predict(data))


def test_bad_params_files(tmp_path):
    p = tmp_path / "p.json"
    p.write_text("{not json")
    with pytest.raises(ParamsError, match="not valid JSON"):
        load_params(p)
    p.write_text('{"format": "other"}')
    with pytest.raises(ParamsError, match="not a cellcal params file"):
        load_params(p)
    m = load_model("ur5e")
    em = ErrorModel(m)
    rng = np.random.default_rng(0)
    data = simulate(em, realistic_truth(em, rng), random_joints(m, 60, rng), 0.02, rng)
    doc = fit_to_dict(identify(em, data))
    doc["parameters"][0]["unit"] = "rad"
    p.write_text(json.dumps(doc))
    with pytest.raises(ParamsError, match="unit 'rad', expected 'deg'"):
        load_params(p)


def test_auto_steps_are_recorded_and_read_back(tmp_path):
    """``diagnose --auto --out``'s steps ride along in params.json; the parameters read as
    before, and a file without them (``calibrate``) has none."""
    from calibration.auto_diagnosis import auto_diagnose
    from calibration.params_io import read_auto_steps

    m = load_model("ur5e")
    em = ErrorModel(m, "geometric,base,tool,compliance:3")
    rng = np.random.default_rng(3)
    data = simulate(em, realistic_truth(em, rng), random_joints(m, 200, rng), 0.015, rng)
    start = identify(ErrorModel(m), data)
    auto = auto_diagnose(start, data, max_steps=2)
    assert [s.effect for s in auto.steps][:1] == ["compliance:3"]
    p = tmp_path / "auto.json"
    save_params(auto.fit, p, auto=auto)
    rec = read_auto_steps(p)
    assert rec["start_effects"] == ["geometric", "base", "tool"]
    assert [s["effect"] for s in rec["steps"]] == [s.effect for s in auto.steps]
    assert rec["steps"][0] == auto.steps[0].to_json()
    assert rec["stop_reason"] == auto.stop_reason
    assert rec["start_heldout_rms_mm"] == pytest.approx(auto.start_heldout_rms_mm)
    em2, x, _ = load_params(p)
    assert em2.labels == auto.effects
    np.testing.assert_allclose(x, auto.fit.values, rtol=1e-12, atol=1e-12)
    plain = tmp_path / "plain.json"
    save_params(start, plain)
    assert read_auto_steps(plain) is None and read_auto_steps({"auto_steps": 3}) is None
