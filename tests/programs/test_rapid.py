"""ABB RAPID modules: what the reader finds and refuses, the frames of a target (tool,
work object, payload), the configuration a robconf asks for, generated modules that change
only their targets, and a compensated module run by the nominal controller on a robot
with hidden errors reaching what it meant."""

import re

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from calibration import ErrorModel, identify, load_model
from calibration.compensation.pose_compensation import NominalTcpFK, as_poses, pose_difference
from calibration.fit.simulate import random_joints, realistic_truth, simulate
from calibration.model.inverse import solve_ik
from calibration.model.transforms import make_T
from cellcal.programs import rapid
from cellcal.programs.compensate import (
    DIALECTS,
    Options,
    compensate_program,
    language_of,
    solve,
)
from cellcal.programs.poses import T_to_rapid, rapid_to_T
from cellcal.programs.targets import Correction, ProgramError

from .test_compensate_program import _true_tcp
from .test_readers import CORPUS, _read, _shifted

TRACK = "[9E+09,9E+09,9E+09,9E+09,9E+09,9E+09]"


def _module(body: str, data: str = "") -> str:
    return (f"MODULE M\n  PERS tooldata t1:=[TRUE,[[0,0,100],[1,0,0,0]],[1,[0,0,0],[1,0,0,0],"
            f"0,0,0]];\n{data}  PROC main()\n{body}  ENDPROC\nENDMODULE\n")


def _rt(x=1000.0, y=0.0, z=1200.0, conf="0,0,0,0"):
    return f"[[{x:g},{y:g},{z:g}],[0,0,1,0],[{conf}],{TRACK}]"


def test_what_is_refused_and_noted_with_the_reason():
    _, p = _read(CORPUS / "refused.mod")
    reasons = {r.line: r.reason for r in p.refusals}
    assert "Offs() is computed at run time" in reasons[15]
    assert "assigned at line 16" in reasons[17]
    assert "stationary tool (robhold FALSE)" in reasons[18]
    assert "ufprog FALSE" in reasons[19]
    assert "different tools or work objects" in reasons[20]
    assert "not a unit quaternion" in reasons[21]
    assert "tOther is not declared in this module" in reasons[22]
    assert "routine approach(), which may move to it" in reasons[26]
    assert "instruction cellcal does not compensate" in reasons[27]
    assert "parameter of routine approach()" in reasons[31]
    notes = "\n".join(p.notes)
    for said in ("line 23: GripLoad", "line 24: PDispOn", "line 10: robtarget pTrack: external "
                 "axes are set", "left as written: pSpare (line 11)",
                 "line 15: pA is also used in an expression"):
        assert said in notes
    assert "pB" not in notes  # moved to (and refused), so not 'unused'


def test_keywords_any_case_comments_strings_and_statements_over_lines():
    _, p = _read(CORPUS / "cell.mod")
    by_context = {t.context: t for t in p.targets}
    assert by_context["robtarget pLower"].values[:3] == (904.34, 1215.88, 989.12)
    place = by_context["robtarget pPlace"]  # over four lines, spaces everywhere
    assert place.values == (-109.51, -492.38, 519.76, 0.2153809, 0.3055636, 0.9206946,
                            0.1120871) and place.line == 12 and place.extra["robconf"] == (-1, 0,
                                                                                          -1, 0)
    assert place.statement_end == p.text.index("];", p.text.index("9E9, 9E9 ]")) + 2
    # the string that looks like a move, and comments, are no targets
    assert not any("[[0,0,0]" in t.text for t in p.targets)
    # tool, work object and payload of each target
    pick = by_context["robtarget pPick"]
    assert pick.tcp == (0.0, 0.0, 60.0, 1.0, 0.0, 0.0, 0.0) and pick.payload_kg == 0.4
    np.testing.assert_allclose(rapid_to_T(pick.extra["base"]),
                               make_T(rapid_to_T((0, 0, 0, 0.9238795, 0, 0, 0.3826834))[:3, :3],
                                      [700, -300, 200]), atol=1e-9)
    assert by_context["robtarget pApproach"].extra["base"] is None
    assert [t.context for t in p.targets if t.kind == "joints"] == ["jointtarget jHome",
                                                                     "MoveAbsJ"]


def test_tool_rotation_work_object_and_load():
    text, p = _read(CORPUS / "gripper.modx")
    assert "\r\n" in text and "\udc96" in text  # Windows-1252 bytes pass through
    grab, drop = p.targets[2], p.targets[3]
    assert grab.tcp == (10.0, 0.0, 150.0, 0.9659258, 0.0, 0.258819, 0.0)
    assert grab.payload_kg == 2.5 and drop.payload_kg == 1.2  # \TLoad: the total load
    assert grab.extra["wobj"] == "wTable" and p.targets[1].extra["wobj"] == "wobj0"


@pytest.mark.parametrize("body, data, what", [
    ("    MoveL path{2}, v100, fine, t1;\n",
     f"  CONST robtarget path{{3}}:=[{_rt(900)},{_rt(950)},{_rt(1000)}];\n", [950.0]),
    ("    FOR i FROM 1 TO 3 DO\n      MoveL path{i}, v100, fine, t1;\n    ENDFOR\n",
     f"  CONST robtarget path{{3}}:=[{_rt(900)},{_rt(950)},{_rt(1000)}];\n",
     [900.0, 950.0, 1000.0]),
    ("    MoveL grid{2,1}, v100, fine, t1;\n",
     f"  CONST robtarget grid{{2,2}}:=[[{_rt(1)},{_rt(2)}],[{_rt(3)},{_rt(4)}]];\n", [3.0]),
    ("    IF reg1 > 0 MoveL p1, v100, fine, t1;\n    TEST reg1\n    CASE 1, 2:\n"
     "      MoveJ p2, v100, fine, t1\\WObj:=wobj0;\n    ENDTEST\n",
     f"  CONST robtarget p1:={_rt(1)};\n  CONST robtarget p2:={_rt(2)};\n", [1.0, 2.0]),
    ("    VAR robtarget pLoc:=" + _rt(7) + ";\n    MoveL \\Conc, pLoc \\ID:=1, v100 \\V:=200, "
     "z10 \\Z:=5, t1 \\TLoad:=load0;\n", "", [7.0]),
])
def test_arrays_indices_and_control_flow(body, data, what):
    p = rapid.parse_program(_module(body, data))
    assert [t.values[0] for t in p.targets] == what and not p.refusals


def test_a_local_declaration_hides_the_modules():
    p = rapid.parse_program(_module("    VAR robtarget p:=" + _rt(5) + ";\n"
                                    "    MoveL p, v100, fine, t1;\n",
                                    "  CONST robtarget p:=" + _rt(1) + ";\n"))
    assert [t.values[0] for t in p.targets] == [5.0]
    assert "p (line 3)" in p.notes[0]  # the module's p is not moved to


@pytest.mark.parametrize("text, line, what", [
    ("MODULE M\n  CONST robtarget p:=[[1,2,3],[1,0,0,0],[0,0,0,0],[9E9,9E9,9E9,9E9,9E9,9E9];\n"
     "ENDMODULE\n", 2, "'[' is never closed"),
    ("MODULE M\n  PROC main()\n    TPWrite \"open;\n  ENDPROC\nENDMODULE\n", 3,
     "unterminated string"),
    ("MODULE M\n  PROC main()\n    MoveL p], v100, fine, tool0;\n  ENDPROC\nENDMODULE\n", 3,
     "unbalanced ']'"),
])
def test_a_module_that_does_not_parse_is_refused_with_its_line(text, line, what):
    with pytest.raises(ProgramError, match=f"line {line}: {re.escape(what)}"):
        rapid.parse_program(text)


def test_suffixes_and_files_that_are_not_modules():
    for suffix in (".mod", ".MOD", ".modx", ".sys", ".sysx"):
        assert language_of(f"x{suffix}").name == "rapid"
    with pytest.raises(ProgramError, match=r"\.pgf.*compensate each module"):
        language_of("prog.pgf")
    with pytest.raises(ProgramError, match=r"S4 RAPID program \(\.prg\)"):
        language_of("old.prg")


def test_quaternion_written_normalised_with_the_sign_kept():
    T = rapid_to_T((100.0, 0.0, 0.0, -0.5, -0.5, -0.5, -0.5))
    v = T_to_rapid(T, near=(0, 0, 0, -0.5, -0.5, -0.5, -0.5))
    np.testing.assert_allclose(v[3:], [-0.5] * 4, atol=1e-12)
    assert T_to_rapid(T)[3] > 0
    # a rewritten robtarget: unit quaternion, robconf and external axes as they were
    text = _module("    MoveL p, v100, fine, t1;\n", "  CONST robtarget p:=[[1,2,3],[0.70711,"
                   "0,0.70711,0],[0,-1,2,1],[100,9E+09,9E+09,9E+09,9E+09,9E+09]];\n")
    p = rapid.parse_program(text)
    new = T_to_rapid(rapid_to_T(p.targets[0].values) @ rapid_to_T((0.5, 0, 0, 0.9998477,
                                                                     0.0174524, 0, 0)))
    out = rapid.rewrite(p, {0: Correction(new, 0.5)})
    again = rapid.parse_program(out).targets[0]
    assert abs(np.linalg.norm(again.values[3:]) - 1.0) < 1e-6
    assert "[0,-1,2,1],[100,9E+09,9E+09,9E+09,9E+09,9E+09]];  ! cellcal: was [1,2,3]," in out


def test_the_robconf_seeds_the_configuration_and_is_checked():
    t = rapid.parse_program(_module("    MoveL p, v100, fine, t1;\n", "  CONST robtarget p:="
                                    + _rt(conf="-2,1,-1,1") + ";\n")).targets[0]
    seed = np.degrees(rapid.seeds([t], np.radians([[0.0, 0.0, 0.0, 0.0, 30.0, 0.0]]))[0])
    assert -180 < seed[0] < -90 and 90 < seed[3] < 180 and -90 < seed[5] < 0 and seed[4] < 0
    ok = np.radians([-120.0, 10, 10, 100, -40, -30])
    assert rapid.configuration(t, ok, ok) is None
    flipped = np.radians([-120.0, 10, 10, 100 - 180, 40, -30 + 180])
    why = rapid.configuration(t, flipped, flipped)
    assert "axis 4 at -80.0 deg, outside the quadrant its robconf gives (cf4 = 1)" in why
    on_edge = np.radians([-90.5, 10, 10, 90.0, -0.5, -0.2])  # within 1 deg of the quadrant
    assert rapid.configuration(t, on_edge, on_edge) is None


# ---- generated modules ----------------------------------------------------------------
_NUM = st.floats(-2000.0, 2000.0, allow_nan=False).map(lambda v: f"{v:.{len(str(v)) % 4}f}")
_SP = st.sampled_from(["", " ", "  ", "\t"])


@st.composite
def _statement(draw):
    n = draw(st.lists(_NUM, min_size=6, max_size=6))
    sp = draw(_SP)
    rt = (f"[[{n[0]},{sp}{n[1]},{n[2]}],{sp}[0,{sp}0,1,0],[0,0,{sp}0,0],"
          f"[9E+09,9E+09,9E9,{sp}9E+09,9E+09,9E+09]]")
    jt = f"[[{','.join(n)}],{sp}[9E+09,9E+09,9E+09,9E+09,9E+09,9E+09]]"
    name = draw(st.sampled_from(["p1", "P1", "pHome"]))
    return draw(st.sampled_from([
        f"MoveL {rt},{sp}v100, fine, t1;", f"moveabsj {jt}, v100, z10, t1;",
        f"MoveJ{sp} {name}, v100, z10, t1\\WObj:=wobj0;", f"TPWrite \"{rt} ! ;\";",
        f"MoveC {rt},{sp}{rt}, v100, z10, t1;", f"! MoveL {rt}, v100, fine, t1;",
        "IF reg1 > 1 THEN", "ENDIF", "reg1 := reg1 + 1;", f"MoveL Offs({name},1,2,3), v100,"
        " fine, t1;", f"MoveL {rt},\n      v100, fine, t1;",
    ]))


@st.composite
def _module_text(draw):
    eol = draw(st.sampled_from(["\n", "\r\n"]))
    lines = [f"  {draw(_statement())}" for _ in range(draw(st.integers(0, 10)))]
    data = [f"  CONST robtarget {n}:=[[1,2,3],[1,0,0,0],[0,0,0,0],{TRACK}];"
            for n in ("p1", "pHome")]
    return eol.join(["MODULE Gen", "  PERS tooldata t1:=[TRUE,[[0,0,100],[1,0,0,0]],"
                     "[1,[0,0,0],[1,0,0,0],0,0,0]];", *data, "PROC main()", *lines,
                     "ENDPROC", "ENDMODULE"]) + draw(st.sampled_from(["", eol]))


@settings(max_examples=150, deadline=None)
@given(_module_text())
def test_generated_modules_change_only_their_targets(text):
    program = rapid.parse_program(text)
    same = rapid.rewrite(program, {t.index: Correction(t.values, 0.0) for t in program.targets})
    assert same == text
    out = rapid.rewrite(program, _shifted(program))
    again = rapid.parse_program(out)
    assert [t.kind for t in again.targets] == [t.kind for t in program.targets]
    assert len(again.refusals) == len(program.refusals)
    assert len(out.splitlines()) == len(text.splitlines())


# ---- against a known truth ------------------------------------------------------------
@pytest.fixture(scope="module")
def calibrated():
    """An IRB 2600 calibrated with an SMR off the flange's axis (40, 60, 80 mm), the
    flange's own turn and offset (which the SMR cannot tell from its position) nominal."""
    m = load_model("irb2600_12_165").with_changes(tool=(40.0, 60.0, 80.0))
    em = ErrorModel(m, "geometric,base,tool,harmonic:2")
    rng = np.random.default_rng(7)
    x_true = realistic_truth(em, rng)
    for name in ("j6.theta", "j6.d"):
        x_true[em.index("geometric." + name)] = 0.0
    q = random_joints(m, 300, rng, max_abs_deg=170)
    data = simulate(em, x_true, q, 0.015, rng, is_valid=np.arange(300) >= 220)
    return em, x_true, identify(em, data)


def test_gripper_module_reaches_what_it_meant(calibrated, tmp_path):
    em, x_true, fit = calibrated
    src, out = CORPUS / "gripper.modx", tmp_path / "gripper.modx"
    report = compensate_program(src, em, fit.values, out, options=Options())
    assert report.exit_code == 0 and report.written, report.lines()
    assert "not the point the calibration measured" in "\n".join(report.lines())
    read = lambda path: rapid.parse_program(path.read_bytes().decode("utf-8",  # noqa: E731
                                                                      "surrogateescape"))
    before, after = read(src), read(out)
    raw = out.read_bytes()
    assert raw.count(b"\r\n") == src.read_bytes().count(b"\r\n") and b"\x96" in raw
    tcp = DIALECTS["rapid"].to_T(before.targets[1].tcp)
    fk = NominalTcpFK(em.model, tcp[:3, 3])
    seed = np.radians(before.targets[0].values)
    q_b, q_a, meant = [], [], []
    for tb, ta in zip(before.targets, after.targets, strict=True):
        if tb.kind == "joints":
            q_b.append(np.radians(tb.values))
            q_a.append(np.radians(ta.values))
            r = fk.chain(np.radians([tb.values]))
            meant.append(as_poses(r.base_p_tcp, r.base_R_flange @ tcp[:3, :3])[0])
            continue
        B = np.eye(4) if tb.extra["base"] is None else rapid_to_T(tb.extra["base"])
        for q_list, t in ((q_b, tb), (q_a, ta)):
            T = B @ rapid_to_T(t.values)
            ik = solve_ik(fk, seed, T[:3, 3], T[:3, :3] @ tcp[:3, :3].T, success_rad=1e-7)
            assert ik.success.all()
            q_list.append(ik.q[0])
        meant.append(B @ rapid_to_T(tb.values))
    payload = [2.5, 2.5, 2.5, 1.2]
    true_b = np.stack([_true_tcp(em, x_true, q[None], tcp, 20.0, m)[0][0]
                       for q, m in zip(q_b, payload, strict=True)])
    true_a = np.stack([_true_tcp(em, x_true, q[None], tcp, 20.0, m)[0][0]
                       for q, m in zip(q_a, payload, strict=True)])
    i = em.labels.index("base")
    B_fit = make_T(*em.effects[i].transform(fit.values[em.slices[i]]))
    miss_b = pose_difference(true_b, B_fit @ np.array(meant))
    miss_a = pose_difference(true_a, B_fit @ np.array(meant))
    assert miss_b[0].min() > 0.3 and miss_a[0].max() < 0.05, (miss_b, miss_a)
    assert miss_a[1].max() < 0.3 * miss_b[1].max()


def test_a_wrist_flipped_robtarget_is_solved_in_its_configuration(calibrated):
    """The same pose taught with the wrist flipped (axis 5 negative, axes 4 and 6 half a
    turn away): the neighbours' seed finds the other wrist, the robconf's seed this one."""
    em, _, fit = calibrated
    fk = NominalTcpFK(load_model("irb2600_12_165"), np.zeros(3))
    out = []
    for q, conf in (((10, 20, -10, 100, 40, 50), "0,1,0,0"),
                    ((10, 20, -10, -80, -40, -130), "0,-1,-2,1")):
        r = fk.chain(np.radians([q]))
        v = T_to_rapid(as_poses(r.base_p_tcp, r.base_R_flange)[0])
        rt = (f"[[{v[0]:.4f},{v[1]:.4f},{v[2]:.4f}],[{','.join(f'{c:.7f}' for c in v[3:])}],"
              f"[{conf}],{TRACK}]")
        program = rapid.parse_program(_module("    MoveL p, v100, fine, tool0;\n",
                                              f"  CONST robtarget p:={rt};\n"))
        solved = solve(program, DIALECTS["rapid"], em, fit.values, Options())
        out.append(np.degrees(solved.joints.compensation.q_nominal[0]))
        np.testing.assert_allclose(out[-1], q, atol=1e-3)
    assert out[0][3] > 0 > out[1][3]


_PIECES = st.sampled_from([
    "MODULE", "ENDMODULE", "PROC", "main", "(", ")", "ENDPROC", "FUNC", "TRAP", "ENDFUNC",
    "CONST", "VAR", "PERS", "LOCAL", "robtarget", "jointtarget", "tooldata", "wobjdata",
    "loaddata", "p", "t1", "tool0", "wobj0", "MoveL", "MoveC", "MoveAbsJ", "TriggL", "SearchL",
    "[", "]", "{", "}", ",", ";", ":=", ":", "\\", "WObj", "TLoad", "Conc", ".", "+", "-", "*",
    "1", "0.5", "9E+09", "1e999", "-2", "TRUE", "FALSE", "IF", "THEN", "ENDIF", "! c", "\n",
    '""', '"a;b"', "Offs", "GripLoad", "PDispOn", " ", _rt(), _rt(conf="1,2,3,5"),
])


@settings(max_examples=300, deadline=None)
@given(st.lists(_PIECES, max_size=40))
def test_any_text_parses_or_is_refused_with_its_line(pieces):
    text = " ".join(pieces)
    try:
        program = rapid.parse_program(text)
    except ProgramError as e:
        assert "line " in str(e) and "\n" not in str(e)
        return
    assert rapid.rewrite(program, {t.index: Correction(t.values, 0.0)
                                   for t in program.targets}) == text
    seeds = rapid.seeds(program.targets, np.zeros((len(program.targets), 6)))
    assert np.isfinite(seeds).all()
    for t in program.targets:
        assert all(np.isfinite(t.values))
