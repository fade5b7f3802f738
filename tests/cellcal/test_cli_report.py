"""`cellcal report` from the command line."""

import json
import re

import pytest

from cellcal.cli import main


@pytest.fixture(scope="module")
def c3_csv(tmp_path_factory):
    path = tmp_path_factory.mktemp("report") / "c3.csv"
    assert main(["simulate", "--model", "ur5e", "--hidden", "compliance:3", "--poses", "300",
                 "--valid", "300", "--out", str(path)]) == 0
    return path


def test_report_names_the_hidden_compliance(c3_csv, tmp_path, capsys):
    capsys.readouterr()
    out = tmp_path / "r.html"
    assert main(["report", str(c3_csv), "--model", "ur5e", "--out", str(out), "--json"]) == 0
    doc = json.loads(capsys.readouterr().out)
    assert doc["out"] == str(out) and doc["bytes"] == out.stat().st_size < 3e6
    assert doc["next_effects"] == "geometric,base,tool,compliance:3"
    assert [s["label"] for s in doc["stages"]] == [
        "uncalibrated", "current model", "current model + compliance:3"]
    page = out.read_text()
    assert "compliance:3" in page and "Compliance of joint 3" in page
    assert "https://" not in page and "http://" not in page
    assert len(re.findall(r'<img [^>]*src="data:image/png;base64,', page)) == \
        page.count("<img") == len(doc["figures"])


def test_report_with_params_and_text_output(c3_csv, tmp_path, capsys):
    params = tmp_path / "p.json"
    assert main(["calibrate", str(c3_csv), "--model", "ur5e", "--effects",
                 "geometric,base,tool,compliance:3", "--out", str(params), "--json"]) == 0
    capsys.readouterr()
    out = tmp_path / "p.html"
    assert main(["report", str(c3_csv), "--model", "ur5e", "--params", str(params),
                 "--out", str(out)]) == 0
    text = capsys.readouterr().out
    assert "given parameters" in text and f"wrote {out}" in text
    assert "given parameters" in out.read_text()


def test_unknown_solver_is_refused_by_the_parser_with_the_choices(c3_csv, capsys):
    with pytest.raises(SystemExit) as e:
        main(["report", str(c3_csv), "--model", "ur5e", "--solver", "nosuch"])
    assert e.value.code == 2 and "choose from 'lm', 'ridge'" in capsys.readouterr().err


@pytest.mark.parametrize("extra, message", [
    (["--model", "nosuchrobot"], "unknown model"),
    (["--model", "ur5e", "--effects", "geometric,nosuch"], "unknown effect"),
    (["--model", "ur5e", "--sigma", "-1"], "--sigma"),
    (["--model", "ur5e", "--params", "/nonexistent/p.json"], "no such file"),
    (["--model", "ur5e", "--out", "/nonexistent/dir/r.html"], "does not exist"),
])
def test_bad_input_exits_2(c3_csv, tmp_path, capsys, extra, message):
    capsys.readouterr()
    argv = ["report", str(c3_csv), *extra]
    if "--out" not in extra:
        argv += ["--out", str(tmp_path / "r.html")]
    try:
        rc = main(argv)
    except SystemExit as e:  # refused by the parser (a number out of range)
        rc = e.code
    assert rc == 2
    assert message in capsys.readouterr().err
    assert not (tmp_path / "r.html").exists()


def test_missing_data_file_exits_2(tmp_path, capsys):
    assert main(["report", str(tmp_path / "none.csv"), "--model", "ur5e",
                 "--out", str(tmp_path / "r.html")]) == 2
    assert "report" in capsys.readouterr().err


def _sha256(path) -> str:
    import hashlib

    return hashlib.sha256(path.read_bytes()).hexdigest()


def test_provenance_names_the_file_its_hash_and_the_run(c3_csv, tmp_path, capsys):
    data = tmp_path / "run.csv"
    data.write_text("# run: 42\n" + c3_csv.read_text())
    out = tmp_path / "r.html"
    capsys.readouterr()
    assert main(["report", str(data), "--model", "ur5e", "--out", str(out), "--json"]) == 0
    doc = json.loads(capsys.readouterr().out)
    prov = doc["provenance"]
    assert prov["data_sha256"] == _sha256(data) and prov["data_file"] == str(data)
    assert prov["run_id"] == "42" and prov["model"] == "ur5e"
    assert prov["software"].startswith("cellcal ") and prov["created"].endswith("+00:00")
    page = out.read_text()
    block = re.search(r'<dl class="prov" id="provenance">(.*?)</dl>', page, re.S)[1]
    assert _sha256(data) in block and ">42<" in block and str(data) in block
    # a file without a run says so
    capsys.readouterr()
    assert main(["report", str(c3_csv), "--model", "ur5e", "--out", str(out)]) == 0
    assert "not recorded in the data file" in out.read_text()


def test_auto_steps_recorded_by_diagnose_show_in_the_report(tmp_path, capsys):
    data = tmp_path / "two.csv"
    assert main(["simulate", "--model", "ur5e", "--hidden", "compliance:3,harmonic2:4",
                 "--poses", "250", "--valid", "150", "--blunders", "0.02",
                 "--out", str(data)]) == 0
    params = tmp_path / "auto.json"
    capsys.readouterr()
    assert main(["diagnose", str(data), "--model", "ur5e", "--auto", "--out", str(params),
                 "--json"]) == 0
    auto = json.loads(capsys.readouterr().out)
    recorded = json.loads(params.read_text())["auto_steps"]
    assert [s["effect"] for s in recorded["steps"]] == [s["effect"] for s in auto["steps"]]
    assert recorded["start_effects"] == auto["start_effects"]
    assert {"compliance:3", "harmonic2:4"} <= {s["effect"] for s in auto["steps"]}
    out = tmp_path / "p.html"
    assert main(["report", str(data), "--model", "ur5e", "--params", str(params),
                 "--out", str(out), "--json"]) == 0
    doc = json.loads(capsys.readouterr().out)
    k = len(auto["steps"])
    assert doc["steps"]["recorded"] is True
    assert [s["effect"] for s in doc["steps"]["steps"]] == [None] + [
        s["effect"] for s in auto["steps"]]
    assert doc["figures"][0] == "fig-steps"
    assert doc["figures"][1:k + 1] == [f"fig-step-{i}" for i in range(1, k + 1)]
    assert doc["provenance"]["params_sha256"] == _sha256(params)
    # the last step is the given parameters: the same numbers as diagnose reported
    assert doc["steps"]["steps"][-1]["calib_rms_mm"] == pytest.approx(
        auto["steps"][-1]["calib_rms_mm"], rel=1e-6)
    page = out.read_text()
    assert "Replayed from the steps recorded" in page
    # the blunders diagnose left out are listed in the report too
    left = {o["pose_id"] for o in auto["outliers"]}
    assert left and left <= {o["pose_id"] for o in doc["outliers"]}
    assert all(f"<code>{p}</code>" in page for p in left)


def test_report_auto_from_the_command_line(c3_csv, tmp_path, capsys):
    out = tmp_path / "a.html"
    capsys.readouterr()
    assert main(["report", str(c3_csv), "--model", "ur5e", "--auto", "--max-steps", "1",
                 "--out", str(out)]) == 0
    text = capsys.readouterr().out
    assert "+ compliance:3" in text and "automatic diagnosis:" in text
    assert "maximum of 1 steps" in text
    page = out.read_text()
    assert page.index("<figure") == page.index('<figure id="fig-steps">')
    assert 'id="fig-step-1"' in page and 'id="fig-step-2"' not in page


@pytest.mark.parametrize("extra, message", [
    (["--max-steps", "3"], "need --auto"),
    (["--auto", "--max-steps", "0"], "--max-steps"),
    (["--auto", "--budget-s", "-1"], "--budget-s"),
])
def test_bad_auto_options_exit_2(c3_csv, tmp_path, capsys, extra, message):
    capsys.readouterr()
    out = tmp_path / "r.html"
    assert main(["report", str(c3_csv), "--model", "ur5e", "--out", str(out), *extra]) == 2
    assert message in capsys.readouterr().err
    assert not out.exists()


def test_report_never_overwrites_its_input(c3_csv, capsys):
    before = c3_csv.read_bytes()
    assert main(["report", str(c3_csv), "--model", "ur5e", "--out", str(c3_csv)]) == 2
    assert "is an input of this command" in capsys.readouterr().err
    assert c3_csv.read_bytes() == before
