"""`cellcal report` from the command line."""

import json
import re

import pytest

from daq.cli import main


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
    (["--model", "ur5e", "--out", "/nonexistent/dir/r.html"], "no such directory"),
])
def test_bad_input_exits_2(c3_csv, tmp_path, capsys, extra, message):
    capsys.readouterr()
    argv = ["report", str(c3_csv), *extra]
    if "--out" not in extra:
        argv += ["--out", str(tmp_path / "r.html")]
    assert main(argv) == 2
    assert message in capsys.readouterr().err
    assert not (tmp_path / "r.html").exists()


def test_missing_data_file_exits_2(tmp_path, capsys):
    assert main(["report", str(tmp_path / "none.csv"), "--model", "ur5e",
                 "--out", str(tmp_path / "r.html")]) == 2
    assert "report" in capsys.readouterr().err
