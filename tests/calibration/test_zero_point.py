"""Zero-point recalibration: a simulated cell whose joint zeros moved (hidden offsets) and
whose tool is unknown; 20 taught postures on one point, 0.02 mm scatter."""

import numpy as np
import pytest

from calibration import DataError, load_model
from calibration.model.inverse import ChainFK
from calibration.zero_point import (
    Postures,
    assess,
    load_postures,
    postures_from_dataset,
    rigorous_method,
    seed_method,
    simulate_postures,
    zero20_postures,
)

HIDDEN_DEG = np.array([0.3, -0.12, 0.25, 0.08, -0.4, 0.2])
TOOL = np.array([12.0, -8.0, 135.0])  # the true tool, unknown to the methods
TARGET = np.array([700.0, 150.0, 250.0])
TOL_DEG = 0.005


def _cell(seed=1, hidden_deg=HIDDEN_DEG, **kw):
    m = load_model("ur10e")
    rng = np.random.default_rng(seed)
    post, q_true = simulate_postures("dh", m.dh_table(), np.radians(hidden_deg), TOOL, TARGET,
                                     scatter_mm=0.02 / np.sqrt(3), limits=m.limits_rad(),
                                     rng=rng, **kw)
    return m, post, q_true


@pytest.fixture(scope="module")
def cell():
    return _cell()


def test_generated_postures_reach_the_target_on_four_planes():
    m = load_model("ur10e")
    q, plane, ok = zero20_postures("dh", m.dh_table(), TOOL, TARGET, limits=m.limits_rad(),
                                   rng=np.random.default_rng(3))
    assert ok.all() and q.shape == (20, 6)
    assert np.bincount(plane).tolist() == [0, 5, 5, 5, 5]
    tip = ChainFK("dh", m.dh_table(), TOOL).point(q)
    np.testing.assert_allclose(tip, np.broadcast_to(TARGET, (20, 3)), atol=1e-6)
    lim = m.limits_rad()
    assert ((q >= lim[:, 0]) & (q <= lim[:, 1])).all()
    # two shoulder configurations (planes 1, 3 and 2, 4) so joint 2 is determined
    q1 = np.degrees(q[:, 0])
    assert abs(((q1[plane == 1].mean() - q1[plane == 2].mean()) + 180) % 360 - 180) > 90


@pytest.mark.parametrize("method", ["rigorous", "seed"])
def test_methods_recover_identifiable_offsets(cell, method):
    m, post, _ = cell
    fk = ChainFK.from_model(m)
    if method == "rigorous":
        r = rigorous_method(fk, post)
    else:
        r = seed_method(fk, post, rng=np.random.default_rng(0))
    assert r.converged, r.reason
    # one fixed point: joint 1 (about the base axis) and 6 (about the tool axis) are free
    assert r.unidentifiable == ["j1", "j6"]
    err = np.degrees(r.offsets - np.radians(HIDDEN_DEG))[r.determined]
    assert np.abs(err).max() < TOL_DEG, err
    np.testing.assert_allclose(r.tool[2], TOOL[2], atol=0.05)
    # the tool's x, y turn with the undetermined joint 6; its distance from the axis does not
    assert np.hypot(*r.tool[:2]) == pytest.approx(np.hypot(*TOOL[:2]), abs=0.05)
    assert r.rms_mm < 0.04


def test_rigorous_uncertainties_are_honest_and_status_ok(cell):
    m, post, _ = cell
    r = rigorous_method(ChainFK.from_model(m), post)
    z = (r.offsets - np.radians(HIDDEN_DEG))[r.determined] / r.std[r.determined]
    assert np.abs(z).max() < 3.5
    assert np.isnan(r.std[[0, 5]]).all()
    assert assess(r, tolerance_deg=0.01, sigma_mm=0.02 / np.sqrt(3)) == ("ok", [])
    assert r.fixed["zero.j1"].startswith("redundant with target")
    assert r.fixed["zero.j6"].startswith("redundant with tool")


def test_measured_tips_make_joint_1_identifiable():
    m, post, _ = _cell(seed=4, tracker_sigma_mm=0.01)
    r = rigorous_method(ChainFK.from_model(m), post, measured_base=post.base_p_tip)
    assert r.unidentifiable == ["j6"]
    err = np.degrees(r.offsets - np.radians(HIDDEN_DEG))[r.determined]
    assert np.abs(err).max() < TOL_DEG, err


def test_wrong_posture_is_flagged_as_outlier():
    m, post, _ = _cell(seed=2)
    fk = ChainFK.from_model(m)
    # posture 7 taught 2 mm off the target: move its joints so the tip shifts by 2 mm
    _, _, Jp, _ = fk(post.q[6:7])
    post.q[6] += np.linalg.pinv(Jp[0]) @ np.array([2.0, 0.0, 0.0])
    r = rigorous_method(fk, post)
    assert r.outliers == [post.pose_id[6]]
    err = np.degrees(r.offsets - np.radians(HIDDEN_DEG))[r.determined]
    assert np.abs(err).max() < TOL_DEG
    kept = rigorous_method(fk, post, reject_outliers=False)
    assert assess(kept, tolerance_deg=0.01, sigma_mm=0.02)[0] == "poor"


def test_bad_start_and_fine_pass():
    hidden = HIDDEN_DEG + np.array([0, 1.0, 0, 0, 0, 0])  # joint 2 off by more than 1 deg
    m, post, _ = _cell(seed=5, hidden_deg=hidden)
    fk = ChainFK.from_model(m)
    for r in (rigorous_method(fk, post), seed_method(fk, post, rng=np.random.default_rng(1))):
        err = np.degrees(r.offsets - np.radians(hidden))[r.determined]
        assert np.abs(err).max() < TOL_DEG, (r.method, err)
    # second, fine pass from the first pass's result: converges at once to the same answer
    first = seed_method(fk, post, rng=np.random.default_rng(1), max_iter=5)
    fine = seed_method(fk, post, offsets0=first.offsets, rng=np.random.default_rng(2))
    err = np.degrees(fine.offsets - np.radians(hidden))[fine.determined]
    assert np.abs(err).max() < TOL_DEG
    assert fine.iterations < 5 + seed_method(fk, post, rng=np.random.default_rng(2)).iterations


def test_one_plane_only_is_too_poor():
    m, post, _ = _cell(seed=6)
    one = post.subset(post.plane == 1)
    r = rigorous_method(ChainFK.from_model(m), one, reject_outliers=False)
    status, reasons = assess(r, tolerance_deg=0.01, sigma_mm=0.02)
    assert status == "poor" and reasons


def test_postures_csv_round_trip_and_strictness(cell, tmp_path):
    m, post, _ = cell
    p = tmp_path / "postures.csv"
    post.to_csv(p)
    back = load_postures(p, m)
    np.testing.assert_allclose(back.q, post.q, rtol=0, atol=1e-14)
    assert back.plane.tolist() == post.plane.tolist()
    text = p.read_text().splitlines()
    bad = tmp_path / "bad.csv"
    fields = text[2].split(",")
    fields[1] = "7"
    bad.write_text("\n".join([text[0], text[1], ",".join(fields)]) + "\n")
    with pytest.raises(DataError, match=r"bad.csv: line 3, column plane: 7"):
        load_postures(bad, m)
    bad.write_text("\n".join([text[0], text[1], text[1]]) + "\n")
    with pytest.raises(DataError, match=r"line 3, column pose_id: '1' already used on line 2"):
        load_postures(bad, m)
    bad.write_text(text[0].replace(",q6", "") + "\n")
    with pytest.raises(DataError, match="missing required column"):
        load_postures(bad, m)
    bad.write_text(text[0] + "\n1,1,0,0,nan,0,0,0\n")
    with pytest.raises(DataError, match=r"line 2, column q3: 'nan' is not a finite number"):
        load_postures(bad, m)
    bad.write_text(text[0] + "\n1,1,0,0,200,0,0,0\n")
    with pytest.raises(DataError, match=r"column q3: 200 deg is outside"):
        load_postures(bad, m)


def test_dataset_like_input(cell):
    from calibration import Dataset

    m, post, _ = cell
    data = Dataset(q=post.q, tracker_p_smr=np.zeros((post.n, 3)), source="store run 7")
    p = postures_from_dataset(data, measured=False)
    assert isinstance(p, Postures) and p.plane.tolist() == post.plane.tolist()
    r = rigorous_method(ChainFK.from_model(m), p)
    assert r.unidentifiable == ["j1", "j6"]
