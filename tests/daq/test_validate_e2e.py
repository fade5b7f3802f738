"""The calibration reaches the robot's program, proved on the served cell.

``cellcal sim serve`` (a UR10e with hidden compliance of joints 2 and 3 and a gear
harmonic of joint 1; its robot moved over Modbus TCP: the served ``ur://`` RTDE server is
read-only) → ``capture frame`` → ``capture poses`` → ``calibrate`` with the effects →
``compensate --program`` writes the compensated URScript → ``validate`` runs the taught
waypoints of examples/taught.script as written, compensated and with calibration.conf's
geometric deltas alone, and the simulated tracker measures where the SMR went. The
compensated waypoints must land within 1.3x the calibration's validation RMS while the
program as written misses by the uncalibrated error; the geometric-only figure is
reported beside them.
"""

from __future__ import annotations

import contextlib
import io
import json

import pytest

from cellcal.cli import main
from cellcal.programs import urscript
from daq.store import RunStore

from .capture_helpers import ROOT, sim_serve
from .test_readme_workflow import _urls

SEED, HIDDEN = 6, "compliance:2,compliance:3,harmonic:1"
#: taught targets whose SMR faces the tracker at the simulated cell's default place
PROGRAM = ROOT / "examples" / "taught.script"


def _cellcal(*args: str, rc: int = 0) -> str:
    out = io.StringIO()
    with contextlib.redirect_stdout(out):
        got = main(list(args))
    assert got == rc, f"cellcal {' '.join(args)}: exit {got}\n{out.getvalue()}"
    return out.getvalue()


@pytest.mark.slow
def test_compensated_program_reaches_the_validation_rms(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    (tmp_path / "taught.script").write_bytes(PROGRAM.read_bytes())
    with sim_serve("--seed", str(SEED), "--hidden", HIDDEN, "--no-pty", "--no-rtde") as serve:
        urls = _urls(serve)
        R = next(u for u in urls if u.startswith("modbus+tcp://"))
        T = next(u for u in urls if u.startswith("tracker+tcp://"))
        devices = ["--robot", R, "--tracker", T, "--db", "cell.db"]
        common = ["--model", "ur10e", "--tool-mm", "0,0,60", *devices]
        _cellcal("capture", "frame", "--tracker-at", "2500,0,500", *common)
        _cellcal("capture", "poses", "--count", "240", "--valid-fraction", "0.25", "--seed",
                 str(SEED), "--remeasure", "0", *common)
        _cellcal("export", "--db", "cell.db", "--out", "capture.csv")
        fit = json.loads(_cellcal("calibrate", "capture.csv", "--effects",
                                  "geometric,base,tool," + HIDDEN, "--out", "params.json",
                                  "--json"))
        valid_rms = fit["valid"]["rms_mm"]
        comp = json.loads(_cellcal("compensate", "--params", "params.json", "--program",
                                   "taught.script", "--out", "compensated.script", "--json"))
        assert comp["written"] and not comp["refused"], comp
        assert comp["n_compensated"] == comp["n_targets"] == 8
        assert "identified position is used" in comp["notes"][0]
        # the program's other text is unchanged: the compensated file parses to the same
        # targets, line for line
        before = urscript.parse_program((tmp_path / "taught.script").read_text())
        after = urscript.parse_program((tmp_path / "compensated.script").read_text())
        assert [t.line for t in after.targets] == [t.line for t in before.targets]
        out = json.loads(_cellcal("validate", "--params", "params.json", "--program",
                                  "taught.script", "--cycles", "2", "--remeasure", "0",
                                  *devices, "--json"))
    v = out["validation"]
    assert out["status"] == "completed" and out["calibration_valid_rms_mm"] == valid_rms
    e_u, e_c, e_g = (v[k]["rms_mm"] for k in ("uncompensated", "compensated", "geometric"))
    print(f"\nvalidate: {out['waypoints']} waypoints x 2 cycles: uncompensated {e_u:.3f} mm, "
          f"compensated {e_c:.3f} mm, geometric only {e_g:.3f} mm; validation RMS "
          f"{valid_rms:.4f} mm (uncalibrated {fit['uncalibrated']['valid']['rms_mm']:.3f} "
          f"mm); AP max {v['compensated']['ap_max_mm']:.3f} mm, RP max "
          f"{v['compensated']['rp_max_mm']:.3f} mm; {out['notes'][-1]}")
    assert e_c <= 1.3 * valid_rms, (e_c, valid_rms)
    assert e_u > 10 * valid_rms
    assert e_g > 2 * e_c
    assert v["compensated"]["rp_max_mm"] is not None  # two cycles: RP per waypoint
    with RunStore(tmp_path / "cell.db") as store:  # the measurements are a run
        run = store.run(3)
        assert run.routine == "validate" and run.summary.validation is not None
        assert len(store.samples(3).target) == 3 * 2 * out["waypoints"]
