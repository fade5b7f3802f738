"""The corpus's workspace: a folder of good input files every bad input is made from.

Built once per session (:func:`build`) through public APIs that exist since the first
release of the formats (so the same corpus also runs against an older cellcal, for the
before/after tally), then copied for every case (:func:`copy_workspace`).

Files
    good.csv        ur5 measurement CSV: 60 calibration + 30 validation poses (simulated)
    ur10e.csv       ur10e measurement CSV: 60 poses
    params.json     `cellcal calibrate good.csv --model ur5 --out params.json`
    params_ur10e.json   the same for ur10e.csv (a calibration of another model)
    model.yaml      the ur5 model as a YAML file
    targets.csv     ur5 targets: x, y, z and nominal joints
    postures.csv    20 ur10e zero-point postures (simulated)
    zero.json       `cellcal zero postures.csv --model ur10e --json` (a replay file)
    effect.py       a valid user effect (family ``myeffect``)
    cell.db         a schema-current run store (frame, steps, zero20 and poses runs)
    v2.db           the same store in schema 2 (an old file)
"""

from __future__ import annotations

import contextlib
import io
import shutil
from pathlib import Path

import numpy as np

FIXTURE = Path(__file__).resolve().parents[1] / "daq" / "data" / "schema_v2" / "cell.db"

EFFECT_PY = '''"""A user effect: a joint error proportional to sin(2 theta) (for the corpus)."""
import numpy as np

from calibration.effects import JointEffect


class MyEffect(JointEffect):
    family = "myeffect"
    summary = "a twice-per-turn joint error"

    def __init__(self, model, joint=None, order=None):
        super().__init__(model, joint, order)
        self.param_names = ["amp"]
        self.units = ["rad"]
        self.scales = np.array([1e-4])

    def delta(self, p, data, state):
        s = np.sin(2 * data.q[:, self.joint - 1])
        return p[0] * s, s[:, None]
'''


def _quiet(fn, *args):
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        rc = fn(*args)
    if rc not in (0, None):
        raise RuntimeError(f"building the corpus workspace: {args}: exit {rc}: {err.getvalue()}")
    return out.getvalue()


def build(ws: Path) -> Path:
    """Write the good files into ``ws`` (created); returns ``ws``."""
    from calibration import ErrorModel, load_model
    from calibration.fit.simulate import random_joints, realistic_truth, simulate
    from calibration.model.kinematics import tool_points
    from calibration.zero_point import simulate_postures
    from cellcal.cli import main
    from daq.store import RunStore

    ws.mkdir(parents=True, exist_ok=True)
    for name, n, n_valid, seed in (("good.csv", 90, 30, 7), ("ur10e.csv", 60, 0, 8)):
        model = load_model(name.split(".")[0] if name != "good.csv" else "ur5")
        em = ErrorModel(model)
        rng = np.random.default_rng(seed)
        x = realistic_truth(em, rng)
        q = random_joints(model, n, rng)
        data = simulate(em, x, q, 0.015, rng, is_valid=np.arange(n) >= n - n_valid)
        data.to_csv(ws / name)
    _quiet(main, ["calibrate", str(ws / "good.csv"), "--model", "ur5",
                  "--out", str(ws / "params.json")])
    _quiet(main, ["calibrate", str(ws / "ur10e.csv"), "--model", "ur10e",
                  "--out", str(ws / "params_ur10e.json")])
    ur5 = load_model("ur5")
    (ws / "model.yaml").write_text(ur5.to_yaml())
    rng = np.random.default_rng(3)
    q = random_joints(ur5, 5, rng, max_abs_deg=120.0)
    p = tool_points(ur5, q)
    lines = ["pose_id,x,y,z," + ",".join(f"q{j + 1}" for j in range(6))]
    for i in range(5):
        lines.append(",".join([f"t{i + 1}"] + [repr(float(v)) for v in p[i]]
                              + [repr(float(v)) for v in np.degrees(q[i])]))
    (ws / "targets.csv").write_text("\n".join(lines) + "\n")
    m10 = load_model("ur10e")
    post, _ = simulate_postures("dh", m10.dh_table(),
                                np.radians([0.3, -0.12, 0.25, 0.08, -0.4, 0.2]),
                                np.array([12.0, -8.0, 135.0]), np.array([700.0, 150.0, 250.0]),
                                scatter_mm=0.02 / np.sqrt(3), limits=m10.limits_rad(),
                                rng=np.random.default_rng(1))
    post.to_csv(ws / "postures.csv")
    (ws / "zero.json").write_text(_quiet(main, ["zero", str(ws / "postures.csv"),
                                                "--model", "ur10e", "--json"]))
    (ws / "effect.py").write_text(EFFECT_PY)
    shutil.copyfile(FIXTURE, ws / "v2.db")
    shutil.copyfile(FIXTURE, ws / "cell.db")
    RunStore(ws / "cell.db").close()  # brought to the current schema
    for side in ("-wal", "-shm"):
        Path(str(ws / "cell.db") + side).unlink(missing_ok=True)
    return ws


def copy_workspace(src: Path, dst: Path) -> Path:
    """A fresh copy of the workspace for one case."""
    shutil.copytree(src, dst, dirs_exist_ok=True)
    return dst
