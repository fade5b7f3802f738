"""The program readers on a corpus and on generated programs: every target found, every
construct that cannot be compensated listed with its line, and a rewrite that changes
nothing but the targets (an identity correction gives the file back byte for byte)."""

import re
from pathlib import Path

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from cellcal.programs import krl, rapid, urscript
from cellcal.programs.targets import Correction, ProgramError

CORPUS = Path(__file__).parent / "corpus"
READERS = {".script": urscript, ".dat": krl, ".mod": rapid, ".modx": rapid}

#: file -> (targets as (line, kind, context), refused lines)
EXPECTED = {
    "pick_place.script": ([(5, "joints", "movej"), (6, "pose", "movel"), (7, "pose", "movel")],
                          []),
    "functions.script": ([(6, "joints", "movej"), (10, "pose", "movel"), (11, "pose", "movel")],
                         [3, 9, 12, 14]),
    "crlf_unicode.script": ([(4, "joints", "movej"), (5, "pose", "movel")], []),
    "movec_servoj.script": ([(2, "joints", "movej"), (4, "pose", "movec"), (4, "pose", "movec"),
                             (5, "pose", "movep"), (6, "joints", "servoj")], [9, 11]),
    "taught.dat": ([(8, "joints", "E6AXIS XHOME"), (9, "pose", "E6POS XP1"),
                    (12, "pose", "E6POS XP2"), (15, "pose", "E6POS xP3"),
                    (18, "pose", "E6POS XPATH[1]"), (19, "pose", "E6POS XPATH[2]")], [16]),
    "windows.dat": ([(4, "joints", "E6AXIS XSTART"), (5, "pose", "E6POS XDROP")], []),
    "cell.mod": ([(9, "joints", "jointtarget jHome"), (10, "pose", "robtarget pApproach"),
                  (11, "pose", "robtarget pPick"), (12, "pose", "robtarget pPlace"),
                  (17, "pose", "robtarget pPath{1}"), (18, "pose", "robtarget pPath{2}"),
                  (19, "pose", "robtarget pPath{3}"), (20, "pose", "robtarget pLower"),
                  (33, "pose", "MoveC"), (34, "pose", "MoveC"), (36, "pose", "MoveL"),
                  (37, "joints", "MoveAbsJ")], []),
    "refused.mod": ([(6, "pose", "robtarget pA"), (10, "pose", "robtarget pTrack")],
                    [15, 17, 18, 19, 20, 21, 22, 26, 27, 31]),
    "gripper.modx": ([(6, "joints", "jointtarget jStart"), (7, "pose", "robtarget pOver"),
                      (8, "pose", "robtarget pGrab"), (9, "pose", "robtarget pDrop")], []),
}


def _read(path: Path):
    text = path.read_bytes().decode("utf-8", "surrogateescape")
    return text, READERS[path.suffix].parse_program(text, path.name)


def _shifted(program, delta=1e-3):
    return {t.index: Correction(tuple(v + delta * (k + 1) for k, v in enumerate(t.values)),
                                0.123) for t in program.targets}


def _skeleton(text: str, program) -> str:
    """The text with every target span blanked and cellcal's comments removed."""
    out, at = [], 0
    for a, b in sorted(t.span for t in program.targets):
        out += [text[at:a], "<T>"]
        at = b
    out.append(text[at:])
    return re.sub(r"  [#;!] cellcal: [^\r\n]*", "", "".join(out))


@pytest.mark.parametrize("name", sorted(EXPECTED))
def test_corpus(name):
    path = CORPUS / name
    reader = READERS[path.suffix]
    text, program = _read(path)
    targets, refused = EXPECTED[name]
    assert [(t.line, t.kind, t.context) for t in program.targets] == targets
    assert [r.line for r in program.refusals] == refused, program.refusals
    # identity: byte for byte
    same = reader.rewrite(program, {t.index: Correction(t.values, 0.0) for t in program.targets})
    assert same.encode("utf-8", "surrogateescape") == path.read_bytes()
    # a correction changes the targets' numbers and appends one comment per changed line
    out = reader.rewrite(program, _shifted(program))
    again = reader.parse_program(out, name)
    assert _skeleton(out, again) == _skeleton(text, program)
    assert len(out.splitlines()) == len(text.splitlines())
    for t, u in zip(program.targets, again.targets, strict=True):
        assert (u.line, u.kind) == (t.line, t.kind)
        want = _shifted(program)[t.index].values
        assert max(abs(a - b) for a, b in zip(u.values, want, strict=True)) < 1e-4
    assert again.compensated_at is not None and program.compensated_at is None


def test_what_is_refused_and_why():
    _, p = _read(CORPUS / "functions.script")
    reasons = {r.line: r.reason for r in p.refusals}
    assert "never assigned" in reasons[3]  # a function parameter
    assert "function approach()" in reasons[9]
    assert "get_inverse_kin() is computed at run time" in reasons[12]
    assert "assigned from an expression" in reasons[14]
    _, p = _read(CORPUS / "movec_servoj.script")
    assert "TCP was set at run time (line 10)" in p.refusals[1].reason
    assert p.targets[0].tcp is None
    _, p = _read(CORPUS / "pick_place.script")
    assert p.targets[1].tcp == (0.0, 0.0, 0.15, 0.0, 0.0, 0.0) and p.targets[1].payload_kg == 1.2
    _, p = _read(CORPUS / "taught.dat")
    assert p.targets[1].extra == {"s": "6", "t": "50", "tool_no": 1, "base_no": 0}
    assert "FRAME" in p.refusals[0].reason
    p = krl.parse_program(_read(CORPUS / "taught.dat")[0], frame_targets=["f_offset"])
    assert "FRAME F_OFFSET" in [t.context for t in p.targets] and not p.refusals


@pytest.mark.parametrize("text, line, what", [
    ("def a():\n  movel(p[0.1, 0.2, 0.3, 0, 0, 0)\nend\n", 2, "unbalanced ')'"),
    ("def a():\n  textmsg(\"open\n  movej([0,0,0,0,0,0])\nend\n", 2, "unterminated string"),
    ("def a():\n  x = [1, 2\n\nend\n", 2, "'[' is never closed"),
])
def test_a_program_that_does_not_parse_is_refused_with_its_line(text, line, what):
    with pytest.raises(ProgramError, match=f"line {line}: {re.escape(what)}"):
        urscript.parse_program(text)


def test_krl_unbalanced_brace():
    with pytest.raises(ProgramError, match="line 2: '{' is never closed"):
        krl.parse_program("DEFDAT X\nDECL E6POS XP1={X 1,Y 2\nENDDAT\n")


# ---- generated programs ---------------------------------------------------------------
_NUM = st.floats(-3.0, 3.0, allow_nan=False).map(lambda v: f"{v:.{len(str(v)) % 6}f}")
_SP = st.sampled_from(["", " ", "  ", "\t"])
_COMMENT = st.text(st.characters(blacklist_characters="\r\n", blacklist_categories=("Cs",)),
                   max_size=12)


@st.composite
def _statement(draw):
    nums = draw(st.lists(_NUM, min_size=6, max_size=6))
    sp = draw(_SP)
    lit = "p[" + f",{sp}".join(nums) + "]"
    joints = "[" + f",{sp}".join(nums) + "]"
    name = draw(st.sampled_from(["a", "b", "wp1"]))
    return draw(st.sampled_from([
        f"movel({sp}{lit}{sp}, a=1.2)", f"movej({joints})", f"{name} = {lit}",
        f"set_tcp({lit})", f"movej({sp}{name}{sp})", f"textmsg(\"{lit} ]\")",
        f"movel(pose_trans({lit}, {lit}))", "while True:", "end", "i = i + 1",
        f"# {lit}", f"movec({lit}, {lit}, r=0.01)",
    ]))


@st.composite
def _program(draw):
    lines = draw(st.lists(_statement(), max_size=12))
    eol = draw(st.sampled_from(["\n", "\r\n"]))
    indent = draw(_SP)
    body = [f"{indent}{s}{draw(st.sampled_from(['', '  # ' + draw(_COMMENT)]))}"
            for s in lines]
    return eol.join(["def prog():", *body, "end"]) + draw(st.sampled_from(["", eol]))


@settings(max_examples=150, deadline=None)
@given(_program())
def test_generated_programs_change_only_their_targets(text):
    program = urscript.parse_program(text)
    same = urscript.rewrite(program, {t.index: Correction(t.values, 0.0)
                                      for t in program.targets})
    assert same == text
    out = urscript.rewrite(program, _shifted(program))
    again = urscript.parse_program(out)
    assert _skeleton(out, again) == _skeleton(text, program)
    assert [t.kind for t in again.targets] == [t.kind for t in program.targets]
    assert len(again.refusals) == len(program.refusals)
