"""A compensated program against a known truth: the controller (nominal model) runs the
rewritten program, the true robot (hidden geometric and compliance errors, thermal
growth) ends where the original program meant, position and orientation."""

import numpy as np
import pytest

from calibration import ErrorModel, identify, load_model
from calibration.compensation.compensation import CalibratedFK
from calibration.compensation.pose_compensation import NominalTcpFK, as_poses, pose_difference
from calibration.fit.simulate import random_joints, realistic_truth, simulate
from calibration.model.inverse import solve_ik
from calibration.model.transforms import make_T
from cellcal.programs import krl, urscript
from cellcal.programs.compensate import Options, compensate_program
from cellcal.programs.poses import krl_to_T, ur_to_T
from cellcal.programs.targets import ProgramError

from .test_readers import CORPUS

HIDDEN = "geometric,base,tool,compliance:2,compliance:3,thermal"


@pytest.fixture(scope="module")
def calibrated():
    m = load_model("ur10e").with_changes(tool=(40.0, 60.0, 80.0))
    em = ErrorModel(m, HIDDEN)
    rng = np.random.default_rng(4)
    x_true = realistic_truth(em, rng)
    # the flange the SMR cannot see (d6, theta6...) is the nominal one in this truth
    for name in ("j1.theta", "j1.d", "j3.d", "j4.d", "j6.theta", "j6.d", "j6.a", "j6.alpha"):
        x_true[em.index("geometric." + name)] = 0.0
    q = random_joints(m, 300, rng, max_abs_deg=170)
    temp = rng.uniform(18, 32, 300)
    data = simulate(em, x_true, q, 0.015, rng, is_valid=np.arange(300) >= 220,
                    temp_c=temp, payload_kg=np.full(300, 1.2))
    return em, x_true, identify(em, data)


def _true_tcp(em, x, q, tcp, temp, payload):
    n = len(q)
    cols = {"temp_c": np.full(n, temp), "payload_kg": np.full(n, payload)}
    r = CalibratedFK(em, x, cols, tcp[:3, 3]).chain(q)
    i = em.labels.index("base")
    B = make_T(*em.effects[i].transform(x[em.slices[i]]))
    return B @ as_poses(r.base_p_tcp, r.base_R_flange @ tcp[:3, :3]), B


def test_urscript_program_reaches_what_it_meant(calibrated, tmp_path):
    em, x_true, fit = calibrated
    src = CORPUS / "pick_place.script"
    out = tmp_path / "out.script"
    report = compensate_program(src, em, fit.values, out, options=Options(temp_c=26.0))
    assert report.exit_code == 0 and report.written, report.lines()
    before = urscript.parse_program(src.read_text())
    after = urscript.parse_program(out.read_text())
    tcp = ur_to_T(before.targets[1].tcp)
    fk = NominalTcpFK(em.model, tcp[:3, 3])
    # what the controller does: joints as written, poses by its own IK near home
    home = np.array(before.targets[0].values)
    q_b, q_a, meant = [], [], []
    for tb, ta in zip(before.targets, after.targets, strict=True):
        if tb.kind == "joints":
            q_b.append(tb.values)
            q_a.append(ta.values)
            r = fk.chain(np.array([tb.values]))
            meant.append(as_poses(r.base_p_tcp, r.base_R_flange @ tcp[:3, :3])[0])
            continue
        for q_list, t in ((q_b, tb), (q_a, ta)):
            T = ur_to_T(t.values)
            ik = solve_ik(fk, home, T[:3, 3], T[:3, :3] @ tcp[:3, :3].T, success_rad=1e-7)
            assert ik.success.all()
            q_list.append(ik.q[0])
        meant.append(ur_to_T(tb.values))
    meant = np.array(meant)
    true_b, _ = _true_tcp(em, x_true, np.array(q_b), tcp, 26.0, 1.2)
    true_a, B = _true_tcp(em, x_true, np.array(q_a), tcp, 26.0, 1.2)
    i = em.labels.index("base")
    B_fit = make_T(*em.effects[i].transform(fit.values[em.slices[i]]))
    miss_b = pose_difference(true_b, B_fit @ meant)
    miss_a = pose_difference(true_a, B_fit @ meant)
    assert miss_b[0].min() > 0.3 and miss_a[0].max() < 0.05, (miss_b, miss_a)
    assert miss_a[1].max() < 0.3 * miss_b[1].max()
    rows = report.to_json()["targets"]
    assert [r["line"] for r in rows] == [5, 6, 7]
    assert all(abs(r["correction_mm"] - m) < 0.2 * m for r, m in zip(rows, miss_b[0],
                                                                      strict=True))


def test_partial_programs_and_refusals(calibrated, tmp_path):
    em, _, fit = calibrated
    opts = Options(temp_c=20.0)
    out = tmp_path / "f.script"
    report = compensate_program(CORPUS / "functions.script", em, fit.values, out, options=opts)
    assert report.exit_code == 1 and not report.written and not out.exists()
    assert "nothing written" in report.lines()[-1]
    report = compensate_program(CORPUS / "functions.script", em, fit.values, out,
                                allow_partial=True, options=opts)
    assert report.written and report.exit_code == 1 and len(report.rows) == 3
    with pytest.raises(ProgramError, match="compensated already"):
        compensate_program(out, em, fit.values, tmp_path / "g.script", options=opts)


def test_krl_points_with_their_tool(calibrated, tmp_path):
    em, _, fit = calibrated
    out = tmp_path / "taught.dat"
    report = compensate_program(CORPUS / "taught.dat", em, fit.values, out, allow_partial=True,
                                options=Options(temp_c=20.0, tools={1: (0, 0, 150, 0, 0, 0)}))
    assert len(report.rows) == 6 and [r.line for r in report.refusals] == [16]
    new = krl.parse_program(out.read_bytes().decode("utf-8", "surrogateescape"))
    old = krl.parse_program((CORPUS / "taught.dat").read_text())
    for a, b, row in zip(old.targets, new.targets, report.rows, strict=True):
        if a.kind == "pose":  # the rewritten frame moved by the reported correction
            d = np.linalg.norm(krl_to_T(a.values)[:3, 3] - krl_to_T(b.values)[:3, 3])
            assert abs(d - row["correction_mm"]) < 1e-3
            assert b.extra.get("s") == a.extra.get("s")
    # without the tool the points that use it are refused
    report = compensate_program(CORPUS / "taught.dat", em, fit.values, out, allow_partial=True,
                                options=Options(temp_c=20.0))
    assert sum("TOOL_DATA[1] is not given" in r.reason for r in report.refusals) == 2


def test_a_program_of_pose_targets_only(calibrated, tmp_path):
    """No joint target to seed from: the default posture (or --start) seeds them."""
    em, _, fit = calibrated
    src = tmp_path / "poses.script"
    src.write_text("def p():\n  movel(p[0.6, -0.2, 0.5, 0, 3.1416, 0])\nend\n")
    report = compensate_program(src, em, fit.values, tmp_path / "out.script",
                                options=Options(temp_c=20.0))
    assert report.exit_code == 0 and report.written and len(report.rows) == 1
