"""iso9283 end to end over real sockets: a frame run, then a short ISO 9283 capture against
the simulated UR10e (realistic hidden errors) through the line-protocol robot and TCP tracker
drivers; the stored finalize summary (AP, RP per cube point) is checked against the truth."""

from __future__ import annotations

import json

import numpy as np

from cellcal.cli import main
from daq.store import RunStore
from sim_drivers.model_truth import model_truth_factory
from sim_drivers.truth import PoseContext

from .capture_helpers import served_cell

CYCLES = 10


def test_iso9283_summary_is_plausible(tmp_path, capsys):
    db = tmp_path / "cell.db"
    with served_cell(model_truth_factory, seed=2) as stack:
        common = ["--model", "ur10e", "--tool-mm", "0,0,60", "--no-floor", "--robot",
                  stack.urls[1], "--tracker", stack.urls[2], "--db", str(db), "--json"]
        # the frame from a start facing the tracker (given roughly), the cube from a posture
        # facing the tracker the frame measured
        assert main(["capture", "frame", *common, "--line-length-mm", "400",
                     "--tracker-at", "2450,40,520"]) == 0
        assert main(["capture", "iso9283", *common, "--cycles", str(CYCLES)]) == 0
        cell = stack.cell
        truth = cell.truth
        with RunStore(db) as store:
            run = store.run(2)
            s = store.samples(2)
        T_fit = run.context.tracker_T_base_matrix
        ctx = PoseContext(direction=None, temp_c=cell.temp0_c, t_s=0.0)
        true_tip = np.array([truth.true_point(q, ctx) for q in s.q])
        sigma_t = np.array([cell.tracker_sigma(p) for p in s.tracker_p_smr])
        from calibration.model.kinematics import run_chain

        m = truth.model
        J = run_chain(m.convention, m.dh_table(), s.q, m.tool_mm(),
                      jacobian=True).dP_dtable[..., 0]  # (n, 3, N) mm/rad
        # 3-D variance of one attained, measured position: arrival noise of every joint
        # (the repeatability) + the tracker's noise on each axis
        var3 = (np.sum(J**2, axis=(1, 2)) * cell.joint_noise_rad**2 + 3 * sigma_t**2)
    summary = json.loads(capsys.readouterr().out.strip().splitlines()[-1])["summary"]["iso9283"]
    assert summary == run.summary["iso9283"]
    pts = np.array([t["info"]["point"] for t in s.target])
    T_true = truth.tracker_T_base
    rows = []
    for k in range(1, 6):
        e = summary[f"P{k}"]
        sel = pts == k
        assert e["n"] == CYCLES
        sigma3 = float(np.sqrt(var3[sel].mean()))
        # RP = mean l + 3 S_l: for a 3-D normal scatter of per-axis sigma about 3.6 sigma,
        # i.e. about 2-3 times the 3-D standard deviation (repeatability + tracker)
        ratio = e["RP_mm"] / sigma3
        assert 1.2 < ratio < 3.5, (k, e["RP_mm"], sigma3)
        # AP in the fitted frame: the truth's mean attained position against the commanded
        # point in that frame (what AP must be, up to the averaged noise)
        xc = np.asarray([t["xyz"] for t in s.target])[sel][0]
        ap_fit = float(np.linalg.norm(true_tip[sel].mean(axis=0) - (T_fit[:3, :3] @ xc
                                                                     + T_fit[:3, 3])))
        assert abs(e["AP_mm"] - ap_fit) < 3 * sigma3 / np.sqrt(CYCLES) + 0.005
        # the uncalibrated positioning error in the true frame (the frame fit from the
        # robot's own motion absorbs part of it)
        ap_true = float(np.linalg.norm(true_tip[sel].mean(axis=0) - (T_true[:3, :3] @ xc
                                                                       + T_true[:3, 3])))
        assert ap_true / 3 < e["AP_mm"] < 3 * ap_true
        rows.append((k, e["RP_mm"], sigma3, ratio, e["AP_mm"], ap_fit, ap_true))
    print("\nP  RP mm  sigma3 mm  RP/sigma3  AP mm  AP(fit frame, truth)  AP(true frame)")
    for r in rows:
        print(f"P{r[0]} {r[1]:.4f} {r[2]:.4f} {r[3]:.2f} {r[4]:.3f} {r[5]:.3f} {r[6]:.3f}")
