"""`cellcal demo`: the whole cell on the simulator, end to end (real drivers over loopback)."""

import json

import pytest

from cellcal.cli import main
from cellcal.usecases.demo import DEMO_EFFECTS, pick_hidden, run_demo


@pytest.mark.slow
def test_demo_finds_the_hidden_effect_and_reaches_the_noise_floor(tmp_path):
    hidden = pick_hidden(3)
    with open(tmp_path / "demo.txt", "w") as stream:
        r = run_demo(tmp_path / "demo", seed=3, poses=150, valid=60, progress=None,
                     say=lambda text: print(text, file=stream, flush=True))
    assert r.hidden == hidden and r.found == hidden
    final = list(r.rms.values())[-1]
    assert final < 1.15 * r.noise_floor_mm
    assert list(r.rms)[0].startswith("uncalibrated") and r.rms[list(r.rms)[0]] > 0.5
    for f in ("store", "csv", "params", "report"):
        assert (tmp_path / "demo" / r.files[f].split("/")[-1]).stat().st_size > 0
    html = (tmp_path / "demo" / "report.html").read_text()
    assert hidden in html and html.count("<img") >= 5
    # the report tells the story: the RMS at every step first, then what each step fixed,
    # with the capture's provenance (run id from the exported CSV)
    assert html.index("<figure") == html.index('<figure id="fig-steps">')
    assert f"+ <code>{hidden}</code>" in html and 'id="fig-step-1"' in html
    assert 'id="provenance"' in html and "capture.csv" in html
    params = json.loads((tmp_path / "demo" / "params.json").read_text())
    assert hidden in [s["effect"] for s in params["auto_steps"]["steps"]]
    text = (tmp_path / "demo.txt").read_text()
    assert "[7/7]" in text and f"hidden effect: {hidden} -> found it" in text


@pytest.mark.slow
def test_demo_command(tmp_path, capsys):
    out = tmp_path / "d"
    rc = main(["demo", "--seed", "5", "--out", str(out), "--poses", "150", "--valid", "60",
               "--quiet"])
    assert rc == 0
    doc = json.loads((out / "demo.json").read_text())
    assert doc["hidden"] == doc["found"] == DEMO_EFFECTS[5 % len(DEMO_EFFECTS)]
    assert "noise floor" in capsys.readouterr().out


def test_demo_rejects_bad_options(tmp_path, capsys):
    with pytest.raises(SystemExit) as e:  # refused by the parser: at least 50
        main(["demo", "--out", str(tmp_path), "--poses", "10"])
    assert e.value.code == 2 and "--poses: 10 is not an integer 50" in capsys.readouterr().err
    assert main(["demo", "--out", str(tmp_path), "--hidden", "wobble:1"]) == 2
    assert "unknown effect family" in capsys.readouterr().err


def test_the_demo_writes_only_into_a_folder_it_owns(tmp_path):
    """Refused: a folder with other files (unless --force), and, even with --force, a
    run store the demo did not create. A folder of an earlier demo is the demo's."""
    import pytest

    from cellcal.usecases.demo_folder import DemoFolderError, check_demo_folder

    check_demo_folder(tmp_path / "new")  # a folder still to be made
    mine = tmp_path / "mine"
    mine.mkdir()
    (mine / "demo.json").write_text(json.dumps({"cellcal_demo": 1, "files": {}}))
    for name in ("cell.db", "capture.csv", "params.json", "report.html"):
        (mine / name).write_text("from an earlier demo")
    check_demo_folder(mine)
    (mine / "notes.txt").write_text("the user's")
    with pytest.raises(DemoFolderError, match="notes.txt"):
        check_demo_folder(mine)
    check_demo_folder(mine, force=True)
    user = tmp_path / "user"
    user.mkdir()
    (user / "capture.csv").write_text("the user's data")
    with pytest.raises(DemoFolderError, match="--force"):
        check_demo_folder(user)
    check_demo_folder(user, force=True)
    (user / "cell.db").write_text("the user's run store")
    with pytest.raises(DemoFolderError, match="never deletes"):
        check_demo_folder(user, force=True)
    with pytest.raises(DemoFolderError, match="not a folder"):
        check_demo_folder(user / "capture.csv")


@pytest.mark.slow
def test_cold_start_demo_shows_the_drift_and_the_diagnosis_names_it(tmp_path, capsys):
    out = tmp_path / "cold"
    rc = main(["demo", "--cold-start", "--seed", "2", "--out", str(out), "--poses", "150",
               "--valid", "60", "--quiet"])
    text = capsys.readouterr().out
    assert rc == 0, text
    assert "from cold, measuring a reference pose again every 25 points" in text
    assert "drift checks:" in text and "the robot drifted during the capture" in text
    assert "hidden effect: the warm-up (thermal drift) -> found it" in text
    doc = json.loads((out / "demo.json").read_text())
    assert doc["hidden"] == doc["found"] == "the warm-up (thermal drift)"
    stages = list(doc["valid_rms_mm"])
    assert stages[2].startswith("+ thermal_")
    assert doc["valid_rms_mm"][stages[-1]] < 1.15 * doc["noise_floor_mm"]
    assert doc["valid_rms_mm"][stages[1]] > 1.2 * doc["noise_floor_mm"]
    html = (out / "report.html").read_text()
    assert 'id="fig-joint-temps"' in html
    params = json.loads((out / "params.json").read_text())
    assert params["thermal"]["warm_state"]["joint_temp_c"][1] > 24.0


@pytest.mark.slow
def test_demo_on_the_simulated_abb(tmp_path, capsys):
    """The demo's robot behind a simulated ABB IRC5, moved over Robot Web Services through
    the RAPID server module: the same story, found at the noise floor."""
    out = tmp_path / "abb"
    rc = main(["demo", "--robot", "abb", "--seed", "5", "--out", str(out), "--poses", "150",
               "--valid", "60", "--quiet"])
    text = capsys.readouterr().out
    assert rc == 0, text
    assert "robot abb://127.0.0.1:" in text and "an ABB IRC5 over Robot Web Services" in text
    assert "a simulated ABB IRB 2600-12/1.65 with realistic hidden errors" in text
    doc = json.loads((out / "demo.json").read_text())
    assert doc["hidden"] == doc["found"] == pick_hidden(5, "abb")
    assert list(doc["valid_rms_mm"].values())[-1] < 1.15 * doc["noise_floor_mm"]
