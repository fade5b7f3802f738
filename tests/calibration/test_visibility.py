"""Line-of-sight geometry (calibration.cell.visibility) and the cell description
(calibration.cell.cell), each checked against a brute-force construction of its own."""

import numpy as np
import pytest

from calibration import load_model
from calibration.cell.cell import (
    REFLECTOR_ACCEPTANCE_DEG,
    Box,
    CellError,
    CellSpec,
    Cylinder,
    cell_from_dict,
    load_cell,
    tracker_in_base,
)
from calibration.cell.visibility import (
    assess,
    box_blocks,
    cylinder_blocks,
    facing_angle,
    facing_rotations,
    link_capsules,
    sample_cone,
    sample_visible,
    segment_distance,
    smr_pose,
    solve_facing,
    workspace_ok,
)
from calibration.fit.simulate import random_joints
from calibration.model.transforms import make_T, random_rotation

UR = load_model("ur10e").with_changes(tool=(0.0, 0.0, 60.0))


def _dense(p0, p1, n=4001):
    """n points along each segment p0-p1 ((m, 3) each): (m, n, 3)."""
    s = np.linspace(0.0, 1.0, n)[None, :, None]
    return p0[:, None] + s * (p1 - p0)[:, None]


def _point_segment(x, a, b):
    """Distance of points x (m, n, 3) from segments a-b ((m, 3) each), by projection."""
    d = (b - a)[:, None]
    t = np.clip(np.sum((x - a[:, None]) * d, -1) / np.maximum(np.sum(d * d, -1), 1e-300), 0, 1)
    return np.linalg.norm(x - a[:, None] - t[..., None] * d, axis=-1)


def test_segment_distance_matches_dense_sampling_including_points():
    rng = np.random.default_rng(0)
    p0, p1, q0, q1 = (rng.normal(0, 100, (200, 3)) for _ in range(4))
    q1[:20] = q0[:20]  # points against segments
    p1[20:30] = p0[20:30]
    p1[30:40] = p0[30:40] + 1e-9  # nearly degenerate
    q1[40:50] = q0[40:50] + (p1[40:50] - p0[40:50])  # parallel
    d = segment_distance(p0, p1, q0, q1)
    brute = _point_segment(_dense(p0, p1, 20001), q0, q1).min(axis=1)
    assert np.all(d <= brute + 1e-6)
    assert np.allclose(d, brute, atol=0.05)  # the sampling's own resolution


def test_box_and_cylinder_blocking_match_dense_sampling():
    rng = np.random.default_rng(1)
    box = Box(centre=(100.0, -50.0, 20.0), size=(300.0, 120.0, 80.0), rpy=(10.0, -20.0, 35.0))
    cyl = Cylinder(start=(0.0, 0.0, -100.0), end=(80.0, 60.0, 300.0), radius=70.0)
    p0, p1 = rng.normal(0, 250, (400, 3)), rng.normal(0, 250, (400, 3))
    pts = _dense(p0, p1)
    local = (pts - np.asarray(box.centre)) @ box.rotation()
    for grow in (0.0, 25.0):
        inside = (np.abs(local) <= np.asarray(box.size) / 2 + grow).all(-1).any(-1)
        got = box_blocks(p0, p1, box, grow)
        assert np.mean(got == inside) > 0.99 and got[inside].all()
        s0, s1 = np.asarray(cyl.start), np.asarray(cyl.end)
        u = (s1 - s0) / np.linalg.norm(s1 - s0)
        h = (pts - s0) @ u
        r = np.linalg.norm(pts - s0 - h[..., None] * u, axis=-1)
        inside = ((r <= cyl.radius + grow) & (h >= -grow)
                  & (h <= np.linalg.norm(s1 - s0) + grow)).any(-1)
        got = cylinder_blocks(p0, p1, cyl, grow)
        assert np.mean(got == inside) > 0.99 and got[inside].all()
        assert inside.sum() > 40 and (~inside).sum() > 40


def test_facing_rotations_turn_the_smr_axis_onto_the_direction():
    rng = np.random.default_rng(2)
    d = rng.normal(size=(50, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    for axis in ((0.0, 0.0, 1.0), (1.0, 0.2, -0.3)):
        a = np.asarray(axis) / np.linalg.norm(axis)
        R = facing_rotations(d, rng.uniform(-np.pi, np.pi, 50), a)
        assert np.allclose(R @ a, d, atol=1e-12)
        assert np.allclose(R @ np.swapaxes(R, 1, 2), np.eye(3), atol=1e-12)
        assert np.allclose(np.linalg.det(R), 1.0)
    # the roll turns the flange about the direction
    R0 = facing_rotations(d[:1], np.array([0.0]), (0, 0, 1))[0]
    R1 = facing_rotations(d[:1], np.array([0.5]), (0, 0, 1))[0]
    assert np.isclose(np.arccos((np.trace(R1 @ R0.T) - 1) / 2), 0.5)


def test_sample_cone_is_inside_the_cone_and_fills_it():
    rng = np.random.default_rng(3)
    c = np.tile([[0.3, -0.4, 0.866]], (4000, 1))
    v = sample_cone(c, np.radians(25.0), rng)
    ang = np.degrees(np.arccos(np.clip(v @ (c[0] / np.linalg.norm(c[0])), -1, 1)))
    assert ang.max() <= 25.0 + 1e-9 and np.allclose(np.linalg.norm(v, axis=1), 1.0)
    # uniform on the cap: the share within half the cap's solid angle is one half
    half = np.degrees(np.arccos((1 + np.cos(np.radians(25.0))) / 2))
    assert abs(np.mean(ang <= half) - 0.5) < 0.03


def test_link_capsules_follow_the_chain_and_end_flat_at_the_flange():
    q = random_joints(UR, 20, np.random.default_rng(4))
    caps = link_capsules(UR, q)
    assert caps.a.shape == caps.b.shape == (20, len(caps.radius), 3)
    assert list(caps.link) == [1, 2, 3, 4, 5, 6]  # one non-degenerate segment per UR row
    np.testing.assert_allclose(caps.radius, UR.link_radii())
    from calibration.model.kinematics import run_chain

    r = run_chain(UR.convention, UR.dh_table(), q, UR.tool_mm(), jacobian=False)
    np.testing.assert_allclose(caps.a[:, 0], r.frames_p[:, 0], atol=1e-9)
    # the last capsule stops its radius short of the flange, along the flange axis
    np.testing.assert_allclose(caps.b[:, -1] + caps.radius[-1] * r.base_R_flange[:, :, 2],
                               r.base_p_flange, atol=1e-9)


def test_assess_agrees_with_first_principles():
    cell = CellSpec().with_tracker((2500.0, 0.0, 500.0), "test")
    q = random_joints(UR, 400, np.random.default_rng(5))
    s = assess(UR, q, cell, margins=False)
    p, a = smr_pose(UR, q, (0, 0, 1))
    to = cell.tracker_mm - p
    cos = np.sum(a * to, axis=1) / np.linalg.norm(to, axis=1)
    np.testing.assert_allclose(s.facing_deg, np.degrees(np.arccos(cos)), atol=1e-9)
    assert np.array_equal(s.facing_ok, s.facing_deg <= 30.0)
    caps = link_capsules(UR, q)
    beam = _dense(p, np.broadcast_to(cell.tracker_mm, p.shape), 3001)
    for k in range(caps.a.shape[1]):
        d = _point_segment(beam, caps.a[:, k], caps.b[:, k]).min(axis=1)
        np.testing.assert_allclose(d - caps.radius[k], s.clearance_mm[:, k], atol=0.7)
    hidden = np.flatnonzero(~s.visible)
    assert all(s.reason(i) for i in hidden) and not any(s.reason(i) for i in
                                                        np.flatnonzero(s.visible))
    # about 7 % of uniformly drawn poses face a tracker 2.5 m away within 30 deg
    assert 0.03 < s.facing_ok.mean() < 0.12


def test_fixtures_block_the_beam_and_are_named():
    cell = cell_from_dict({"tracker": {"position": [2500, 0, 500]},
                           "fixtures": [{"name": "pillar", "cylinder": {
                               "start": [1500, -2000, -500], "end": [1500, 2000, -500],
                               "radius": 1200}}]})
    q = sample_visible(UR, CellSpec().with_tracker((2500, 0, 500), "t"), 60,
                       np.random.default_rng(6))
    s = assess(UR, q, cell)
    assert s.fixture_hit[:, 0].any() and (~s.fixture_hit[:, 0]).any()
    i = int(np.flatnonzero(s.fixture_hit[:, 0])[0])
    assert "fixture pillar in the beam" in s.reason(i)


def test_sample_visible_and_solve_facing():
    cell = CellSpec().with_tracker((0.0, 2500.0, 400.0), "t")
    q = sample_visible(UR, cell, 200, np.random.default_rng(7), floor_z_mm=0.0)
    assert len(q) == 200 and assess(UR, q, cell).visible.all()
    assert workspace_ok(UR, q).all() and np.all(np.abs(q) <= np.pi + 1e-9)
    assert np.all((q >= UR.limits_rad()[:, 0]) & (q <= UR.limits_rad()[:, 1]))
    # an exact facing pose: the SMR where asked, its axis at the tracker
    p = np.array([[400.0, 600.0, 500.0]])
    qf, ok = solve_facing(UR, p, cell.tracker_mm - p, np.zeros(1), q[:1], (0, 0, 1))
    assert ok[0]
    pp, a = smr_pose(UR, qf, (0, 0, 1))
    np.testing.assert_allclose(pp, p, atol=1e-3)
    assert np.degrees(facing_angle(pp, a, cell.tracker_mm))[0] < 1e-3


def test_cell_file_and_its_errors(tmp_path):
    f = tmp_path / "cell.yaml"
    f.write_text("tracker: {position: [-2500, 0, 500]}\n"
                 "smr: {axis: [0, 0, 2], reflector: RRR 0.5in}\nmargins: {facing_deg: 3}\n"
                 "fixtures:\n"
                 "  - {name: table, box: {centre: [0, 0, -400], size: [1000, 800, 780]}}\n")
    c = load_cell(f)
    assert c.tracker_mm.tolist() == [-2500, 0, 500] and c.tracker_source == "cell file"
    assert c.smr.half_angle_deg == REFLECTOR_ACCEPTANCE_DEG["RRR 0.5in"]
    np.testing.assert_allclose(c.smr.axis_unit(), [0, 0, 1])
    assert c.margins.facing_deg == 3 and c.margins.clearance_mm == 20
    assert c.fixtures[0].name == "table" and c.fixtures[0].box.size == (1000, 800, 780)
    assert cell_from_dict(None).tracker is None  # an empty file: the defaults
    for text, msg in [
        ("tracker: {position: [1, 2]}\n", "tracker.position"),
        ("smr: {reflector: RRR 9in}\n", "unknown reflector"),
        ("fixtures: [{name: a}]\n", "exactly one of box, cylinder"),
        ("fixtures: [{name: a, box: {centre: [0, 0, 0], size: [1, 0, 1]}}]\n", "must be > 0"),
        ("smr: {axis: [0, 0, 0]}\n", "must not be zero"),
        ("margin: {}\n", "unknown field"),
        ("- 1\n", "must be a mapping"),
    ]:
        f.write_text(text)
        with pytest.raises(CellError, match=msg) as e:
            load_cell(f)
        assert str(f) in str(e.value)
    with pytest.raises(CellError, match="missing.yaml: no such file"):
        load_cell(tmp_path / "missing.yaml")


def test_tracker_in_base_inverts_the_frame():
    R = random_rotation(np.random.default_rng(8))
    p = np.array([1200.0, -800.0, 300.0])
    T = make_T(R, -R @ p)
    np.testing.assert_allclose(tracker_in_base(T), p, atol=1e-9)
