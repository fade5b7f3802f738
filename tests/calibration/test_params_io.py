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
