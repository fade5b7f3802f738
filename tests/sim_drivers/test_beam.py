"""The simulated tracker's line of sight: it refuses to measure an SMR that faces away and one
whose beam a link crosses, and measures the poses it sees; the refusals are checked against
the simulator's own truth (true SMR point and axis, the true robot's link segments) by a
construction independent of calibration.cell.visibility."""

import numpy as np
import pytest

from calibration.cell.cell import CellSpec, cell_from_dict
from calibration.cell.visibility import assess, sample_visible, smr_pose, solve_facing
from calibration.model.kinematics import run_chain
from sim_drivers.cell import CellRefused, SimCell
from sim_drivers.model_truth import DEFAULT_TRACKER_AT_MM, ModelTruth
from sim_drivers.truth import PoseContext

SEED = 3


@pytest.fixture(scope="module")
def truth():
    return ModelTruth.from_spec("ur10e", None, SEED)


def _cell(truth, cell=None):
    c = SimCell(truth, seed=SEED, tracker_initialised=True, cell=cell)
    return c


def _measure(cell, q):
    cell.command_move_joints(q, 1.0)
    try:
        cell.tracker_measure(0.1)
        return None
    except CellRefused as e:
        assert e.name == "BEAM_BROKEN"
        return e.detail


def _true_geometry(truth, q):
    """From the truth alone: the true SMR centre and tracker (base frame), the true SMR axis
    and the true links' DH segments (frame origins and the d/a corner points)."""
    T = truth.tracker_T_base
    base_T_tracker = np.linalg.inv(T)
    p_tr = truth.true_point(q, PoseContext())
    p = base_T_tracker[:3, :3] @ p_tr + base_T_tracker[:3, 3]
    tracker = base_T_tracker[:3, 3]
    m = truth.model
    r = run_chain(m.convention, m.dh_table(), q[None], m.tool_mm(), jacobian=False)
    axis = r.base_R_flange[0] @ truth.smr_axis
    pts = [r.frames_p[0, 0]]
    for i, row in enumerate(m.joints):
        pts += [r.frames_p[0, i] + row.d * r.frames_R[0, i, :, 2], r.frames_p[0, i + 1]]
    return p, tracker, axis, np.array(pts)


def _link_gap(p, tracker, pts, radii):
    """Smallest distance between the beam and each link's segments, less its radius, by
    sampling the beam densely (mm): (N,)."""
    beam = p + np.linspace(0, 1, 20001)[:, None] * (tracker - p)
    out = []
    for i, r in enumerate(radii):
        a, mid, b = pts[2 * i], pts[2 * i + 1], pts[2 * i + 2]
        d = np.inf
        for s0, s1 in ((a, mid), (mid, b)):
            u = s1 - s0
            t = np.clip((beam - s0) @ u / max(u @ u, 1e-300), 0, 1)
            d = min(d, float(np.min(np.linalg.norm(beam - s0 - t[:, None] * u, axis=1))))
        out.append(d - r)
    return np.array(out)


def test_the_tracker_stands_where_the_cell_puts_it(truth):
    np.testing.assert_allclose(truth.tracker_in_base, DEFAULT_TRACKER_AT_MM, atol=1e-9)
    tilt = np.degrees(np.arccos(truth.smr_axis @ [0, 0, 1]))
    assert 0 < tilt < 5  # the hidden tilt of the true SMR axis


def test_refuses_an_smr_facing_away(truth):
    cell = _cell(truth)
    plan_cell = CellSpec().with_tracker(truth.tracker_in_base, "truth")
    rng = np.random.default_rng(0)
    q_vis = sample_visible(truth.model, plan_cell, 20, rng)
    # the same SMR positions, the axis turned 40-80 deg away from the tracker
    p, _ = smr_pose(truth.model, q_vis, (0, 0, 1))
    to = plan_cell.tracker_mm - p
    to /= np.linalg.norm(to, axis=1, keepdims=True)
    side = np.cross(to, [0.0, 0.0, 1.0])
    side /= np.linalg.norm(side, axis=1, keepdims=True)
    ang = np.radians(rng.uniform(40, 80, len(p)))[:, None]
    d = np.cos(ang) * to + np.sin(ang) * side
    q_away, ok = solve_facing(truth.model, p, d, np.zeros(len(p)), q_vis, (0, 0, 1))
    n_checked = 0
    for qv, qa in zip(q_vis, q_away[ok], strict=False):
        assert _measure(cell, qv) is None
        why = _measure(cell, qa)
        p_true, tracker, axis, _ = _true_geometry(truth, cell.robot_state().q)
        v = (tracker - p_true) / np.linalg.norm(tracker - p_true)
        facing = np.degrees(np.arccos(np.clip(axis @ v, -1, 1)))
        assert facing > 30.0 and why is not None and "faces" in why
        assert f"{facing:.1f} deg away" in why
        n_checked += 1
    assert n_checked >= 10


def test_refuses_when_a_link_crosses_the_beam(truth):
    """SMRs facing the tracker straight on at random places: the simulator measures exactly
    those whose beam the true links leave clear (by the truth's own geometry)."""
    cell = _cell(truth)
    plan_cell = CellSpec().with_tracker(truth.tracker_in_base, "truth")
    rng = np.random.default_rng(1)
    m = truth.model
    p = rng.uniform([-1100, -1100, 0], [1100, 1100, 1100], (600, 3))
    p = p[np.linalg.norm(p[:, :2], axis=1) > 350]
    seeds = rng.uniform(-np.pi, np.pi, (len(p), 6))
    q, ok = solve_facing(m, p, plan_cell.tracker_mm - p, np.zeros(len(p)), seeds, (0, 0, 1))
    q = q[ok]
    s = assess(m, q, plan_cell, margins=False)
    blocked = np.flatnonzero(s.facing_ok & ~s.links_ok)[:12]
    clear = np.flatnonzero(s.visible & (s.clearance_mm.min(axis=1) > 10))[:12]
    assert len(blocked) >= 8 and len(clear) >= 8
    radii = m.link_radii()
    seen = {"blocked": 0, "clear": 0}
    for i in np.concatenate([blocked, clear]):
        why = _measure(cell, q[i])
        p_true, tracker, _, pts = _true_geometry(truth, cell.robot_state().q)
        gap = _link_gap(p_true, tracker, pts, radii)
        gap[-1] = np.inf if gap[-1] > -radii[-1] else gap[-1]  # the flange end is flat
        if gap.min() < -1.0:  # a true link crosses the true beam
            assert why is not None and "in the beam" in why, (i, gap, why)
            assert f"link {int(np.argmin(gap)) + 1}" in why
            seen["blocked"] += 1
        elif gap.min() > 1.0:
            assert why is None, (i, gap, why)
            seen["clear"] += 1
    assert seen["blocked"] >= 6 and seen["clear"] >= 6, seen


def test_status_and_fixtures(truth):
    """A fixture of the cell file breaks the beam of a pose the tracker otherwise sees, and
    the status reports the target as not visible."""
    plan_cell = CellSpec().with_tracker(truth.tracker_in_base, "truth")
    q = sample_visible(truth.model, plan_cell, 1, np.random.default_rng(2))[0]
    p, _ = smr_pose(truth.model, q[None], (0, 0, 1))
    mid = (p[0] + truth.tracker_in_base) / 2
    wall = cell_from_dict({"fixtures": [{"name": "wall", "box": {
        "centre": mid.tolist(), "size": [50, 3000, 3000]}}]})
    free, walled = _cell(truth), _cell(truth, wall)
    assert _measure(free, q) is None and free.tracker_target_visible()
    assert _measure(walled, q) == "fixture wall in the beam"
    assert not walled.tracker_target_visible()


def test_sim_serve_places_the_tracker_and_reads_the_cell(tmp_path):
    """``cellcal sim serve --tracker-at=... --cell FILE``: the tracker stands there (poses
    facing it are measured, poses facing the default place are not) and the file's fixture
    breaks the beam; bad values exit 2."""
    import subprocess
    import sys
    from pathlib import Path

    from cellcal.cli import main
    from drivers.errors import BeamBroken
    from drivers.urls import open_robot, open_tracker
    from tests.daq.capture_helpers import read_lines

    at = (-2400.0, 300.0, 700.0)
    m = ModelTruth.from_spec("ur10e", None, 0).model
    rng = np.random.default_rng(5)
    q_here = sample_visible(m, CellSpec().with_tracker(at, "t"), 1, rng)[0]
    q_default = sample_visible(m, CellSpec().with_tracker(DEFAULT_TRACKER_AT_MM, "t"), 1, rng)[0]
    p, _ = smr_pose(m, q_here[None], (0, 0, 1))
    f = tmp_path / "cell.yaml"
    x, y = (p[0, :2] + np.array(at[:2])) / 2  # a post halfway along that pose's beam
    f.write_text(f"fixtures:\n  - {{name: post, cylinder: {{start: [{x}, {y}, -500], "
                 f"end: [{x}, {y}, 2500], radius: 60}}}}\n")
    root = Path(__file__).resolve().parents[2]
    for cell_args, blocked in (([], False), (["--cell", str(f)], True)):
        proc = subprocess.Popen([sys.executable, "-m", "cellcal", "sim", "serve", "--no-pty",
                                 "--no-rtde", "--port-base", "0",
                                 f"--tracker-at={at[0]},{at[1]},{at[2]}",
                                 *cell_args], cwd=root, stdout=subprocess.PIPE,
                                stderr=subprocess.PIPE)
        try:
            urls = read_lines(proc, 4, timeout=30.0)
            with open_robot(urls[1]) as rob, open_tracker(urls[2]) as trk:
                rob.connect(2.0)
                trk.connect(2.0)
                for q, seen in ((q_here, not blocked), (q_default, False)):
                    rob.move_joints(q, speed=2.0, timeout=5.0)
                    rob.wait_settled(timeout=5.0)
                    if seen:
                        assert np.all(np.isfinite(trk.measure(0.05).xyz))
                    else:
                        with pytest.raises(BeamBroken):
                            trk.measure(0.05)
        finally:
            proc.terminate()
            proc.wait(timeout=10)
            proc.stdout.close()
            proc.stderr.close()
    assert main(["sim", "serve", "--tracker-at", "1,2"]) == 2
    f.write_text("fixtures: [{name: x}]\n")
    assert main(["sim", "serve", "--cell", str(f)]) == 2
