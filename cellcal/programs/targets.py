"""What a controller-language reader finds in a program, and the one way it is written back.

A reader (:mod:`cellcal.programs.urscript`, :mod:`cellcal.programs.krl`) turns a program's
text into a :class:`Program`: the targets it can compensate (:class:`Target`: where each
literal is, its kind and values in the language's own units, the active TCP), the
constructs it cannot (:class:`Refusal`, with their line), and notes. :func:`rewrite`
replaces only the numbers of the changed targets (or a folded expression by one literal)
and appends one comment to each changed line with the original text and the correction
in mm; every other character of the program is kept, so an identity correction gives the
input back byte for byte.
"""

from __future__ import annotations

from dataclasses import dataclass, field

from ..errors import UsageError


class ProgramError(UsageError, ValueError):
    """A program that does not parse (unbalanced brackets, an unterminated string...):
    the message names the line (bad input, exit code 2)."""


@dataclass(frozen=True)
class Target:
    """One target a program moves to.

    Attributes
    ----------
    index : position in :attr:`Program.targets` (the order the program moves in)
    kind : ``"pose"`` (a TCP pose) or ``"joints"``
    values : as written, in the language's units (URScript: m and a rotation vector, or
        rad; KRL: mm and A, B, C deg, or deg)
    line, column : 1-based, where the literal starts
    span : (start, end) character offsets of the text a correction replaces
    numbers : (start, end) of every number token of ``values``, in order; empty when the
        whole span is replaced (a folded expression)
    text : the original text of the span
    statement_end : offset of the end of the line that ends the statement (where the
        comment goes)
    context : the instruction or declaration (``movel``, ``E6POS XP1``...)
    tcp : the active TCP as the language writes a pose, or None for the flange
    payload_kg : the payload set before the move, or None (the calibration's)
    extra : language-specific (KRL's S and T, tool and base numbers)
    """

    index: int
    kind: str
    values: tuple[float, ...]
    line: int
    column: int
    span: tuple[int, int]
    numbers: tuple[tuple[int, int], ...]
    text: str
    statement_end: int
    context: str
    tcp: tuple[float, ...] | None = None
    payload_kg: float | None = None
    extra: dict = field(default_factory=dict)


@dataclass(frozen=True)
class Refusal:
    """A construct the program moves by that cannot be compensated, and why."""

    line: int
    construct: str
    reason: str

    def __str__(self) -> str:
        return f"line {self.line}: {self.construct}: {self.reason}"


@dataclass
class Program:
    """A parsed program: its text (kept whole), targets, refusals and notes."""

    language: str
    text: str
    targets: list[Target]
    refusals: list[Refusal]
    notes: list[str] = field(default_factory=list)
    #: line of a comment a previous compensation wrote, or None
    compensated_at: int | None = None


@dataclass(frozen=True)
class Correction:
    """New values for one target (the language's units) and the TCP's correction, mm."""

    values: tuple[float, ...]
    mm: float


def line_of(text: str, offset: int) -> int:
    """1-based line number of a character offset."""
    return text.count("\n", 0, offset) + 1


def line_end(text: str, offset: int) -> int:
    """Offset of the end of the line holding ``offset`` (before its ``\\r\\n`` or ``\\n``)."""
    k = text.find("\n", offset)
    k = len(text) if k < 0 else k
    return k - 1 if k > 0 and text[k - 1] == "\r" else k


def format_number(v: float, decimals: int) -> str:
    """A number as a program writes it: fixed decimals, trailing zeros dropped, no -0."""
    s = f"{v:.{decimals}f}".rstrip("0").rstrip(".")
    return "0" if s in ("-0", "") else s


def rewrite(program: Program, corrections: dict[int, Correction], *, comment: str,
            formatter, literal) -> str:
    """The program's text with the changed targets rewritten.

    Parameters
    ----------
    corrections : target index -> :class:`Correction`; a target whose values are
        unchanged (or that is absent) keeps its text and gets no comment
    comment : the language's comment prefix (``#``, ``;``)
    formatter : (target, value index, value) -> the number's text
    literal : (target, values) -> the text replacing a whole span (folded expressions)
    """
    text = program.text
    edits: list[tuple[int, int, str]] = []
    notes: dict[int, list[str]] = {}
    for t in program.targets:
        c = corrections.get(t.index)
        if c is None or tuple(c.values) == tuple(t.values):
            continue
        if len(c.values) != len(t.values):
            raise ValueError(f"target {t.index} (line {t.line}) has {len(t.values)} values, "
                             f"the correction {len(c.values)}")
        if t.numbers:
            edits += [(a, b, formatter(t, k, v))
                      for k, ((a, b), v) in enumerate(zip(t.numbers, c.values, strict=True))]
        else:
            edits.append((*t.span, literal(t, c.values)))
        was = " ".join(t.text.split())
        notes.setdefault(t.statement_end, []).append(f"was {was}; corrected {c.mm:.3f} mm")
    for end, words in notes.items():
        edits.append((end, end, f"  {comment} cellcal: " + " | ".join(words)))
    out, at = [], 0
    for a, b, new in sorted(edits, key=lambda e: (e[0], e[1])):
        out += [text[at:a], new]
        at = b
    out.append(text[at:])
    return "".join(out)
