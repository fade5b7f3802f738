"""A small tokenizer for controller languages: names, numbers, strings, comments, brackets.

Enough of a lexer to find targets without misreading a comment or a string that happens
to contain ``p[`` or a brace: every token keeps its character offsets, so a reader
rewrites exactly the characters it means to. Brackets must balance and strings must end
on their line; otherwise :class:`~cellcal.programs.targets.ProgramError` names the line.
"""

from __future__ import annotations

import re
from dataclasses import dataclass

from .targets import ProgramError, line_of

NUMBER = re.compile(r"(?:\d+\.?\d*|\.\d+)(?:[eE][+-]?\d+)?")
NAME = re.compile(r"[A-Za-z_$][A-Za-z0-9_$]*")
_CLOSE = {")": "(", "]": "[", "}": "{"}


@dataclass(frozen=True)
class Token:
    """One token: ``kind`` is name, number, string, comment, newline or op."""

    kind: str
    text: str
    start: int
    end: int
    depth: int  # bracket depth before the token


def tokenize(text: str, comment: str, quotes: str = "\"'", source: str = "program",
             escape: str | None = "\\") -> list[Token]:
    """Tokens of ``text``; ``comment`` the line-comment character (``#``, ``;``),
    ``quotes`` the string delimiters, ``escape`` the character that escapes one in a
    string (None: none).

    Raises ProgramError for an unterminated string or unbalanced brackets, naming the line.
    """
    out: list[Token] = []
    stack: list[tuple[str, int]] = []
    i, n = 0, len(text)
    while i < n:
        ch = text[i]
        depth = len(stack)
        if ch == "\n":
            out.append(Token("newline", ch, i, i + 1, depth))
            i += 1
        elif ch in " \t\r\f\v":
            i += 1
        elif ch == comment:
            j = text.find("\n", i)
            j = n if j < 0 else j
            out.append(Token("comment", text[i:j], i, j, depth))
            i = j
        elif ch in quotes:
            j = i + 1
            while j < n and text[j] not in (ch, "\n"):
                j += 2 if text[j] == escape else 1
            if j >= n or text[j] != ch:
                raise ProgramError(f"{source}: line {line_of(text, i)}: unterminated string")
            out.append(Token("string", text[i:j + 1], i, j + 1, depth))
            i = j + 1
        elif m := NUMBER.match(text, i):
            out.append(Token("number", m.group(), i, m.end(), depth))
            i = m.end()
        elif m := NAME.match(text, i):
            out.append(Token("name", m.group(), i, m.end(), depth))
            i = m.end()
        else:
            two = text[i:i + 2]
            op = two if two in ("==", "!=", "<=", ">=", ":=") else ch
            if op in "([{":
                stack.append((op, i))
            elif op in _CLOSE:
                if not stack or stack[-1][0] != _CLOSE[op]:
                    raise ProgramError(f"{source}: line {line_of(text, i)}: unbalanced "
                                       f"'{op}'")
                stack.pop()
                depth = len(stack)
            out.append(Token("op", op, i, i + len(op), depth))
            i += len(op)
    if stack:
        op, at = stack[-1]
        raise ProgramError(f"{source}: line {line_of(text, at)}: '{op}' is never closed")
    return out


def signed_numbers(tokens: list[Token]) -> list[tuple[float, int, int]] | None:
    """The values of a comma-separated list of (optionally signed) numbers, each with the
    span to rewrite (the sign included); None when anything else is in the list."""
    vals, k = [], 0
    while k < len(tokens):
        sign, start = 1.0, tokens[k].start
        if tokens[k].text in "+-" and tokens[k].kind == "op":
            sign = -1.0 if tokens[k].text == "-" else 1.0
            k += 1
        if k >= len(tokens) or tokens[k].kind != "number":
            return None
        vals.append((sign * float(tokens[k].text), start, tokens[k].end))
        k += 1
        if k < len(tokens):
            if tokens[k].text != ",":
                return None
            k += 1
            if k == len(tokens):
                return None
    return vals
