"""ABB RAPID modules (``.mod``, ``.modx``, ``.sys``, ``.sysx``): the targets a module moves
to, and their compensated rewrite.

Handled (see :func:`parse_program`): the targets of ``MoveL``, ``MoveJ`` (``ToPoint``),
``MoveC`` (``CirPoint`` and ``ToPoint``), ``MoveAbsJ`` (``ToJointPos``), their ``DO``,
``AO``, ``GO`` and ``Sync`` variants, ``TriggL``/``TriggJ``/``TriggC`` and
``SearchL``/``SearchC``: an inline ``robtarget`` or ``jointtarget`` aggregate, or the name
of one declared in the module (``CONST``, ``PERS``, ``VAR``, with ``LOCAL`` or ``TASK``,
in the module or a routine), or an element of a declared array (``path{2}``; an index
known at run time, ``path{i}``, makes every element a target). A robtarget is
``[[x, y, z], [q1, q2, q3, q4], [cf1, cf4, cf6, cfx], [eax_a, ..., eax_f]]``: position
(mm) and quaternion are compensated (the quaternion written normalised), the robconf and
the external axes (``9E+09``: none) kept as written; a jointtarget's six robot axes (deg)
are compensated, its external axes kept. The active TCP is the instruction's ``tooldata``
(its ``tframe``; ``tool0`` the flange), the frame of a robtarget its ``\\WObj``
``wobjdata`` (``uframe`` * ``oframe``, the world frame taken as the base frame; ``wobj0``
the base frame), the payload the tool's mass (or the ``\\TLoad``'s). Tools and work
objects are read from their declarations in the module, by name.

Refused, with their line: a move to a target computed at run time (``Offs(...)``,
``RelTool(...)``, ``CRobT()``, any expression), to a variable assigned in a routine, to a
routine's parameter or to a name not declared in the module; a move whose tool or work
object is not declared in the module, changes at run time, is stationary (``robhold``)
or moves with a mechanical unit (``ufprog FALSE``); the same target moved to with
different tools or work objects; a robtarget whose quaternion is not a rotation; a
target literal in an instruction that is not one of the above, or passed to one of the
module's routines. Noted: a declared target no move of the module uses, a target also
used in an expression or call, set external axes, a program displacement
(``PDispOn``/``PDispSet``/``EOffsOn``/``EOffsSet``) and ``GripLoad``.

RAPID is case-insensitive; statements end at ``;`` and may run over several lines;
comments start at ``!``. Only the numbers of a target change; each changed statement gets
``  ! cellcal: was ...; corrected N mm`` at the end of the line where it ends.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .rapid_data import (
    Agg,
    aggregate,
    is_jointtarget,
    is_robtarget,
    read_jointtarget,
    read_loaddata,
    read_robtarget,
    read_tooldata,
    read_wobjdata,
)
from .targets import Correction, Program, Refusal, Target, format_number, line_end, line_of
from .targets import rewrite as _rewrite
from .tokens import Token, tokenize

#: move instructions: (argument positions of the targets, of the tool, target kind); the
#: positions count the required arguments only (optional ones, ``\\Conc``, are skipped)
MOVES: dict[str, tuple[tuple[int, ...], int, str]] = {
    **{f"MOVE{m}{v}": ((0,), 3, "pose") for m in "LJ" for v in ("", "DO", "AO", "GO", "SYNC")},
    **{f"MOVEC{v}": ((0, 1), 4, "pose") for v in ("", "DO", "AO", "GO", "SYNC")},
    "MOVEABSJ": ((0,), 3, "joints"),
    "TRIGGL": ((0,), 4, "pose"), "TRIGGJ": ((0,), 4, "pose"), "TRIGGC": ((0, 1), 5, "pose"),
    "SEARCHL": ((2,), 4, "pose"), "SEARCHC": ((2, 3), 5, "pose"),
}
TYPES = {"pose": "robtarget", "joints": "jointtarget"}
DECLARE = ("CONST", "VAR", "PERS")
ROUTINES = ("PROC", "FUNC", "TRAP")
ENDS = ("ENDPROC", "ENDFUNC", "ENDTRAP")
DISPLACEMENT = ("PDISPON", "PDISPSET", "EOFFSON", "EOFFSSET")
#: words after which an instruction starts
STRUCTURE = ("THEN", "ELSE", "DO", "ENDIF", "ENDFOR", "ENDWHILE", "ENDTEST", "ERROR",
             "BACKWARD", "UNDO", "DEFAULT", *ENDS)
#: decimals written: position mm, quaternion, axis angle deg
DECIMALS_MM, DECIMALS_QUAT, DECIMALS_DEG = 4, 7, 6


@dataclass
class Decl:
    """A data declaration: its routine (None: the module), type and name (upper-cased
    type), line, initial aggregate (None: no literal), whether it has an initial value,
    array dimensions, the end of its statement's line and where a routine assigns it."""

    scope: str | None
    type: str
    name: str
    line: int
    init: Agg | None
    has_init: bool
    dims: int
    statement_end: int
    name_at: int
    assigned: int | None = None


def _elements(agg, dims: int, index=()) -> dict[tuple, object]:
    """An array's elements by index (1-based), from its nested aggregate."""
    if dims == 0:
        return {index: agg}
    if not isinstance(agg, Agg):
        return {}
    out = {}
    for k, item in enumerate(agg.items, 1):
        out.update(_elements(item, dims - 1, (*index, k)))
    return out


class _Reader:
    def __init__(self, text: str, source: str):
        self.text, self.source = text, source
        self.all = tokenize(text, "!", '"', source, escape=None)
        self.toks = [t for t in self.all if t.kind not in ("comment", "newline")]
        self.at = {t.start: k for k, t in enumerate(self.toks)}
        self.refusals: list[Refusal] = []
        self.notes: list[str] = []
        self.decls: dict[tuple, Decl] = {}
        self.params: dict[str, set[str]] = {}
        #: routine names, upper-cased -> as written
        self.routines: dict[str, str] = {}
        #: declarations a move names (compensated or refused)
        self.moved: set[int] = set()
        self.scope_at: list[str | None] = []
        #: offsets of the names and literals moved to directly
        self.direct: set[int] = set()
        self.lhs: set[int] = set()
        #: span of a target's literal -> what the first move to it says
        self.sites: dict[tuple[int, int], dict] = {}

    # ---- structure --------------------------------------------------------------------
    def upper(self, k: int) -> str:
        t = self.toks[k]
        return t.text.upper() if t.kind == "name" else ""

    def snippet(self, a: int, b: int) -> str:
        s = " ".join(self.text[a:b].split())
        return s if len(s) <= 70 else s[:67] + "..."

    def close_of(self, k: int) -> int:
        """Index of the bracket closing the one at k."""
        depth, j = self.toks[k].depth, k + 1
        while self.toks[j].depth != depth or self.toks[j].text not in ")]}":
            j += 1
        return j

    def scan_routines(self) -> None:
        toks, scope = self.toks, None
        for k, t in enumerate(toks):
            u = self.upper(k)
            if t.depth == 0 and u in ROUTINES:
                j = k + 1 + (u == "FUNC")
                if j < len(toks) and toks[j].kind == "name":
                    scope = toks[j].text.upper()
                    self.routines[scope] = toks[j].text
                    self.params[scope] = set()
                    if j + 1 < len(toks) and toks[j + 1].text == "(":
                        close = self.close_of(j + 1)
                        self.params[scope] = {
                            toks[i].text.upper() for i in range(j + 2, close)
                            if toks[i].kind == "name" and toks[i + 1].text in (",", ")", "|", "{")}
            self.scope_at.append(scope)
            if t.depth == 0 and u in ENDS:
                scope = None

    def statements(self):
        """Index ranges of the statements: up to each ``;`` at depth 0 (excluded)."""
        start = 0
        for k, t in enumerate(self.toks):
            if t.text == ";" and t.depth == 0:
                yield start, k
                start = k + 1
        if start < len(self.toks):
            yield start, len(self.toks)

    def end_of(self, b: int) -> int:
        """Where a statement ending at token b (its ``;``) puts a comment."""
        at = self.toks[b].start if b < len(self.toks) else len(self.text)
        return line_end(self.text, at)

    def lookup(self, name: str, scope: str | None):
        """The declaration a name means in a routine, "param" for a parameter, else None."""
        if scope is not None:
            if (scope, name) in self.decls:
                return self.decls[scope, name]
            if name in self.params.get(scope, ()):
                return "param"
        return self.decls.get((None, name))

    # ---- declarations and assignments -------------------------------------------------
    def declaration(self, j: int, b: int) -> None:
        toks = self.toks
        if j + 2 >= b or toks[j + 1].kind != "name" or toks[j + 2].kind != "name":
            return
        name_tok, k, dims = toks[j + 2], j + 3, 0
        if k < b and toks[k].text == "{":
            close = self.close_of(k)
            dims = 1 + sum(1 for i in range(k + 1, close) if toks[i].text == ","
                           and toks[i].depth == toks[k].depth + 1)
            k = close + 1
        init, has_init = None, k < b and toks[k].text == ":="
        if has_init and k + 1 < b and toks[k + 1].text == "[":
            agg, close = aggregate(toks, k + 1)
            init = agg if close == b - 1 else None
        key = (self.scope_at[j], name_tok.text.upper())
        self.decls.setdefault(key, Decl(
            key[0], toks[j + 1].text.upper(), name_tok.text, line_of(self.text, name_tok.start),
            init, has_init, dims, self.end_of(b), name_tok.start))

    def assignments(self, a: int, b: int) -> None:
        toks = self.toks
        for k in range(a + 1, b):
            if toks[k].text != ":=" or toks[k].depth != 0:
                continue
            j = k - 1
            while j > a:
                if toks[j].text == "}":
                    while not (toks[j].text == "{" and toks[j].depth == 0):
                        j -= 1
                    j -= 1
                elif toks[j - 1].text == "." and toks[j].kind == "name":
                    j -= 2
                else:
                    break
            if toks[j].kind != "name" or (j > 0 and toks[j - 1].text == "\\"):
                continue  # an optional argument (\WObj:=...)
            self.lhs.add(toks[j].start)
            d = self.lookup(toks[j].text.upper(), self.scope_at[j])
            if isinstance(d, Decl) and d.assigned is None:
                d.assigned = line_of(self.text, toks[j].start)

    # ---- moves ------------------------------------------------------------------------
    def arguments(self, a: int, b: int) -> tuple[list[list[Token]], dict[str, list[Token]]]:
        """(required arguments, optional ones by upper-cased name) of an instruction whose
        arguments are toks[a:b]."""
        parts, cur = [], []
        for t in self.toks[a:b]:
            if t.text == "," and t.depth == 0:
                parts.append(cur)
                cur = []
            else:
                cur.append(t)
        parts.append(cur)
        required, optional = [], {}
        for part in parts:
            cut = next((i for i, t in enumerate(part) if t.text == "\\" and t.depth == 0),
                       len(part))
            if cut or not part:
                required.append(part[:cut])
            rest, name = part[cut:], None
            for i, t in enumerate(rest):
                if t.text == "\\" and t.depth == 0 and i + 1 < len(rest):
                    name = rest[i + 1].text.upper()
                    optional[name] = []
                elif name is not None and not (i and rest[i - 1].text == "\\") \
                        and t.text != ":=":
                    optional[name].append(t)
        return required, optional

    def named(self, expr: list[Token]) -> tuple[str, tuple | None] | None:
        """(upper-cased name, index tokens or None) of ``name`` or ``name{...}``."""
        if not expr or expr[0].kind != "name":
            return None
        if len(expr) == 1:
            return expr[0].text.upper(), None
        if expr[1].text == "{" and expr[-1].text == "}" and expr[-1].depth == expr[1].depth:
            return expr[0].text.upper(), tuple(expr[2:-1])
        return None

    def data(self, expr: list[Token], scope, kind: str, default: str):
        """A tool's, work object's or load's value named by ``expr``: (value, name), or
        the reason it is not known. ``default`` (tool0, wobj0) is the identity (None)."""
        got = self.named(expr)
        if got is None:
            return f"the {kind} is an expression (known at run time)"
        name, index = got
        d = self.lookup(name, scope)
        shown = " ".join(t.text for t in expr)
        if d is None and name == default.upper() and index is None:
            return None, shown
        if not isinstance(d, Decl):
            return (f"{kind} {shown} is a routine's parameter (known at run time)" if d
                    else f"{kind} {shown} is not declared in this module (not known here)")
        if d.type != kind.upper():
            return f"{shown} is a {d.type.lower()}, not a {kind}"
        if d.assigned is not None:
            return f"{kind} {shown} is assigned at line {d.assigned} (changed at run time)"
        elements = _elements(d.init, d.dims) if d.init is not None else {}
        key = self._index(index)
        if key is None or key not in elements:
            return f"{kind} {shown}: its value is not a literal in its declaration"
        reader = {"tooldata": read_tooldata, "wobjdata": read_wobjdata,
                  "loaddata": read_loaddata}[kind]
        value = reader(elements[key])
        return f"{kind} {shown}: {value}" if isinstance(value, str) else (value, shown)

    def _index(self, index) -> tuple | None:
        """The literal index of ``name{...}`` (() without one), None when not literal."""
        if index is None:
            return ()
        vals = [t for t in index if t.text != ","]
        if vals and all(t.kind == "number" and t.text.isdigit() for t in vals) and \
                len(vals) == sum(1 for t in index if t.text == ",") + 1:
            return tuple(int(t.text) for t in vals)
        return None

    def targets_of(self, expr: list[Token], scope, kind: str) -> list[tuple] | str:
        """The targets a move's argument names: [(read, aggregate, context, statement end)]
        or why it cannot be compensated."""
        toks = self.toks
        k = self.at[expr[0].start] if expr else -1
        if expr and expr[0].text == "[" and expr[-1] is toks[self.close_of(k)]:
            agg, _ = aggregate(toks, k)
            read = (read_robtarget if kind == "pose" else read_jointtarget)(agg)
            return read if isinstance(read, str) else [(read, agg, None, None)]
        got = self.named(expr)
        if got is None:
            if len(expr) > 1 and expr[0].kind == "name" and expr[1].text == "(":
                return f"the result of {expr[0].text}() is computed at run time"
            return "computed at run time" if expr else "no target"
        name, index = got
        shown = expr[0].text
        d = self.lookup(name, scope)
        if d == "param":
            return (f"{shown} is a parameter of routine {self.routines[scope]}() (known at "
                    "run time)")
        if d is None:
            return f"{shown} is not declared in this module (its value is not known here)"
        if d.type != TYPES[kind].upper():
            return f"{shown} is a {d.type.lower()}, not a {TYPES[kind]}"
        if d.assigned is not None:
            return f"{shown} is assigned at line {d.assigned} (changed at run time)"
        if d.init is None:
            return (f"{shown}'s value is an expression (computed at run time)" if d.has_init
                    else f"{shown} has no value in its declaration (set at run time)")
        self.direct.add(expr[0].start)
        elements = _elements(d.init, d.dims)
        key = self._index(index)
        if index is not None and d.dims == 0:
            return f"{shown} is not an array"
        picked = sorted(elements) if key is None else [key]
        out = []
        for idx in picked:
            if idx not in elements:
                return f"{shown}{{{','.join(map(str, idx))}}} is not in its declaration"
            label = f"{TYPES[kind]} {d.name}" + (f"{{{','.join(map(str, idx))}}}" if idx else "")
            read = (read_robtarget if kind == "pose" else read_jointtarget)(elements[idx])
            if isinstance(read, str):
                return f"{label}: {read}"
            out.append((read, elements[idx], label, d.statement_end))
        return out

    def move(self, j: int, b: int) -> None:
        toks = self.toks
        name = self.upper(j)
        slots, tool_at, kind = MOVES[name]
        scope = self.scope_at[j]
        line = line_of(self.text, toks[j].start)
        construct = self.snippet(toks[j].start, toks[b - 1].end if b > j + 1 else toks[j].end)
        required, optional = self.arguments(j + 1, b)
        if len(required) <= tool_at:
            self.refusals.append(Refusal(line, construct, "too few arguments"))
            return
        for i in slots:  # what the move names is moved to, whatever else is refused
            if required[i] and required[i][0].text == "[":
                self.direct.add(required[i][0].start)
            named = self.named(required[i])
            d = named and self.lookup(named[0], scope)
            if isinstance(d, Decl):
                self.moved.add(id(d))
        tool = self.data(required[tool_at], scope, "tooldata", "tool0")
        wobj = (self.data(optional["WOBJ"], scope, "wobjdata", "wobj0")
                if "WOBJ" in optional else (None, "wobj0"))
        for why in (tool, wobj):
            if isinstance(why, str):
                self.refusals.append(Refusal(line, construct, why))
                return
        (tool_value, tool_name), (base, wobj_name) = tool, wobj
        tcp = None if tool_value is None else tool_value.tframe
        payload = None if tool_value is None else tool_value.mass_kg
        if "TLOAD" in optional:
            load = self.data(optional["TLOAD"], scope, "loaddata", "load0")
            if isinstance(load, str) or load[0] is None:
                self.notes.append(f"line {line}: {construct}: the load is not known here "
                                  f"({load if isinstance(load, str) else 'load0'}); the "
                                  "tool's is used")
            else:
                payload = load[0]
        frame = (tcp, base if kind == "pose" else None)
        for i in slots:
            got = self.targets_of(required[i], scope, kind)
            if isinstance(got, str):
                self.refusals.append(Refusal(line, construct, got))
                continue
            for read, agg, label, end in got:
                span = (agg.start, agg.end)
                site = self.sites.get(span)
                if site is not None:
                    if site["frame"] != frame:
                        self.refusals.append(Refusal(line, construct, "the same target is "
                                                     "moved to with different tools or work "
                                                     "objects"))
                    continue
                self.sites[span] = {
                    "kind": kind, "read": read, "frame": frame, "payload": payload,
                    "context": label or toks[j].text, "end": end if end is not None
                    else self.end_of(b), "extra": {"robconf": read.robconf, "base": frame[1],
                                                  "tool": tool_name, "wobj": wobj_name}}

    # ---- everything else ----------------------------------------------------------------
    def other(self, a: int, b: int) -> None:
        """A statement that neither declares nor moves: notes, and target literals it holds."""
        toks = self.toks
        for k in range(a, b):
            u = self.upper(k)
            if toks[k].depth == 0 and u in DISPLACEMENT:
                self.notes.append(f"line {line_of(self.text, toks[k].start)}: {toks[k].text}: "
                                  "a program displacement moves the targets after it at run "
                                  "time; they are compensated where they are written")
            elif toks[k].depth == 0 and u == "GRIPLOAD":
                self.notes.append(f"line {line_of(self.text, toks[k].start)}: GripLoad: the "
                                  "load it adds at run time is not followed; the moves are "
                                  "compensated for their tool's load (or --payload-kg)")
        if any(toks[k].text == ":=" and toks[k].depth == 0 and not (
                k >= a + 2 and toks[k - 2].text == "\\") for k in range(a + 1, b)):
            return  # an assignment: its variable is refused where it is moved to
        k = a
        while k < b:
            if toks[k].text == "[":
                agg, close = aggregate(toks, k)
                if is_robtarget(agg) or is_jointtarget(agg):
                    i = self.instruction(a, k)
                    why = (f"a literal passed to the program's routine {toks[i].text}(), "
                           "which may move to it: its target is known at run time"
                           if self.upper(i) in self.routines else
                           "a target in an instruction cellcal does not compensate (see "
                           "docs/programs.md)")
                    self.refusals.append(Refusal(line_of(self.text, agg.start), self.snippet(
                        toks[i].start, toks[b - 1].end), why))
                k = close
            k += 1

    def instruction(self, a: int, k: int) -> int:
        """Index of the name that starts the instruction holding toks[k] (statement
        a..): the last name at depth 0 before k that follows the statement's start or a
        structure word."""
        toks = self.toks
        for i in range(k - 1, a - 1, -1):
            if toks[i].kind == "name" and toks[i].depth == 0 and (
                    i == a or toks[i - 1].text in (")", ":") or self.upper(i - 1) in STRUCTURE):
                return i
        return k

    def run(self) -> Program:
        self.scan_routines()
        spans = list(self.statements())
        kinds = []
        for a, b in spans:
            j = next((k for k in range(a, b) if self.toks[k].depth == 0
                      and self.upper(k) in DECLARE), None)
            if j is not None:
                self.declaration(j, b)
                kinds.append(("declare", j))
            else:
                self.assignments(a, b)
                j = next((k for k in range(a, b) if self.toks[k].depth == 0
                          and self.upper(k) in MOVES), None)
                kinds.append(("move", j) if j is not None else ("other", None))
        for (a, b), (kind, j) in zip(spans, kinds, strict=True):
            if kind == "move":
                self.move(j, b)
            elif kind == "other":
                self.other(a, b)
        return self.program()

    def program(self) -> Program:
        targets = []
        for s in self.sites.values():  # in the order moved to
            read = s["read"]
            a, b = read.span
            targets.append(Target(
                len(targets), s["kind"], read.values, line_of(self.text, a),
                a - self.text.rfind("\n", 0, a), (a, b), read.spans, self.text[a:b], s["end"],
                s["context"], s["frame"][0], s["payload"], s["extra"]))
            if read.extax_set and not any("external axes" in n for n in self.notes):
                self.notes.append(f"line {targets[-1].line}: {s['context']}: external axes "
                                  "are set and kept as written; the target is compensated in "
                                  "the robot's base frame, as if they did not move it")
        self.note_unused_and_other_uses(targets)
        done = next((line_of(self.text, t.start) for t in self.all
                     if t.kind == "comment" and "cellcal:" in t.text), None)
        return Program("rapid", self.text, targets, self.refusals, self.notes, done)

    def note_unused_and_other_uses(self, targets: list[Target]) -> None:
        spans = set(self.sites)
        used, unused = set(), []
        for d in self.decls.values():
            if d.type.lower() not in TYPES.values() or d.init is None:
                continue
            mine = {(e.start, e.end) for e in _elements(d.init, d.dims).values()
                    if isinstance(e, Agg)}
            if mine & spans:
                used.add(id(d))
            elif d.assigned is None and id(d) not in self.moved:
                unused.append(f"{d.name} (line {d.line})")
        if unused:
            self.notes.append("not moved to in this module, left as written: "
                              + ", ".join(unused))
        toks, seen = self.toks, set()
        for k, t in enumerate(toks):
            if t.kind != "name" or t.start in self.direct or t.start in self.lhs or (
                    k and toks[k - 1].text in (".", "\\")):
                continue
            d = self.lookup(t.text.upper(), self.scope_at[k])
            line = line_of(self.text, t.start)
            if isinstance(d, Decl) and id(d) in used and t.start != d.name_at and \
                    (line, id(d)) not in seen:
                seen.add((line, id(d)))
                self.notes.append(f"line {line}: {t.text} is also used in an expression or "
                                  "call, which sees the compensated value")


def parse_program(text: str, source: str = "program") -> Program:
    """The targets, refusals and notes of a RAPID module (see the module docstring).

    Raises :class:`~cellcal.programs.targets.ProgramError` (naming the line) for a module
    that does not tokenize: unbalanced brackets, an unterminated string.
    """
    return _Reader(text, source).run()


def _number(t: Target, k: int, v: float) -> str:
    if t.kind == "joints":
        return format_number(v, DECIMALS_DEG)
    return format_number(v, DECIMALS_MM if k < 3 else DECIMALS_QUAT)


def rewrite(program: Program, corrections: dict[int, Correction]) -> str:
    """The module with its changed targets rewritten (see the module docstring)."""
    return _rewrite(program, corrections, comment="!", formatter=_number, literal=None)


# ---- the configuration a robtarget asks for ---------------------------------------------
def seeds(targets: list[Target], joints: np.ndarray) -> np.ndarray:
    """Seed joints (rad) for the nominal inverse kinematics: a robtarget's robconf puts
    axes 1, 4 and 6 in their quadrants (cf1, cf4, cf6: floor(angle / 90 deg)) and axis 5
    on the side cfx's lowest bit gives (1: negative), the configuration the controller
    picks; the other axes keep the neighbouring joint target's (or the default)."""
    out = np.array(joints, float)
    if out.shape[1] != 6:
        return out
    for i, t in enumerate(targets):
        conf = t.extra.get("robconf") if t.kind == "pose" else None
        if conf is None:
            continue
        q = np.degrees(out[i])
        for axis, cf in zip((0, 3, 5), conf[:3], strict=True):
            q[axis] = np.clip(q[axis], cf * 90.0 + 1.0, cf * 90.0 + 89.0)
        q[4] = (-1.0 if conf[3] % 2 else 1.0) * max(abs(q[4]), 30.0)
        out[i] = np.radians(q)
    return out


#: how far (deg) the nominal solution's axes 1, 4 and 6 may be outside the robconf's quadrant
#: (a taught target on a quadrant's edge) before it is another configuration
CONF_TOLERANCE_DEG = 1.0


def configuration(t: Target, q_nominal: np.ndarray, q: np.ndarray) -> str | None:
    """Why a robtarget's compensation is not for the configuration its robconf asks for
    (the nominal solution in other quadrants, or axis 5 on the other side), else None."""
    conf = t.extra.get("robconf") if t.kind == "pose" else None
    if conf is None or len(q_nominal) != 6:
        return None
    deg = np.degrees(q_nominal)
    for axis, cf in zip((0, 3, 5), conf[:3], strict=True):
        lo, hi = cf * 90.0 - CONF_TOLERANCE_DEG, cf * 90.0 + 90.0 + CONF_TOLERANCE_DEG
        if not lo <= deg[axis] <= hi:
            return (f"the nominal robot reaches it with axis {axis + 1} at {deg[axis]:.1f} "
                    f"deg, outside the quadrant its robconf gives (cf{axis + 1} = {cf}): "
                    "give --start near the joints the controller uses")
    if abs(deg[4]) > CONF_TOLERANCE_DEG and (deg[4] < 0) != bool(conf[3] % 2):
        return (f"the nominal robot reaches it with axis 5 at {deg[4]:.1f} deg, the other "
                f"side than its robconf gives (cfx = {conf[3]}): give --start near the "
                "joints the controller uses")
    return None
