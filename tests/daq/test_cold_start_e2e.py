"""A simulated cold start, end to end (issue 26): the robot warms up while it is captured.

The simulated UR10e (``sim://...&thermal=cold``) starts at the air's temperature; its
joints warm with its work, its links grow and its joint zeros move with them (hidden,
a few tenths of a mm over its warm-up). A capture from cold (50 simulated minutes, with
drift checks), then ``capture warmup``, then a capture that requires the warm robot, then
the validation poses at the warm state:

- the cold capture calibrates visibly worse at the warm state than the warm one;
- ``diagnose --auto`` on the cold capture adds the drift effect and comes back to within
  1.15x the noise floor at the warm state;
- the drift checks show the curve; ``--require-warm`` refuses a robot that has not warmed
  up (exit 2);
- a robot that is warm from the start (or has no thermal model) gets no drift effect.

The numbers of the seeds below (validation RMS at the warm state, mm; floor 0.026):
cold geometric 0.071 / 0.057, warm geometric 0.027 / 0.025, cold + the drift effects
0.029 / 0.027.
"""

from __future__ import annotations

import contextlib
import io
import json

import pytest

from cellcal.cli import main

pytestmark = pytest.mark.slow

GEOMETRIC = "geometric,base,tool"
DRIFT_FAMILIES = ("thermal_growth", "thermal_zero", "time_growth", "base_drift")


def _cellcal(*args: str) -> tuple[int, str]:
    out = io.StringIO()
    with contextlib.redirect_stdout(out):
        rc = main(list(args))
    return rc, out.getvalue()


def _json(*args: str) -> dict:
    rc, out = _cellcal(*args, "--json")
    assert rc == 0, out
    return json.loads(out)


def _cell(name: str, seed: int, thermal: str | None) -> list[str]:
    """The capture flags of a simulated UR10e cell (in this process), 8 s measurements."""
    extra = f"&thermal={thermal}" if thermal else ""
    return ["--model", "ur10e", "--tool-mm", "0,0,60", "--db", "c.db", "--robot",
            f"sim://robot?model=ur10e&tool=0,0,60&seed={seed}&name={name}{extra}",
            "--tracker", f"sim://tracker?seed={seed}&name={name}", "--tracker-at",
            "2500,0,500", "--remeasure", "0", "--measure-s", "8"]


def _at_warm(data: str, effects: str) -> float:
    return _json("calibrate", data, "--valid", "valid.csv", "--effects", effects)[
        "valid"]["rms_mm"]


@pytest.mark.parametrize("seed", [1, 2])
def test_cold_start_warmup_and_the_drift_effect(tmp_path, monkeypatch, seed):
    monkeypatch.chdir(tmp_path)
    cell = _cell(f"cold{seed}", seed, "cold")
    cold = _json("capture", "poses", "--count", "250", "--seed", "1", "--drift-check", "25",
                 *cell)
    assert cold["status"] == "completed" and cold["samples"] == 250 + 11
    # not warmed up yet: refused before anything moves or is stored
    rc, _ = _cellcal("capture", "poses", "--count", "5", "--require-warm", "60", *cell)
    assert rc == 2
    warm_up = _json("capture", "warmup", *cell)["summary"]["warmup"]
    assert warm_up["settled"], warm_up["reason"]
    warm = _json("capture", "poses", "--count", "250", "--seed", "2", "--require-warm", "60",
                 *cell)
    assert warm["status"] == "completed"
    assert _json("capture", "poses", "--count", "60", "--seed", "3", *cell)["samples"] == 60
    for run, csv in ((1, "cold.csv"), (3, "warm.csv"), (4, "valid.csv")):
        assert _cellcal("export", "--db", "c.db", "--out", csv, str(run))[0] == 0

    # the drift checks show the cold robot's curve, flagged
    curve = _json("runs", "--db", "c.db", "1")["drift_checks"][0]
    assert len(curve["drift_mm"]) == 11 and curve["flagged"]
    assert curve["drift_mm"][-1] > 0.1 and curve["joint_temp_c"][-1] > curve["joint_temp_c"][0]

    floor = _json("diagnose", "warm.csv")["noise_floor_mm"]
    cold_rms, warm_rms = _at_warm("cold.csv", GEOMETRIC), _at_warm("warm.csv", GEOMETRIC)
    assert warm_rms < 1.15 * floor
    assert cold_rms > 2.0 * floor and cold_rms > 1.8 * warm_rms  # visibly worse
    auto = _json("diagnose", "cold.csv", "--auto")
    added = auto["effects"][3:]
    assert "thermal_growth" in added or any(e.startswith("thermal_zero") for e in added), auto
    assert all(e.startswith(DRIFT_FAMILIES) for e in added), added
    assert _at_warm("cold.csv", ",".join(auto["effects"])) <= 1.15 * floor


@pytest.mark.parametrize(("seed", "thermal"), [(5, "warm"), (6, "warm"), (7, None), (8, None)])
def test_a_warm_robot_gets_no_drift_effect(tmp_path, monkeypatch, seed, thermal):
    monkeypatch.chdir(tmp_path)
    cell = _cell(f"warm{seed}", seed, thermal)
    assert _json("capture", "poses", "--count", "150", "--seed", "1", "--drift-check", "30",
                 *cell)["status"] == "completed"
    assert _cellcal("export", "--db", "c.db", "--out", "d.csv")[0] == 0
    auto = _json("diagnose", "d.csv", "--auto")
    assert not [e for e in auto["effects"] if e.startswith(DRIFT_FAMILIES)], auto
