"""`cellcal zero`: exit codes 0 (decided), 3 (too poor to decide), 2 (bad input)."""

import json

import numpy as np
import pytest
import yaml

from calibration import load_model
from calibration.zero_point import simulate_postures
from cellcal.cli import main

HIDDEN_DEG = np.array([0.3, -0.12, 0.25, 0.08, -0.4, 0.2])


@pytest.fixture(scope="module")
def postures(tmp_path_factory):
    m = load_model("ur10e")
    post, _ = simulate_postures("dh", m.dh_table(), np.radians(HIDDEN_DEG),
                                np.array([12.0, -8.0, 135.0]), np.array([700.0, 150.0, 250.0]),
                                scatter_mm=0.02 / np.sqrt(3), limits=m.limits_rad(),
                                rng=np.random.default_rng(1))
    folder = tmp_path_factory.mktemp("zero")
    path = folder / "postures.csv"
    post.to_csv(path)
    one_plane = folder / "one_plane.csv"
    post.subset(post.plane == 1).to_csv(one_plane)
    return path, one_plane


def test_zero_json_follows_formats_and_writes_the_model(postures, tmp_path, capsys):
    path, _ = postures
    out = tmp_path / "ur10e_rezeroed.yaml"
    rc = main(["zero", str(path), "--model", "ur10e", "--json", "--out", str(out)])
    doc = json.loads(capsys.readouterr().out)
    assert rc == 0, doc["reasons"]
    for key in ("model", "n_poses", "offsets_deg", "std_deg", "unidentifiable", "tool_mm",
                "target_mm", "rms_mm", "status"):
        assert key in doc
    assert doc["status"] == "ok" and doc["n_poses"] == 20
    assert doc["unidentifiable"] == ["j1", "j6"]
    assert doc["offsets_deg"][0] is None and doc["offsets_deg"][5] is None
    assert doc["std_deg"][0] is None
    got = np.array(doc["offsets_deg"][1:5])
    np.testing.assert_allclose(got, HIDDEN_DEG[1:5], atol=0.005)
    np.testing.assert_allclose(doc["seed"]["offsets_deg"][1:5], HIDDEN_DEG[1:5], atol=0.005)
    assert doc["changed"] == ["j2", "j3", "j4", "j5"]
    # the new model carries the corrections in theta_offset, joints 1 and 6 untouched
    new = yaml.safe_load(out.read_text())
    theta = [j["theta_offset"] for j in new["joints"]]
    np.testing.assert_allclose(theta[1:5], got, atol=1e-6)  # JSON rounds to 1e-6 deg
    assert theta[0] == 0.0 and theta[5] == 0.0


def test_zero_replay_fine_pass_and_text(postures, tmp_path, capsys):
    path, _ = postures
    first = tmp_path / "first.json"
    assert main(["zero", str(path), "--model", "ur10e", "--json"]) == 0
    first.write_text(capsys.readouterr().out)
    assert main(["zero", str(path), "--model", "ur10e", "--replay", str(first),
                 "--method", "rigorous", "--json"]) == 0
    doc = json.loads(capsys.readouterr().out)
    assert doc["iterations"] <= 3
    assert main(["zero", str(path), "--model", "ur10e"]) == 0
    text = capsys.readouterr().out
    assert "undetermined" in text and "status    ok" in text


def test_zero_poor_data_exits_3(postures, tmp_path, capsys):
    _, one_plane = postures
    out = tmp_path / "never.yaml"
    rc = main(["zero", str(one_plane), "--model", "ur10e", "--json", "--out", str(out)])
    doc = json.loads(capsys.readouterr().out)
    assert rc == 3 and doc["status"] == "poor" and doc["reasons"]
    assert not out.exists()


def test_zero_bad_input_exits_2(postures, tmp_path, capsys):
    path, _ = postures
    bad = tmp_path / "bad.csv"
    bad.write_text("pose_id,plane,q1,q2,q3,q4,q5,q6\n1,1,0,0,0,0,0,x\n")
    assert main(["zero", str(bad), "--model", "ur10e"]) == 2
    assert "bad.csv: line 2, column q6: not a number" in capsys.readouterr().err
    assert main(["zero", str(path), "--model", "nosuch"]) == 2
    model = tmp_path / "m.yaml"
    model.write_text(load_model("ur10e").to_yaml())
    assert main(["zero", str(path), "--model", str(model), "--out", str(model)]) == 2
    assert "is an input of this command" in capsys.readouterr().err
    assert main(["zero", str(path), "--model", "ur10e", "--out", str(tmp_path / "p.json")]) == 2
    with pytest.raises(SystemExit) as e:  # refused by the parser
        main(["zero", str(path), "--model", "ur10e", "--sigma", "-1"])
    assert e.value.code == 2 and "--sigma: -1 is not a positive number" in capsys.readouterr().err


def test_measured_tips_are_used_in_the_frame_they_are_in(tmp_path, capsys):
    """Base-frame tips stay as they are with --params; tracker-frame tips are mapped into
    the base frame with the params' base pose."""
    from calibration import ErrorModel, identify
    from calibration.exports.params_io import save_params
    from calibration.fit.simulate import random_joints, realistic_truth, simulate
    from calibration.model.transforms import rotvec_to_matrix

    m = load_model("ur10e")
    rng = np.random.default_rng(7)
    em = ErrorModel(m, "base,tool")
    x = realistic_truth(em, rng)
    fit = identify(em, simulate(em, x, random_joints(m, 60, rng), 0.01, rng))
    params = tmp_path / "p.json"
    save_params(fit, params)
    post, _ = simulate_postures("dh", m.dh_table(), np.radians(HIDDEN_DEG),
                                np.array([12.0, -8.0, 135.0]), np.array([700.0, 150.0, 250.0]),
                                scatter_mm=0.02 / np.sqrt(3), tracker_sigma_mm=0.01,
                                limits=m.limits_rad(), rng=np.random.default_rng(1))
    in_base = tmp_path / "base_tips.csv"
    post.to_csv(in_base)
    k = em.index("base.x")
    R, t = rotvec_to_matrix(fit.values[k + 3:k + 6]), fit.values[k:k + 3]
    post.tracker_p_tip, post.base_p_tip = post.base_p_tip @ R.T + t, None
    in_tracker = tmp_path / "tracker_tips.csv"
    post.to_csv(in_tracker)
    for path in (in_base, in_tracker):
        rc = main(["zero", str(path), "--model", "ur10e", "--params", str(params), "--json"])
        doc = json.loads(capsys.readouterr().out)
        assert rc == 0, doc["reasons"]
        assert doc["unidentifiable"] == ["j6"] and doc["notes"] == []
        np.testing.assert_allclose(doc["offsets_deg"][:5], HIDDEN_DEG[:5], atol=0.005)
