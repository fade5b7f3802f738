"""KUKA KRL ``.dat`` files: the taught points of a program, and their compensated rewrite.

A KRL program keeps its taught points in its ``.dat`` file as declarations; the ``.src``
moves to them by name. Handled (see :func:`parse_program`): ``E6POS`` and ``POS``
declarations (``{X, Y, Z, A, B, C ...}``: mm, Euler angles in degrees, R = Rz(A) Ry(B)
Rx(C); ``S``, ``T`` and external axes are kept), ``E6AXIS`` and ``AXIS`` declarations
(``{A1 ... A6 ...}``: deg), with or without ``DECL``/``GLOBAL``, and element assignments of
declared arrays (``XP[3]={...}``); each point's tool and base numbers from its ``FDAT``
(``FP1`` for ``XP1``, KUKA's naming). ``FRAME`` declarations are read but compensated only
when named as targets (a FRAME may be a tool, a base or an offset).

Refused, with their line: a point missing one of its components or with a component that
is not a number, a FRAME not named as a target.

Only the numbers of a point change; each changed line gets ``  ; cellcal: was ...;
corrected N mm`` at its end. Keywords are case-insensitive, as in KRL.
"""

from __future__ import annotations

from .targets import Correction, Program, Refusal, Target, format_number, line_end, line_of
from .targets import rewrite as _rewrite
from .tokens import Token, signed_numbers, tokenize

POSE_TYPES = ("E6POS", "POS", "FRAME")
AXIS_TYPES = ("E6AXIS", "AXIS")
POSE_KEYS = ("X", "Y", "Z", "A", "B", "C")
AXIS_KEYS = ("A1", "A2", "A3", "A4", "A5", "A6")


def _aggregate(toks: list[Token], k: int) -> tuple[dict, int]:
    """Components of the aggregate whose '{' is toks[k]: name -> (value tokens); and the
    index of its '}'."""
    depth, comps, j = toks[k].depth, {}, k + 1
    while not (toks[j].text == "}" and toks[j].depth == depth):
        start = j
        while not ((toks[j].text in (",", "}")) and toks[j].depth == depth + (
                toks[j].text == ",")):
            j += 1
        part = [t for t in toks[start:j] if t.kind != "newline"]
        if part and part[0].kind == "name":
            comps[part[0].text.upper()] = part[1:]
        if toks[j].text == ",":
            j += 1
    return comps, j


class _Reader:
    def __init__(self, text: str, source: str, frame_targets):
        self.text, self.source = text, source
        self.all = tokenize(text, ";", "\"'", source, escape=None)
        self.toks = [t for t in self.all if t.kind != "comment"]
        self.frames = {n.upper() for n in (frame_targets or ())}
        self.refusals: list[Refusal] = []
        self.arrays: dict[str, str] = {}
        self.fdat: dict[str, dict] = {}
        self.found: list[tuple] = []

    def statements(self):
        """Index ranges of the statements (lines at bracket depth 0)."""
        start = 0
        for k, t in enumerate(self.toks):
            if t.kind == "newline" and t.depth == 0:
                if k > start:
                    yield start, k
                start = k + 1
        if start < len(self.toks):
            yield start, len(self.toks)

    def run(self) -> Program:
        for a, b in self.statements():
            words = [t.text.upper() for t in self.toks[a:b]]
            k = a + (words[:1] == ["DECL"])
            k += self.toks[k].text.upper() == "GLOBAL" if k < b else 0
            kind = self.toks[k].text.upper() if k < b else ""
            if kind in POSE_TYPES + AXIS_TYPES + ("FDAT",) and k + 1 < b:
                self.declaration(kind, k + 1, b)
            elif self.toks[a].text.upper() in self.arrays and "=" in words:
                self.declaration(self.arrays[self.toks[a].text.upper()], a, b)
        targets = [Target(i, *f) for i, f in enumerate(self.found)]
        for t in targets:  # the FDAT of point P1 is FP1, its E6POS XP1
            fd = self.fdat.get("F" + t.context.split()[-1][1:].upper(), {})
            t.extra.update(fd)
        done = next((line_of(self.text, t.start) for t in self.all
                     if t.kind == "comment" and "cellcal:" in t.text), None)
        return Program("krl", self.text, targets, self.refusals, [], done)

    def declaration(self, kind: str, k: int, b: int) -> None:
        toks = self.toks
        name_tok = toks[k]
        eq = next((j for j in range(k, b) if toks[j].text == "="), None)
        if eq is None:  # DECL E6POS XP[10]: an array filled element-wise later
            if k + 1 < b and toks[k + 1].text == "[":
                self.arrays[name_tok.text.upper()] = kind
            return
        name = self.text[name_tok.start:toks[eq - 1].end]
        if eq + 1 >= b or toks[eq + 1].text != "{":
            return
        comps, close = _aggregate(toks, eq + 1)
        line = line_of(self.text, toks[eq + 1].start)
        if kind == "FDAT":
            self.fdat[name.upper()] = {key.lower(): int(v[0].text) for key, v in comps.items()
                                       if key in ("TOOL_NO", "BASE_NO") and len(v) == 1
                                       and v[0].kind == "number"}
            return
        if kind == "FRAME" and name.upper() not in self.frames:
            self.refusals.append(Refusal(line, f"FRAME {name}", "a FRAME may be a tool, a base "
                                         "or an offset: name it as a target to compensate it"))
            return
        keys = AXIS_KEYS if kind in AXIS_TYPES else POSE_KEYS
        values, numbers = [], []
        for key in keys:
            got = signed_numbers(comps.get(key, []))
            if got is None or len(got) != 1:
                why = "missing" if key not in comps else "not a number"
                self.refusals.append(Refusal(line, f"{kind} {name}", f"component {key} {why}"))
                return
            values.append(got[0][0])
            numbers.append(got[0][1:])
        a, e = toks[eq + 1].start, toks[close].end
        extra = {key.lower(): comps[key][0].text for key in ("S", "T")
                 if key in comps and len(comps[key]) == 1}
        self.found.append(("joints" if kind in AXIS_TYPES else "pose", tuple(values), line,
                           a - self.text.rfind("\n", 0, a), (a, e), tuple(numbers),
                           self.text[a:e], line_end(self.text, e), f"{kind} {name}",
                           None, None, extra))


def parse_program(text: str, source: str = "program", *, frame_targets=()) -> Program:
    """The points, refusals and notes of a KRL ``.dat`` file (see the module docstring);
    ``frame_targets``: names of FRAME declarations that are targets.

    Raises :class:`~cellcal.programs.targets.ProgramError` (naming the line) for a file
    that does not tokenize: unbalanced braces or brackets, an unterminated string.
    """
    return _Reader(text, source, frame_targets).run()


def _number(t: Target, k: int, v: float) -> str:
    return format_number(v, 4 if t.kind == "pose" and k < 3 else 6)


def rewrite(program: Program, corrections: dict[int, Correction]) -> str:
    """The file with its changed points rewritten (see the module docstring)."""
    return _rewrite(program, corrections, comment=";", formatter=_number, literal=None)
