"""The calibration reaches the robot's program, proved on the served cell.

``cellcal sim serve`` (a UR10e with hidden compliance of joints 2 and 3 and a gear
harmonic of joint 1; its robot moved over Modbus TCP: the served ``ur://`` RTDE server is
read-only) → ``capture frame`` → ``capture poses`` → ``calibrate`` with the effects →
``compensate --program`` writes the compensated URScript → ``validate`` runs the program's
taught waypoints as written, compensated and with calibration.conf's geometric deltas
alone, and the simulated tracker measures where the SMR went. The compensated waypoints
must land within 1.3x the calibration's validation RMS while the program as written
misses by the uncalibrated error; the geometric-only figure is reported beside them.
"""

from __future__ import annotations

import contextlib
import io
import json

import numpy as np
import pytest

from calibration.kinematics import run_chain
from calibration.visibility import solve_facing
from cellcal.cli import main
from cellcal.programs import urscript
from cellcal.programs.poses import T_to_ur
from daq.store import RunStore
from sim_drivers.model_truth import DEFAULT_TRACKER_AT_MM

from .capture_helpers import sim_serve, ur10e_controller_model
from .test_readme_workflow import _urls

SEED, HIDDEN = 6, "compliance:2,compliance:3,harmonic:1"


def _cellcal(*args: str, rc: int = 0) -> str:
    out = io.StringIO()
    with contextlib.redirect_stdout(out):
        got = main(list(args))
    assert got == rc, f"cellcal {' '.join(args)}: exit {got}\n{out.getvalue()}"
    return out.getvalue()


def taught_program(n: int = 8) -> str:
    """A URScript program: the SMR as its TCP, a joint move home, then ``n`` linear moves to
    pose literals whose SMR faces the tracker at its default place (front of the robot)."""
    model = ur10e_controller_model()
    rng = np.random.default_rng(3)
    p = np.column_stack([rng.uniform(650, 900, n), rng.uniform(-250, 250, n),
                         rng.uniform(250, 650, n)])
    seed = np.radians([0, -100, 100, -90, -90, 0])
    q, ok = solve_facing(model, p, np.asarray(DEFAULT_TRACKER_AT_MM) - p, np.zeros(n),
                         np.tile(seed, (n, 1)), (0.0, 0.0, 1.0))
    q = q[ok]
    r = run_chain(model.convention, model.dh_table(), q, model.tool_mm())
    home = ", ".join(f"{v:.6f}" for v in q[0])
    lines = ["def taught():", "  set_tcp(p[0, 0, 0.06, 0, 0, 0])", f"  movej([{home}])"]
    for pos, R in zip(r.base_p_tcp, r.base_R_flange, strict=True):
        T = np.eye(4)
        T[:3, :3], T[:3, 3] = R, pos
        lines.append("  movel(p[" + ", ".join(f"{v:.6f}" for v in T_to_ur(T)) + "])")
    return "\n".join([*lines, "end", ""])


@pytest.mark.slow
def test_compensated_program_reaches_the_validation_rms(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    (tmp_path / "taught.script").write_text(taught_program())
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
        assert comp["n_compensated"] == comp["n_targets"] >= 7
        assert "identified position is used" in comp["notes"][0]
        # the program's other text is unchanged: the compensated file parses to the same
        # targets, line for line
        before = urscript.parse_program((tmp_path / "taught.script").read_text())
        after = urscript.parse_program((tmp_path / "compensated.script").read_text())
        assert [t.line for t in after.targets] == [t.line for t in before.targets]
        out = json.loads(_cellcal("validate", "--params", "params.json", "--program",
                                  "taught.script", "--cycles", "2", "--remeasure", "0",
                                  "--no-floor", *devices, "--json"))
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
        assert len(store.samples(3).targets) == 3 * 2 * out["waypoints"]
