"""RAPID's data as a module writes them: aggregates ``[...]`` read into trees, and the
records a target depends on (``robtarget``, ``jointtarget``, ``tooldata``, ``wobjdata``,
``loaddata``) read from them, each number with its span so that a rewrite changes only
its characters.

A record is positional (ABB's RAPID reference, data types): ``robtarget`` is
``[trans, rot, robconf, extax]`` (``[x, y, z]`` mm, ``[q1, q2, q3, q4]`` a quaternion,
scalar first, ``[cf1, cf4, cf6, cfx]``, six external axes, ``9E+09`` for none);
``jointtarget`` ``[robax, extax]`` (six axis angles, deg); ``tooldata``
``[robhold, tframe, tload]``; ``wobjdata`` ``[robhold, ufprog, ufmec, uframe, oframe]``;
``loaddata`` ``[mass, cog, aom, ix, iy, iz]``; a pose (``tframe``, ``uframe``,
``oframe``) ``[trans, rot]``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from .poses import T_to_rapid, rapid_to_T
from .tokens import Token, signed_numbers


@dataclass(frozen=True)
class Agg:
    """An aggregate: its items (a nested :class:`Agg`, or the tokens of an expression) and
    the character span from ``[`` to ``]``."""

    items: tuple
    start: int
    end: int


def aggregate(toks: list[Token], k: int) -> tuple[Agg, int]:
    """The aggregate whose ``[`` is ``toks[k]``, and the index of its ``]``."""
    depth, items, cur, j = toks[k].depth, [], [], k + 1
    while not (toks[j].text == "]" and toks[j].depth == depth):
        t = toks[j]
        if t.text == "[" and t.depth == depth + 1 and not cur:
            sub, j = aggregate(toks, j)
            cur = sub
        elif t.text == "," and t.depth == depth + 1:
            items.append(cur)
            cur = []
        elif isinstance(cur, Agg):  # an aggregate followed by more: an expression
            cur = [_NOT_A_VALUE]
        else:
            cur.append(t)
        j += 1
    if cur or items:
        items.append(cur)
    return Agg(tuple(items), toks[k].start, toks[j].end), j


#: stands for an item that is neither an aggregate nor a plain expression
_NOT_A_VALUE = Token("op", "?", 0, 0, 0)


def number(item) -> tuple[float, int, int] | None:
    """(value, start, end) of an item that is one (signed) finite number literal, else
    None."""
    if isinstance(item, Agg):
        return None
    got = signed_numbers(item)
    ok = got is not None and len(got) == 1 and math.isfinite(got[0][0])
    return got[0] if ok else None


def numbers(item, n: int) -> list[tuple[float, int, int]] | None:
    """The n number literals of an aggregate item, else None."""
    if not isinstance(item, Agg) or len(item.items) != n:
        return None
    got = [number(i) for i in item.items]
    return None if any(g is None for g in got) else got


def word(item) -> str | None:
    """The upper-cased name of an item that is one name (``TRUE``, ``FALSE``), else None."""
    if isinstance(item, Agg) or len(item) != 1 or item[0].kind != "name":
        return None
    return item[0].text.upper()


def is_robtarget(agg) -> bool:
    """An aggregate shaped as a robtarget: four aggregates of 3, 4, 4 and 6 items."""
    return (isinstance(agg, Agg) and len(agg.items) == 4
            and all(isinstance(i, Agg) and len(i.items) == n
                    for i, n in zip(agg.items, (3, 4, 4, 6), strict=True)))


def is_jointtarget(agg) -> bool:
    """An aggregate shaped as a jointtarget: two aggregates of 6 items."""
    return (isinstance(agg, Agg) and len(agg.items) == 2
            and all(isinstance(i, Agg) and len(i.items) == 6 for i in agg.items))


@dataclass(frozen=True)
class Read:
    """A target's values read from its aggregate: the values (robtarget: x, y, z mm and
    q1..q4; jointtarget: the six axes, deg), their spans, the span of the text they are
    in (``[x, y, z], [q1, q2, q3, q4]``; ``[a1, ..., a6]``), the robconf (four integers,
    or None) and whether an external axis is set (not 9E+09)."""

    values: tuple[float, ...]
    spans: tuple[tuple[int, int], ...]
    span: tuple[int, int]
    robconf: tuple[int, ...] | None
    extax_set: bool


#: the value RAPID writes for an external axis that is not there
EXTAX_NONE = 9e9
#: a quaternion farther than this from unit (|sum of squares - 1|) is no orientation
#: (RAPID's own limit for one it will normalise)
QUAT_TOLERANCE = 0.1


def _extax_set(item) -> bool:
    got = [number(i) for i in item.items] if isinstance(item, Agg) else []
    return any(g is None or abs(g[0]) < EXTAX_NONE * 0.99 for g in got)


def read_robtarget(agg) -> Read | str:
    """A robtarget's pose, or why it cannot be compensated."""
    if not isinstance(agg, Agg) or len(agg.items) != 4:
        return "not a robtarget [trans, rot, robconf, extax]"
    trans, rot = numbers(agg.items[0], 3), numbers(agg.items[1], 4)
    for got, what, n in ((trans, "trans", 3), (rot, "rot", 4)):
        if got is None:
            return f"its {what} is not {n} numbers"
    norm2 = sum(v * v for v, _, _ in rot)
    if abs(norm2 - 1.0) > QUAT_TOLERANCE:
        return (f"its rot is not a unit quaternion (sum of squares {norm2:.4g}): not an "
                "orientation the controller takes")
    conf = numbers(agg.items[2], 4)
    robconf = (tuple(int(v) for v, _, _ in conf)
               if conf is not None and all(v == int(v) for v, _, _ in conf) else None)
    got = trans + rot
    return Read(tuple(v for v, _, _ in got), tuple((a, b) for _, a, b in got),
                (agg.items[0].start, agg.items[1].end), robconf, _extax_set(agg.items[3]))


def read_jointtarget(agg) -> Read | str:
    """A jointtarget's robot axes (deg), or why it cannot be compensated."""
    if not isinstance(agg, Agg) or len(agg.items) != 2:
        return "not a jointtarget [robax, extax]"
    robax = numbers(agg.items[0], 6)
    if robax is None:
        return "its robax is not 6 numbers"
    return Read(tuple(v for v, _, _ in robax), tuple((a, b) for _, a, b in robax),
                (agg.items[0].start, agg.items[0].end), None, _extax_set(agg.items[1]))


def read_pose(item) -> tuple[float, ...] | None:
    """``[[x, y, z], [q1, q2, q3, q4]]`` as (x, y, z, q1..q4), else None (not numbers,
    or a quaternion far from unit)."""
    if not isinstance(item, Agg) or len(item.items) != 2:
        return None
    trans, rot = numbers(item.items[0], 3), numbers(item.items[1], 4)
    if trans is None or rot is None:
        return None
    if abs(sum(v * v for v, _, _ in rot) - 1.0) > QUAT_TOLERANCE:
        return None
    return tuple(v for v, _, _ in trans + rot)


@dataclass(frozen=True)
class Tool:
    """A tooldata: the TCP (x, y, z, q1..q4 in the flange frame) and the tool's mass."""

    tframe: tuple[float, ...]
    mass_kg: float | None


def read_tooldata(agg) -> Tool | str:
    """A tooldata, or why its TCP is not known."""
    if not isinstance(agg, Agg) or len(agg.items) != 3:
        return "not a tooldata [robhold, tframe, tload]"
    hold = word(agg.items[0])
    if hold == "FALSE":
        return ("a stationary tool (robhold FALSE): the robot holds the work object, the "
                "TCP is not on the flange")
    if hold != "TRUE":
        return "its robhold is not TRUE or FALSE"
    tframe = read_pose(agg.items[1])
    if tframe is None:
        return "its tframe is not a pose of numbers"
    load = agg.items[2]
    mass = number(load.items[0]) if isinstance(load, Agg) and load.items else None
    return Tool(tframe, None if mass is None else mass[0])


def read_wobjdata(agg) -> tuple[float, ...] | str:
    """A wobjdata's object frame in the robot's base frame (uframe * oframe, as a pose
    x, y, z, q1..q4; the world frame taken as the base frame), or why it is not known."""
    if not isinstance(agg, Agg) or len(agg.items) != 5:
        return "not a wobjdata [robhold, ufprog, ufmec, uframe, oframe]"
    hold, prog = word(agg.items[0]), word(agg.items[1])
    if hold == "TRUE":
        return ("the robot holds the work object (robhold TRUE): a stationary tool, the "
                "targets are not in the base frame")
    if prog == "FALSE":
        return ("its user frame moves (ufprog FALSE: coordinated with a mechanical unit), "
                "known at run time")
    if hold != "FALSE" or prog != "TRUE":
        return "its robhold or ufprog is not TRUE or FALSE"
    frames = [read_pose(agg.items[k]) for k in (3, 4)]
    if any(f is None for f in frames):
        return "its uframe or oframe is not a pose of numbers"
    return T_to_rapid(rapid_to_T(frames[0]) @ rapid_to_T(frames[1]))


def read_loaddata(agg) -> float | str:
    """A loaddata's mass (kg), or why it is not known."""
    mass = number(agg.items[0]) if isinstance(agg, Agg) and len(agg.items) == 6 else None
    return "not a loaddata with a mass" if mass is None else mass[0]
