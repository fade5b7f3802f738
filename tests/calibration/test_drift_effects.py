"""The drift family (issue 26): joint temperatures in the data, exact Jacobians of
thermal_growth, thermal_zero:J, time_growthK and base_driftK, and when diagnose offers them."""

import numpy as np
import pytest

from calibration import Dataset, ErrorModel, load_model
from calibration.data.dataset import load_csv
from calibration.diagnosis.diagnosis import candidate_names
from calibration.effects import EffectError, parse_effects
from calibration.errors import DataError
from calibration.fit.simulate import random_joints, realistic_truth, warmup_temperatures

UR = load_model("ur10e")
DRIFTS = ["thermal_growth", "thermal_zero:2", "thermal_zero:6", "time_growth", "time_growth3",
          "base_drift", "base_drift4"]


def _data(n, rng, **extra):
    t = np.arange(n) * 60.0
    cols = {"t_s": t, "joint_temp": warmup_temperatures(t, 6) + rng.normal(0, 0.3, (n, 6)),
            **extra}
    return Dataset(q=random_joints(UR, n, rng), tracker_p_smr=np.zeros((n, 3)), **cols)


@pytest.mark.parametrize("effect", DRIFTS)
def test_jacobian_columns_match_finite_differences(effect):
    em = ErrorModel(UR, "geometric,base,tool," + effect)
    rng = np.random.default_rng(2)
    bound = em.bind(em.prepare(_data(30, rng)))
    x = realistic_truth(em, rng, length_mm=1.0, angle_deg=0.2)
    x[em.slices[-1]] = rng.normal(0, 1, em.effects[-1].n_params) * em.effects[-1].scales * 3
    _, J = em.evaluate(x, bound)
    Jn = em.numeric_jacobian(x, bound)
    col = np.abs(J).max(axis=(0, 1))
    err = np.abs(J - Jn).max(axis=(0, 1)) / np.maximum(col, 1.0)
    assert err.max() < 1e-5, f"{em.names[int(np.argmax(err))]}: relative error {err.max():.1e}"


def test_each_is_described_in_one_line_and_needs_its_column():
    rng = np.random.default_rng(0)
    bare = Dataset(q=random_joints(UR, 5, rng), tracker_p_smr=np.zeros((5, 3)))
    for name, column in (("thermal_growth", "joint_temp"), ("thermal_zero:3", "joint_temp"),
                         ("time_growth2", "t_s"), ("base_drift", "t_s")):
        (eff,) = parse_effects(name, UR)
        assert eff.summary and "\n" not in eff.summary and type(eff).__doc__
        with pytest.raises(EffectError, match=column):
            eff.bind(bare, None)
    for bad, message in (("base_drift5", "order must be 1..4"), ("thermal_zero", "needs a joint"),
                         ("thermal_growth,time_growth", "length")):
        with pytest.raises(EffectError, match=message):
            parse_effects(bad, UR)


def test_the_time_scale_is_the_calibration_rows_and_held_after_them():
    # validation rows measured later (the warm state) see the drift's end value, not an
    # extrapolated polynomial; a subset bound on its own shares the capture's window
    rng = np.random.default_rng(1)
    data = _data(20, rng, is_valid=np.arange(20) >= 15)
    em = ErrorModel(UR, "geometric,base,tool,base_drift2")
    prepared = em.prepare(data)
    assert prepared.meta["drift_window_s"] == f"{0.0!r},{14 * 60.0!r}"
    basis = em.effects[-1].bind(prepared, None)
    np.testing.assert_allclose(basis[14], [1.0, 1.0])
    np.testing.assert_allclose(basis[15:], 1.0)
    held = em.effects[-1].bind(prepared.valid(), None)
    np.testing.assert_allclose(held, 1.0)
    calib_only = em.effects[-1].bind(data.calib(), None)  # no metadata: its own span
    np.testing.assert_allclose(calib_only, basis[:15])


def test_candidates_only_where_the_data_have_temperatures_or_times():
    rng = np.random.default_rng(3)
    em = ErrorModel(UR)
    full = candidate_names(em, _data(12, rng))
    assert {"thermal_growth", "thermal_zero:1", "thermal_zero:6", "time_growth",
            "time_growth3", "base_drift", "base_drift3"} <= set(full)
    bare = Dataset(q=random_joints(UR, 12, rng), tracker_p_smr=np.zeros((12, 3)))
    assert not {n for n in candidate_names(em, bare)
                if n.startswith(("thermal_", "time_", "base_drift"))}
    steady = _data(12, rng, joint_temp=np.full((12, 6), 30.0))
    names = candidate_names(em, steady)
    assert "thermal_growth" not in names and "time_growth" in names
    grown = ErrorModel(UR, "geometric,base,tool,thermal_growth")
    names = candidate_names(grown, _data(12, rng))  # one effect at the length stage
    assert "time_growth" not in names and "thermal_zero:2" in names


def test_drift_stages_stay_out_of_the_chain():
    em = ErrorModel(UR, "geometric,base,tool,base_drift")
    out = em.perturb(np.zeros(em.n_params))
    assert em.labels.index("base_drift") in out.skipped and "drift" not in out.applied


def test_joint_temperature_columns_round_trip_and_are_strict(tmp_path):
    rng = np.random.default_rng(4)
    d = _data(4, rng)
    p = tmp_path / "temps.csv"
    d.to_csv(p)
    e = load_csv(p, UR)
    np.testing.assert_array_equal(e.joint_temp, d.joint_temp)
    assert e.subset(np.array([1, 3])).joint_temp.shape == (2, 6)
    assert e.concat(e).joint_temp.shape == (8, 6)
    assert load_csv(p, UR).calib().joint_temp is not None
    text = p.read_text()
    for bad, where in (
        (text.replace("joint_temp6", "joint_tempX"), "joint_temp1..joint_temp6; missing "
                                                     "joint_temp6"),
        (text.replace("joint_temp6", "joint_temp7"), "joint_temp7 but the model has 6"),
        (text.replace(repr(float(d.joint_temp[1, 2])), "hot"),
         "column joint_temp3: not a number"),
        (text.replace(repr(float(d.joint_temp[2, 0])), "250.0"), "plausible temperature"),
    ):
        q = tmp_path / "bad.csv"
        q.write_text(bad)
        with pytest.raises(DataError, match=where):
            load_csv(q, UR)
    with pytest.raises(DataError, match="one temperature per joint"):
        Dataset(q=np.zeros((2, 6)), tracker_p_smr=np.zeros((2, 3)), joint_temp=np.zeros((2, 5)))
