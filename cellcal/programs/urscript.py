"""URScript: find a program's targets, and write them back compensated.

Handled (see :func:`parse_program`): pose literals ``p[x, y, z, rx, ry, rz]`` (m, rotation
vector) and joint lists ``[q1, ..., qN]`` (rad) as the target arguments of ``movej``,
``movel``, ``movep``, ``servoj`` (the first) and ``movec`` (the first two); variables
assigned from such literals (every assignment of the name a literal) and moved to;
``pose_trans``/``pose_add`` of two pose literals (folded into one literal); the active TCP
from ``set_tcp(p[...])`` and the payload from ``set_payload(m, ...)`` /
``set_payload_mass(m)`` for the moves after them in the text.

Refused, with their line (:attr:`Program.refusals`): targets computed at run time (any
other expression, a function's result, an element of a list), moves on variables that
are assigned from an expression, changed element-wise or never assigned (function
parameters, installation variables), targets after a ``set_tcp`` of a run-time value.

Only the numbers of a target change (a folded expression becomes one literal); each
changed line gets ``  # cellcal: was ...; corrected N mm`` at its end, so line numbers
stay those of the original.
"""

from __future__ import annotations

from .targets import Correction, Program, Refusal, Target, format_number, line_end, line_of
from .targets import rewrite as _rewrite
from .tokens import Token, signed_numbers, tokenize
from .urscript_exprs import Found, args_of, fold, literal

#: moves and how many leading arguments are targets
MOVES = {"movej": 1, "movel": 1, "movep": 1, "servoj": 1, "movec": 2}
PAYLOAD = ("set_payload", "set_payload_mass", "set_target_payload")
DECIMALS = 7


class _Reader:
    def __init__(self, text: str, source: str):
        self.text, self.source = text, source
        self.all = tokenize(text, "#", '"\'', source)
        self.toks = [t for t in self.all if t.kind != "comment"]
        self.refusals: list[Refusal] = []
        self.notes: list[str] = []
        self.assigned: dict[str, list[list[Token]]] = {}
        self.dynamic: set[str] = set()
        #: offsets of the expressions moved to directly (a variable's other uses are noted)
        self.direct: set[int] = set()
        #: span of a target's literal -> (found, tcp, payload, move), in the order moved to
        self.sites: dict[tuple[int, int], tuple] = {}

    def snippet(self, a: int, b: int) -> str:
        s = " ".join(self.text[a:b].split())
        return s if len(s) <= 70 else s[:67] + "..."

    def statement_end(self, j: int) -> int:
        toks = self.toks
        while j < len(toks) and not (toks[j].kind == "newline" and toks[j].depth == 0):
            j += 1
        return line_end(self.text, toks[j].start if j < len(toks) else len(self.text))

    def scan_assignments(self) -> None:
        toks, start = self.toks, True
        for k, t in enumerate(toks):
            if t.kind == "newline" and t.depth == 0:
                start = True
                continue
            if not start:
                continue
            start = t.text in ("global", "local")
            if t.kind != "name" or k + 1 >= len(toks):
                continue
            nxt = toks[k + 1]
            if nxt.text == "=":
                j = k + 2
                while j < len(toks) and not (toks[j].kind == "newline" and toks[j].depth == 0):
                    j += 1
                self.assigned.setdefault(t.text, []).append(toks[k + 2:j])
            elif nxt.text == "[":  # p1[2] = ...: changed at run time
                self.dynamic.add(t.text)

    def literal_to_function(self, t: Token, k: int) -> None:
        """A literal passed to a function of the program: the function may move to it, and
        what it does with it is known only at run time."""
        args, close = args_of(self.toks, k + 1)
        if any(literal(a) is not None for a in args):
            self.refusals.append(Refusal(
                line_of(self.text, t.start), self.snippet(t.start, self.toks[close].end),
                f"a literal passed to the program's function {t.text}(), which may move to "
                "it: its target is known at run time"))

    def value_of(self, expr: list[Token]) -> Found | str:
        """The target an expression names, or the reason it cannot be compensated."""
        found = literal(expr) or fold(expr, self.toks)
        if found is not None:
            return found
        if len(expr) == 1 and expr[0].kind == "name":
            name = expr[0].text
            defs = self.assigned.get(name)
            if not defs:
                return (f"variable {name!r} is never assigned here (a function parameter or "
                        "an installation variable)")
            if name in self.dynamic or any(literal(d) is None for d in defs):
                return f"variable {name!r} is assigned from an expression (computed at run time)"
            if len(defs) > 1:
                return f"variable {name!r} is assigned more than once"
            return literal(defs[0])
        if len(expr) > 1 and expr[0].kind == "name" and expr[1].text == "(":
            return f"the result of {expr[0].text}() is computed at run time"
        return "computed at run time" if expr else "no target"

    def run(self) -> Program:
        self.scan_assignments()
        self.functions = {self.toks[k + 1].text for k, t in enumerate(self.toks[:-1])
                          if t.text == "def"}
        tcp, tcp_line, payload = None, None, None
        toks = self.toks
        for k, t in enumerate(toks[:-1]):
            if t.kind != "name" or toks[k + 1].text != "(" or (k and toks[k - 1].text == "def"):
                continue
            if t.text in self.functions:
                self.literal_to_function(t, k)
            if t.text not in MOVES and t.text != "set_tcp" and t.text not in PAYLOAD:
                continue
            args, close = args_of(toks, k + 1)
            line = line_of(self.text, t.start)
            construct = self.snippet(t.start, toks[close].end)
            if t.text == "set_tcp":
                got = self.value_of(args[0]) if args else "no argument"
                ok = not isinstance(got, str) and got.kind == "pose"
                tcp, tcp_line = (got.values if ok else "unknown"), line
                if not ok:
                    self.notes.append(f"line {line}: {construct}: the TCP is set at run time; "
                                      "the moves after it are not compensated")
                continue
            if t.text in PAYLOAD:
                nums = signed_numbers(args[0]) if args else None
                payload = nums[0][0] if nums and len(nums) == 1 else None
                if payload is None:
                    self.notes.append(f"line {line}: {construct}: the payload is set at run "
                                      "time; the calibration's payload is used after it")
                continue
            for arg in args[:MOVES[t.text]]:
                self.direct.add(arg[0].start if arg else -1)
                got = self.value_of(arg)
                if tcp == "unknown":
                    got = f"the active TCP was set at run time (line {tcp_line})"
                if isinstance(got, str):
                    self.refusals.append(Refusal(line, construct, got))
                    continue
                site = self.sites.get(got.span)
                if site is not None:
                    if site[1] != tcp:
                        self.refusals.append(Refusal(line, construct, "the same target is "
                                                     "moved to with different TCPs"))
                    continue
                self.sites[got.span] = (got, tcp, payload, t.text)
        return self.program()

    def program(self) -> Program:
        targets = []
        for found, tcp, payload, move in self.sites.values():  # in the order moved to
            a, b = found.span
            end = next(j for j, t in enumerate(self.toks) if t.start >= b - 1)
            targets.append(Target(
                len(targets), found.kind, found.values, line_of(self.text, a),
                a - self.text.rfind("\n", 0, a), found.span, found.numbers, self.text[a:b],
                self.statement_end(end), move, tcp, payload))
        self.note_other_uses(targets)
        done = next((line_of(self.text, t.start) for t in self.all
                     if t.kind == "comment" and "cellcal:" in t.text), None)
        return Program("urscript", self.text, targets, self.refusals, self.notes, done)


    def note_other_uses(self, targets: list[Target]) -> None:
        """A note for each variable target used in an expression besides moves: that
        expression sees the compensated value."""
        names = {d[0].start: n for n, defs in self.assigned.items() for d in defs}
        compensated = {names[t.span[0]] for t in targets if t.span[0] in names}
        lhs = {self.toks[k].start for k in range(len(self.toks) - 1)
               if self.toks[k + 1].text in ("=", "[")}
        for t in self.toks:
            if t.kind == "name" and t.text in compensated and t.start not in self.direct \
                    and t.start not in lhs:
                self.notes.append(f"line {line_of(self.text, t.start)}: {t.text} is also used "
                                  "in an expression, which sees the compensated value")


def parse_program(text: str, source: str = "program") -> Program:
    """The targets, refusals and notes of a URScript program (see the module docstring).

    Raises :class:`~cellcal.programs.targets.ProgramError` (naming the line) for a
    program that does not tokenize: unbalanced brackets, an unterminated string.
    """
    return _Reader(text, source).run()


def _number(t: Target, k: int, v: float) -> str:
    return format_number(v, DECIMALS)


def _pose_literal(t: Target, values) -> str:
    return "p[" + ", ".join(format_number(v, DECIMALS) for v in values) + "]"


def rewrite(program: Program, corrections: dict[int, Correction]) -> str:
    """The program with its changed targets rewritten (see the module docstring)."""
    return _rewrite(program, corrections, comment="#", formatter=_number,
                    literal=_pose_literal)
