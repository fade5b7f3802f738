"""URScript expressions a target can be written as: a pose literal, a joint list, and
``pose_trans``/``pose_add`` of two pose literals (folded into one pose)."""

from __future__ import annotations

from dataclasses import dataclass

from .poses import pose_add, pose_trans
from .tokens import Token, signed_numbers

FOLDS = ("pose_trans", "pose_add")


@dataclass(frozen=True)
class Found:
    """A target expression read: kind, values, number spans (empty for a folded one) and
    the span a correction replaces."""

    kind: str
    values: tuple[float, ...]
    numbers: tuple[tuple[int, int], ...]
    span: tuple[int, int]


def args_of(toks: list[Token], k: int) -> tuple[list[list[Token]], int]:
    """The comma-separated arguments of the call whose '(' is toks[k]; (args, index of ')')."""
    depth, args, cur = toks[k].depth, [], []
    j = k + 1
    while not (toks[j].text == ")" and toks[j].depth == depth):
        if toks[j].text == "," and toks[j].depth == depth + 1:
            args.append(cur)
            cur = []
        elif toks[j].kind != "newline":
            cur.append(toks[j])
        j += 1
    if cur or args:
        args.append(cur)
    return args, j


def literal(expr: list[Token]) -> Found | None:
    """A pose literal or a joint list, else None."""
    nums = None
    if len(expr) >= 3 and expr[0].text == "p" and expr[1].text == "[" and expr[-1].text == "]":
        nums = signed_numbers(expr[2:-1])
        kind = "pose" if nums is not None and len(nums) == 6 else None
    elif len(expr) >= 2 and expr[0].text == "[" and expr[-1].text == "]":
        nums = signed_numbers(expr[1:-1])
        kind = "joints" if nums else None
    if not nums or kind is None:
        return None
    return Found(kind, tuple(v for v, _, _ in nums), tuple((a, b) for _, a, b in nums),
                  (expr[0].start, expr[-1].end))


def fold(expr: list[Token], toks: list[Token]) -> Found | None:
    """``pose_trans``/``pose_add`` of two pose literals, folded into one pose, else None."""
    if len(expr) < 4 or expr[0].text not in FOLDS or expr[1].text != "(":
        return None
    args, close = args_of(toks, toks.index(expr[1]))
    lits = [literal(a) for a in args]
    if len(args) != 2 or toks[close] is not expr[-1] or any(
            lit is None or lit.kind != "pose" for lit in lits):
        return None
    fold = pose_trans if expr[0].text == "pose_trans" else pose_add
    return Found("pose", fold(lits[0].values, lits[1].values, near=lits[0].values), (),
                  (expr[0].start, expr[-1].end))


