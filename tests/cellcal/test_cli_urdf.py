"""The URDF commands of docs/urdf.md, run as written, and refused URDFs at the command line."""

import re
import shlex
import subprocess
import sys
from pathlib import Path

import pytest

from calibration import load_model
from cellcal.cli import main
from tests.calibration.test_urdf_model import BAD
from tests.calibration.urdf_writers import ur_style_urdf

DOC = Path(__file__).resolve().parents[2] / "docs" / "urdf.md"


def doc_commands() -> list[list[str]]:
    """Every ``cellcal ...`` line of the first ``sh`` block of docs/urdf.md."""
    block = re.search(r"```sh\n(.*?)```", DOC.read_text(), re.S).group(1)
    return [shlex.split(line)[1:] for line in block.splitlines() if line.startswith("cellcal ")]


def test_the_documented_commands_run_and_every_export_passes_its_parity_check(
        tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    ur_style_urdf(tmp_path / "robot.urdf", load_model("ur10e"))
    commands = doc_commands()
    assert len(commands) >= 6
    out = ""
    for argv in commands:
        assert main(argv) == 0, argv
        out += capsys.readouterr().out
    parity = [float(v) for v in re.findall(r"parity .*?: max ([0-9.e+-]+) mm", out)]
    assert len(parity) == 6  # urdf, table, calibration.conf, UR yaml, panda urdf, panda table
    assert max(parity) <= 1e-6
    assert "not exported: compliance:2: not a fixed kinematic parameter" in out
    for f in ("calibrated.urdf", "table.csv", "calibration.conf", "kinematics.yaml",
              "panda_calibrated.urdf", "panda_mdh.csv"):
        assert (tmp_path / f).stat().st_size > 0
    # the calibrated URDF is itself a model: its chain down to the measured point
    cal = load_model("calibrated.urdf#base_link:tcp")
    assert cal.n_joints == 6 and cal.urdf.joints[0] == "shoulder_pan_joint"
    assert "hash: calib_" in (tmp_path / "kinematics.yaml").read_text()


@pytest.mark.parametrize("case", list(BAD))
def test_bad_urdfs_exit_2_with_one_line_naming_the_element(tmp_path, case, capsys):
    text, suffix, expected = BAD[case]
    p = tmp_path / "bad.urdf"
    if text is not None:
        p.write_text(text)
    argv = ["simulate", "--model", f"{p}{suffix}", "--out", str(tmp_path / "m.csv"),
            "--poses", "5", "--valid", "0"]
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and expected in err, err
    assert not (tmp_path / "m.csv").exists()
    if case == "malformed":  # and as a process: exit code 2, one line, no traceback
        r = subprocess.run([sys.executable, "-m", "cellcal", *argv], capture_output=True, text=True,
                           timeout=120)
        assert r.returncode == 2 and r.stderr.count("\n") == 1 and expected in r.stderr
