"""``cellcal check``: a calibration's error on new poses, exactly as calibrated.

The parity: what ``check`` says of a params.json on new poses is what ``calibrate --valid``
said of the same poses when it wrote that params.json (to 1e-9 mm). Only the base is ever
refitted, when asked or when the data recorded another measurement frame; ``--tolerance-mm``
exits 1 naming the poses beyond it; ``--db`` records the check and ``history`` shows it.
With the calibrated envelope in the params.json the figures are split inside and outside
it as ``calibrate --valid`` splits its validation poses, and every pose beyond it is named
(``outside_range``); without one a note says so."""

from __future__ import annotations

import json

import numpy as np
import pytest

from calibration import ErrorModel, load_csv, load_model
from calibration.fit.identify import error_stats
from calibration.fit.simulate import random_joints, realistic_truth, simulate
from calibration.model.transforms import rotvec_to_matrix
from cellcal.cli import main
from daq.store import RunStore
from tests.corpus.cases import narrowed_params

STATS = ("n", "rms_mm", "mean_mm", "p95_mm", "max_mm")
#: the calibration's measurement frame (as a frame run records it) and another one
T_CAL = np.eye(4)
T_CAL[:3, :3] = rotvec_to_matrix(np.array([0.1, -0.4, 2.0]))
T_CAL[:3, 3] = [2200.0, -350.0, 400.0]
MOVE = np.eye(4)
MOVE[:3, :3] = rotvec_to_matrix(np.array([0.02, 0.05, -0.6]))
MOVE[:3, 3] = [-900.0, 1200.0, 35.0]


def _meta(T: np.ndarray, frame_run: int, store: str = "cell.db") -> str:
    rows = ", ".join(f"{v:.10g}" for v in T[:3].ravel())
    return (f"# store: {store}\n# frame_run: {frame_run}\n# tracker_T_base: {rows}\n"
            "# robot_id: cell-3/UR10e\n")


def _write(data, path, header: str = "") -> None:
    data.to_csv(path)
    if header:
        path.write_text(header + path.read_text())


@pytest.fixture(scope="module")
def files(tmp_path_factory):
    """cal.csv (300 poses) and new.csv (200 later poses) of one simulated UR10e with a hidden
    compliance of joint 2, a backlash of joint 3 and a base drifting over time; moved.csv is
    new.csv measured from another tracker station (its frame recorded so)."""
    d = tmp_path_factory.mktemp("check")
    m = load_model("ur10e")
    em = ErrorModel(m, "geometric,base,tool,compliance:2,backlash:3,base_drift")
    rng = np.random.default_rng(11)
    x = realistic_truth(em, rng)
    q = random_joints(m, 500, rng)
    data = simulate(em, x, q, 0.015, rng, t_s=1.7e9 + 30.0 * np.arange(500))
    cal, new = data.subset(np.arange(500) < 300), data.subset(np.arange(500) >= 300)
    _write(cal, d / "cal.csv", _meta(T_CAL, 1))
    _write(new, d / "new.csv", _meta(T_CAL, 1))
    moved = new.subset(np.ones(new.n, bool))
    moved.tracker_p_smr = new.tracker_p_smr @ MOVE[:3, :3].T + MOVE[:3, 3]
    _write(moved, d / "moved.csv", _meta(MOVE @ T_CAL, 5))
    return d


def _json(capsys, argv, rc=0):
    assert main(argv) == rc, capsys.readouterr().err
    return json.loads(capsys.readouterr().out)


@pytest.mark.parametrize("effects", ["geometric,base,tool",
                                     "geometric,base,tool,compliance:2,backlash:3,base_drift"])
def test_check_meets_the_calibrations_own_validation_figures(files, tmp_path, capsys,
                                                             effects):
    params = tmp_path / "p.json"
    cal = _json(capsys, ["calibrate", str(files / "cal.csv"), "--model", "ur10e", "--effects",
                         effects, "--valid", str(files / "new.csv"), "--out", str(params),
                         "--json"])
    out = _json(capsys, ["check", "--params", str(params), str(files / "new.csv"), "--json"])
    for key in STATS:
        assert out[key] == pytest.approx(cal["valid"][key], abs=1e-9, rel=0), key
    assert out["refitted"] == [] and out["within_tolerance"] is None
    assert out["frame"]["same"] is True and "frame run 1 of cell.db" in out["frame"]["reason"]
    assert out["calibration"] == {"calib_rms_mm": cal["calib"]["rms_mm"],
                                  "valid_rms_mm": cal["valid"]["rms_mm"]}
    assert len(out["poses"]) == 200
    errors = np.array([p["error_mm"] for p in out["poses"]])
    assert np.sqrt(np.mean(errors**2)) == pytest.approx(out["rms_mm"], abs=1e-12)
    assert out["worst"][0]["error_mm"] == pytest.approx(out["max_mm"])


def test_check_on_full_pose_data_meets_calibrate(tmp_path, capsys):
    m = load_model("ur10e")
    em = ErrorModel(m, "geometric,base,tool,tool_rotation")
    rng = np.random.default_rng(5)
    x = realistic_truth(em, rng)
    data = simulate(em, x, random_joints(m, 260, rng), 0.015, rng, sigma_deg=0.01)
    _write(data.subset(np.arange(260) < 180), tmp_path / "cal.csv")
    _write(data.subset(np.arange(260) >= 180), tmp_path / "new.csv")
    params = tmp_path / "p.json"
    cal = _json(capsys, ["calibrate", str(tmp_path / "cal.csv"), "--model", "ur10e", "--valid",
                         str(tmp_path / "new.csv"), "--out", str(params), "--json"])
    assert "tool_rotation" in cal["effects"]
    out = _json(capsys, ["check", "--params", str(params), str(tmp_path / "new.csv"), "--json"])
    for key in (*STATS, "orientation_rms_deg", "orientation_mean_deg", "orientation_max_deg"):
        assert out[key] == pytest.approx(cal["valid"][key], abs=1e-9, rel=0), key


def test_only_the_base_is_refitted_when_the_tracker_moved(files, tmp_path, capsys):
    params = tmp_path / "p.json"
    assert main(["calibrate", str(files / "cal.csv"), "--model", "ur10e", "--out",
                 str(params)]) == 0
    capsys.readouterr()
    given = _json(capsys, ["check", "--params", str(params), str(files / "new.csv"), "--json"])
    asked = _json(capsys, ["check", "--params", str(params), str(files / "new.csv"), "--json",
                           "--refit-base"])
    assert asked["refitted"] == ["base"] and asked["refit_reason"] == "asked (--refit-base)"
    assert asked["base_shift_mm"] < 0.5 and asked["rms_mm"] <= given["rms_mm"]
    # measured from elsewhere: the frame says so, the base is refitted by itself
    moved = _json(capsys, ["check", "--params", str(params), str(files / "moved.csv"),
                           "--json"])
    assert moved["frame"]["same"] is False and moved["refitted"] == ["base"]
    assert "the tracker was moved" in moved["refit_reason"]
    assert moved["frame"]["distance_mm"] > 100
    assert moved["rms_mm"] == pytest.approx(asked["rms_mm"], abs=1e-6)
    assert moved["base_turn_deg"] == pytest.approx(np.degrees(0.6), abs=1.0)
    assert main(["check", "--params", str(params), str(files / "moved.csv")]) == 0
    text = capsys.readouterr().out
    assert "base refitted (the tracker-to-base transform only)" in text.splitlines()[0]
    assert "refitted  base: frame run 5 of cell.db of the data is" in text
    # the geometry was not refitted: the same robot, measured from elsewhere, as accurate
    assert moved["rms_mm"] < 2 * given["rms_mm"]


def test_frames_within_the_tolerance_are_one_frame(files, tmp_path, capsys):
    params = tmp_path / "p.json"
    assert main(["calibrate", str(files / "cal.csv"), "--model", "ur10e", "--out",
                 str(params)]) == 0
    capsys.readouterr()
    near = T_CAL.copy()
    near[:3, 3] += [0.03, -0.02, 0.01]  # the frame routine run again, the tracker in place
    body = (files / "new.csv").read_text().split("# robot_id", 1)[1]
    again = tmp_path / "again.csv"
    again.write_text(_meta(near, 7).split("# robot_id")[0] + "# robot_id" + body)
    out = _json(capsys, ["check", "--params", str(params), str(again), "--json"])
    assert out["frame"]["same"] is True and out["refitted"] == []
    assert "frame run 7 of cell.db of the data is within" in out["frame"]["reason"]
    bare = tmp_path / "bare.csv"  # a file that says nothing of its frame
    bare.write_text("\n".join(ln for ln in again.read_text().splitlines()
                              if not ln.startswith("#")) + "\n")
    out = _json(capsys, ["check", "--params", str(params), str(bare), "--json"])
    assert out["frame"]["same"] is None and out["refitted"] == []
    assert "the data recorded no measurement frame" in out["frame"]["reason"]


def test_tolerance_exits_1_naming_the_worst_poses(files, tmp_path, capsys):
    params = tmp_path / "p.json"
    assert main(["calibrate", str(files / "cal.csv"), "--model", "ur10e", "--out",
                 str(params)]) == 0
    capsys.readouterr()
    base = ["check", "--params", str(params), str(files / "new.csv")]
    rms = _json(capsys, [*base, "--json"])["rms_mm"]
    out = _json(capsys, [*base, "--json", "--tolerance-mm", f"{rms * 0.8:.6f}"], rc=1)
    assert out["within_tolerance"] is False and out["n_beyond_tolerance"] > 0
    assert len(out["worst"]) == min(10, out["n_beyond_tolerance"])
    assert all(w["error_mm"] > rms * 0.8 for w in out["worst"])
    assert main([*base, "--tolerance-mm", f"{rms * 0.8:.6f}"]) == 1
    text = capsys.readouterr().out
    line = next(ln for ln in text.splitlines() if ln.startswith("tolerance"))
    assert "BEYOND" in line and out["worst"][0]["pose_id"] in line
    out = _json(capsys, [*base, "--json", "--tolerance-mm", f"{rms * 1.2:.6f}"])
    assert out["within_tolerance"] is True


def test_check_is_recorded_and_history_shows_accuracy_over_time(files, store_address,
                                                                tmp_path, capsys):
    params = tmp_path / "p.json"
    assert main(["calibrate", str(files / "cal.csv"), "--model", "ur10e", "--out", str(params),
                 "--db", store_address, "--robot-id", "R7"]) == 0
    capsys.readouterr()
    argv = ["check", "--params", str(params), str(files / "new.csv"), "--db", store_address,
            "--robot-id", "R7", "--tolerance-mm", "1", "--json"]
    first = _json(capsys, argv)
    rec = first["recorded"]
    assert rec["robot_id"] == "R7" and rec["new"] is True and rec["calibration"] == 1
    assert _json(capsys, argv)["recorded"] == {**rec, "new": False}  # recorded once
    moved = _json(capsys, [*argv[:3], str(files / "moved.csv"), *argv[4:]])
    # data exported from a run name their robot: no --robot-id needed
    other = _json(capsys, ["check", "--params", str(params), str(files / "new.csv"), "--db",
                           store_address, "--json"])
    assert other["recorded"]["robot_id"] == "cell-3/UR10e"
    assert other["recorded"]["calibration"] is None  # calibrated as R7, not as this robot
    with RunStore(store_address) as st:
        c1, c2 = st.checks("R7")
    assert c1.t == pytest.approx(1.7e9 + 30.0 * 499)  # when the poses were measured
    assert (c1.n, c1.rms_mm, c1.within_tolerance, c1.refitted) == \
        (200, first["rms_mm"], True, ())
    assert c2.refitted == ("base",) and c2.rms_mm == pytest.approx(moved["rms_mm"])
    assert c1.result["rms_mm"] == first["rms_mm"] and "poses" not in c1.result
    hist = _json(capsys, ["history", "R7", "--db", store_address, "--json"])
    assert [c["id"] for c in hist["checks"]] == [c1.id, c2.id]
    assert hist["checks"][0]["calibration"] == hist["calibrations"][0]["id"]
    assert hist["checks"][1]["refitted"] == ["base"]
    assert main(["history", "R7", "--db", store_address]) == 0
    text = capsys.readouterr().out
    assert "accuracy on new poses (`cellcal check`):" in text
    assert "RMS over the checks:" in text and "1: within" in text
    # a robot with checks and no calibration shows its checks
    assert main(["history", "cell-3/UR10e", "--db", store_address]) == 0
    assert "no calibrations, 1 check(s)" in capsys.readouterr().out
    assert main(["history", "cell-3/UR10e", "--db", store_address, "--plot",
                 str(tmp_path / "h.html")]) == 2


def test_check_refuses_what_it_cannot_use(files, tmp_path, capsys):
    params = tmp_path / "p.json"
    assert main(["calibrate", str(files / "cal.csv"), "--model", "ur10e", "--effects",
                 "geometric,tool", "--out", str(params)]) == 0
    capsys.readouterr()
    new = str(files / "new.csv")
    assert main(["check", "--params", str(params), new, "--refit-base"]) == 2
    assert "no base effect" in capsys.readouterr().err
    assert main(["check", "--params", str(params), new, "--robot-id", "R1"]) == 2
    assert "--robot-id needs --db" in capsys.readouterr().err
    assert main(["check", "--params", str(params), new, "--model", "panda"]) == 2
    capsys.readouterr()
    with pytest.raises(SystemExit) as e:
        main(["check", new])  # --params is required
    assert e.value.code == 2
    capsys.readouterr()
    # the measured frame changed but nothing can take it up: said, not refitted
    assert main(["check", "--params", str(params), str(files / "moved.csv")]) == 0
    assert "no base effect to refit" in capsys.readouterr().err


def test_diagnose_with_params_reports_the_given_models_error_first(files, tmp_path, capsys):
    """``diagnose --params`` ranks what a refit leaves; its first lines say so, after the
    given model's own error (the one ``check`` gives)."""
    params = tmp_path / "p.json"
    assert main(["calibrate", str(files / "cal.csv"), "--model", "ur10e", "--out",
                 str(params)]) == 0
    capsys.readouterr()
    check = _json(capsys, ["check", "--params", str(params), str(files / "new.csv"), "--json"])
    diag = _json(capsys, ["diagnose", str(files / "new.csv"), "--model", "ur10e", "--params",
                          str(params), "--json", "--top", "3"])
    assert diag["given"]["rms_mm"] == check["rms_mm"] and diag["given"]["n"] == 200
    assert diag["refitted"] is True and diag["rms_mm"] < check["rms_mm"]
    assert main(["diagnose", str(files / "new.csv"), "--model", "ur10e", "--params",
                 str(params), "--top", "3"]) == 0
    lines = capsys.readouterr().out.splitlines()
    assert lines[1].startswith(f"given     RMS {check['rms_mm']:.4f} mm")
    assert "nothing refitted" in lines[1]
    assert lines[2].startswith("refit     the figures below are of a refit")
    assert lines[3].startswith("error     RMS") and "(refitted)" in lines[3]
    # without --params the fit is the diagnosis' own: nothing more is said
    assert main(["diagnose", str(files / "new.csv"), "--model", "ur10e", "--top", "3"]) == 0
    lines = capsys.readouterr().out.splitlines()
    assert lines[1].startswith("error     RMS") and "refitted" not in lines[1]


def _same_stats(got, want):
    """Two statistics objects of the split agree (to 1e-9 mm; null figures when n is 0)."""
    for key in STATS:
        if want[key] is None:
            assert got[key] is None, key
        else:
            assert got[key] == pytest.approx(want[key], abs=1e-9, rel=0), key


@pytest.mark.parametrize("effects", ["geometric,base,tool",
                                     "geometric,base,tool,compliance:2,backlash:3,base_drift"])
def test_check_splits_its_figures_as_calibrate_splits_its_validation(files, tmp_path, capsys,
                                                                    effects):
    """The same model on the same poses: check's figures inside and outside the envelope
    are calibrate --valid's (the joints beyond it; with base_drift, the later times)."""
    params = tmp_path / "p.json"
    cal = _json(capsys, ["calibrate", str(files / "cal.csv"), "--model", "ur10e", "--effects",
                         effects, "--valid", str(files / "new.csv"), "--out", str(params),
                         "--json"])
    out = _json(capsys, ["check", "--params", str(params), str(files / "new.csv"), "--json"])
    assert out["envelope"] == cal["envelope"] == json.loads(params.read_text())["envelope"]
    _same_stats(out["inside"], cal["valid_inside"])
    _same_stats(out["outside"], cal["valid_outside"])
    assert out["outside"]["by_quantity"] == cal["valid_outside"]["by_quantity"]
    assert out["outside"]["n"] > 0  # the split is not empty on either data set
    assert out["n_outside_range"] == out["outside"]["n"]
    beyond = [p for p in out["poses"] if p["outside_range"]]
    assert len(beyond) == out["outside"]["n"]
    if "base_drift" in effects:  # measured after the calibration: every pose beyond it
        assert out["inside"]["n"] == 0 and all("t_s" in p["outside_range"] for p in beyond)
    by_id = {p["pose_id"]: p["outside_range"] for p in out["poses"]}
    assert all(w["outside_range"] == by_id[w["pose_id"]] for w in out["worst"])


def test_a_narrowed_envelope_splits_the_figures_and_names_the_poses(files, tmp_path, capsys):
    assert main(["calibrate", str(files / "cal.csv"), "--model", "ur10e", "--out",
                 str(tmp_path / "params.json")]) == 0
    capsys.readouterr()
    narrow = tmp_path / "narrow.json"
    narrow.write_text(narrowed_params(tmp_path))  # joint 2 cut to [0, 0.1] deg
    new = str(files / "new.csv")
    out = _json(capsys, ["check", "--params", str(narrow), new, "--json"])
    assert out["inside"]["n"] == 0 and out["inside"]["rms_mm"] is None
    assert out["outside"]["by_quantity"]["q2"] == 200 and out["n_outside_range"] == 200
    _same_stats(out["outside"], out)  # every pose beyond it
    assert all("q2" in p["outside_range"] for p in out["poses"])
    # the worst poses named on failure carry what of them lies beyond the envelope
    failed = _json(capsys, ["check", "--params", str(narrow), new, "--json",
                            "--tolerance-mm", f"{out['rms_mm'] * 0.8:.6f}"], rc=1)
    assert failed["worst"] and all("q2" in w["outside_range"] for w in failed["worst"])
    assert main(["check", "--params", str(narrow), new, "--tolerance-mm",
                 f"{out['rms_mm'] * 0.8:.6f}"]) == 1
    text = capsys.readouterr().out
    assert "  inside the envelope" in text and "  outside the envelope" in text
    line = next(ln for ln in text.splitlines() if ln.startswith("outside "))
    assert line.startswith("outside   200 of 200 poses lie beyond the envelope (")
    assert "q2: 200" in line and line.endswith("): the calibration did not measure there")
    tol = next(ln for ln in text.splitlines() if ln.startswith("tolerance"))
    first = failed["worst"][0]
    assert (f"{first['pose_id']} (line {first['line']}) {first['error_mm']:.3f} mm (outside "
            f"{';'.join(first['outside_range'])})") in tol
    # cut at the median of joint 2: the inside figures are those of the poses inside
    doc = json.loads(narrow.read_text())
    q2 = np.degrees(load_csv(new, load_model("ur10e")).q[:, 1])
    doc["envelope"]["joints_deg"][1] = [-400.0, float(np.median(q2))]
    half = tmp_path / "half.json"
    half.write_text(json.dumps(doc))
    out = _json(capsys, ["check", "--params", str(half), new, "--json"])
    inside = [p for p in out["poses"] if not p["outside_range"]]
    assert out["inside"]["n"] == len(inside) >= 90
    resid = np.array([[p["dx_mm"], p["dy_mm"], p["dz_mm"]] for p in inside])
    _same_stats(out["inside"], error_stats(resid))
    assert out["outside"]["by_quantity"]["q2"] == 100
    assert main(["check", "--params", str(half), new]) == 0
    text = capsys.readouterr().out
    assert f"outside   {200 - len(inside)} of 200 poses lie beyond the envelope (" in text


def test_without_an_envelope_check_says_so(files, tmp_path, capsys):
    params = tmp_path / "p.json"
    assert main(["calibrate", str(files / "cal.csv"), "--model", "ur10e", "--out",
                 str(params)]) == 0
    capsys.readouterr()
    doc = json.loads(params.read_text())
    doc.pop("envelope")
    old = tmp_path / "old.json"
    old.write_text(json.dumps(doc))
    note = (f"{old} records no calibrated envelope (written before cellcal recorded one): the "
            "poses are not checked against the ranges the calibration measured; calibrate "
            "again to have them checked")
    assert main(["check", "--params", str(old), str(files / "new.csv")]) == 0
    captured = capsys.readouterr()
    assert f"note: {note}" in captured.err
    assert "the envelope" not in captured.out
    out = _json(capsys, ["check", "--params", str(old), str(files / "new.csv"), "--json"])
    assert note in out["notes"]
    assert out["envelope"] is None and out["inside"] is None and out["outside"] is None
    assert out["n_outside_range"] == 0
    assert all(p["outside_range"] == [] for p in out["poses"])
