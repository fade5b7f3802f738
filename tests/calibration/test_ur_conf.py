"""UR calibration.conf deltas: import, export, exact conversion of beta to pure DH."""

import numpy as np
import pytest
import yaml

from calibration import ErrorModel, load_model
from calibration.exports.model_export import (
    calibrated_model,
    calibrated_table,
    ur_deltas,
    write_ur_conf,
)
from calibration.exports.ur_conf import (
    URConfError,
    deltas_from_table,
    model_from_table,
    model_table_ur,
    read_calibration_conf,
    table_from_deltas,
    to_pure_dh,
    write_calibration_conf,
)
from calibration.model.kinematics import run_chain
from tests.shared_data import shared_file

TOOL = np.array([10.0, 20.0, 100.0])


def _reference():
    return yaml.safe_load(shared_file("ur_reference_values.yaml").read_text())


def _fk(table, q):
    r = run_chain("dh", table, q, TOOL, jacobian=False)
    return r.base_p_tcp, r.base_R_flange


def _random_q(n=1000, seed=0):
    return np.random.default_rng(seed).uniform(-2 * np.pi, 2 * np.pi, (n, 6))


@pytest.mark.parametrize("name", ["set_1", "set_2", "set_3"])
def test_ur_delta_sets_round_trip(name, tmp_path):
    ref = _reference()
    nominal = model_table_ur(ref["nominal_models"]["ur10_cb3"])
    deltas = ref["calibration_deltas"][name]
    t1 = table_from_deltas(nominal, deltas)
    # export (exact conversion via the joint axes as lines) to a file and re-import
    path = tmp_path / "calibration.conf"
    write_calibration_conf(deltas_from_table(t1, nominal), path)
    back = read_calibration_conf(path)
    t3 = table_from_deltas(nominal, back)
    q = _random_q()
    P1, R1 = _fk(t1, q)
    P3, R3 = _fk(t3, q)
    np.testing.assert_allclose(P3, P1, rtol=0, atol=1e-9)  # mm
    np.testing.assert_allclose(R3, R1, rtol=0, atol=1e-12)
    # the common-normal geometry is UR's own: the deltas come back as they were
    np.testing.assert_allclose(back["delta_d"], deltas["delta_d"], rtol=0, atol=1e-12)
    np.testing.assert_allclose(back["delta_a"], deltas["delta_a"], rtol=0, atol=1e-12)


def test_nominal_ur10_matches_urs_check_values():
    ref = _reference()
    nominal = model_table_ur(ref["nominal_models"]["ur10_cb3"])
    for case in ref["fk_checks_ur10_nominal"]:
        if "position" in case:
            r = run_chain("dh", nominal, np.array([case["q"]]), np.zeros(3), jacobian=False)
            np.testing.assert_allclose(r.base_p_tcp[0] / 1000.0, case["position"], atol=1e-10)


def test_beta_model_exports_to_ur_deltas_exactly():
    m = load_model("ur10e")
    em = ErrorModel(m)
    rng = np.random.default_rng(3)
    x = np.zeros(em.n_params)
    geo = em.slices[em.labels.index("geometric")]
    x[geo] = rng.normal(0, 1, geo.stop - geo.start) * np.where(
        np.array(em.units[geo]) == "rad", np.radians(0.05), 0.3)
    x[em.index("tool.x"):em.index("tool.x") + 3] = TOOL
    assert x[em.index("geometric.j2.beta")] != 0.0
    table, tool, notes = calibrated_table(em, x)
    deltas, _ = ur_deltas(em, x)
    # beta on nearly parallel axes becomes large, cancelling d deltas (metres)
    assert abs(deltas["delta_d"][1]) > 1.0 and abs(deltas["delta_d"][1:4].sum()) < 1e-2
    t_back = table_from_deltas(m.dh_table(), deltas)
    assert (t_back[:, 4] == 0).all()
    q = _random_q(seed=1)
    P1, R1 = _fk(table, q)
    P2, R2 = _fk(t_back, q)
    np.testing.assert_allclose(P2, P1, rtol=0, atol=1e-9)
    np.testing.assert_allclose(R2, R1, rtol=0, atol=1e-12)


def test_model_yaml_export_keeps_fk(tmp_path):
    m = load_model("ur10e")
    em = ErrorModel(m)
    rng = np.random.default_rng(4)
    x = rng.normal(0, 1e-3, em.n_params)
    x[em.index("tool.x"):em.index("tool.x") + 3] = TOOL
    cm, notes = calibrated_model(em, x)
    assert any(n.startswith("base") for n in notes)
    table, tool, _ = calibrated_table(em, x)
    np.testing.assert_allclose(cm.tool_mm(), tool)
    q = _random_q(200, seed=2)
    P1, _ = _fk(table, q)
    P2, _ = _fk(cm.dh_table(), q)
    np.testing.assert_allclose(P2, P1, rtol=0, atol=1e-9)


def test_pure_dh_refuses_beta_on_the_last_row_and_bad_conf(tmp_path):
    t = load_model("ur10e").dh_table()
    t[5, 4] = 1e-3
    with pytest.raises(ValueError, match="last row"):
        to_pure_dh(t)
    bad = tmp_path / "c.conf"
    bad.write_text("[mounting]\n  delta_theta = [0, 0, 0, 0, 0, 0]\n")
    with pytest.raises(URConfError, match="missing delta_a"):
        read_calibration_conf(bad)
    with pytest.raises(URConfError, match="has 2 values"):
        table_from_deltas(t, {"delta_theta": [0, 0], "delta_a": [0] * 6, "delta_d": [0] * 6,
                              "delta_alpha": [0] * 6})


def test_write_ur_conf_and_model_from_table(tmp_path):
    m = load_model("ur10e")
    em = ErrorModel(m)
    x = np.zeros(em.n_params)
    notes = write_ur_conf(em, x, tmp_path / "calibration.conf")
    assert notes and read_calibration_conf(tmp_path / "calibration.conf")["delta_d"].shape == (6,)
    same = model_from_table(m, m.dh_table())
    np.testing.assert_allclose(same.dh_table(), m.dh_table(), atol=1e-15)
