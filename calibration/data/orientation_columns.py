"""The measurement CSV's orientation columns (FORMATS §1): ``qw, qx, qy, qz``, ``sigma_deg``,
``tool_id``, read strictly.

A 6-DoF target (a T-Mac, say) gives each row an orientation: the unit quaternion
(w, x, y, z) of the measured target frame in the tracker frame, and the tracker's
standard uncertainty of it in degrees. ``tool_id`` names which target on the tool a
row measured (SMR nests or 6-DoF targets), when a pose measures several.

:func:`read_orientation_columns` takes the strict CSV table of
:mod:`calibration.data.dataset` (any object with its ``col``, ``lines``, ``source``,
``all_or_none``, ``numeric`` and ``text``) and returns plain arrays; every refusal is
a :class:`~calibration.errors.DataError` naming the file, the line and the column.

Unit length. A quaternion is refused when ``| |q| - 1 | > UNIT_TOLERANCE`` (1e-5).
Rounding each of the four components to d decimals moves the norm by at most
10^-d (the sum of |q_i| is at most 2), so any quaternion written with 5 or more
decimals passes. One that is further off is either no unit quaternion at all (Euler
angles, a rotation vector, a shifted column) or written so coarsely that the rounding
alone (~1e-4 rad, 0.006 deg) rivals a T-Mac's 0.01 deg: neither is guessed at. An
accepted quaternion is normalised, so downstream code may rely on unit length.
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from ..errors import DataError

if TYPE_CHECKING:
    from .dataset import CsvTable

#: the quaternion columns, scalar first
QUAT_COLUMNS = ("qw", "qx", "qy", "qz")
#: largest accepted | |q| - 1 | (see the module docstring)
UNIT_TOLERANCE = 1e-5
#: largest plausible orientation uncertainty, deg (a half turn: anything beyond says nothing)
MAX_SIGMA_DEG = 180.0
#: a tool_id: a short token (letters, digits, ``_ . : -``), at most 32 characters
TOOL_ID = re.compile(r"[A-Za-z0-9][A-Za-z0-9_.:\-]{0,31}")


@dataclass(frozen=True)
class OrientationColumns:
    """What the orientation columns of one file hold (None for a column the file lacks).

    Attributes
    ----------
    quat : (n, 4) unit quaternions (w, x, y, z) of the target frame in the tracker frame
    sigma_deg : (n,) the orientation's standard uncertainty, deg
    tool_id : (n,) object array of str, the target each row measured
    """

    quat: np.ndarray | None = None
    sigma_deg: np.ndarray | None = None
    tool_id: np.ndarray | None = None


def _line_error(table: CsvTable, r: int, column: str, message: str) -> DataError:
    return DataError(f"{table.source}: line {table.lines[r]}, column {column}: {message}")


def read_quaternions(table: CsvTable) -> np.ndarray | None:
    """The ``qw, qx, qy, qz`` columns as (n, 4) unit quaternions, or None when absent.

    Refuses a part of the four, an empty or non-numeric value, and a quaternion whose
    length differs from 1 by more than :data:`UNIT_TOLERANCE` (naming its line).
    """
    if not table.all_or_none(list(QUAT_COLUMNS), "orientations (a unit quaternion)"):
        return None
    q = np.column_stack([table.numeric(c) for c in QUAT_COLUMNS])
    norm = np.linalg.norm(q, axis=1)
    bad = ~(np.abs(norm - 1.0) <= UNIT_TOLERANCE)
    if bad.any():
        r = int(np.argmax(bad))
        raise _line_error(table, r, "qw..qz",
                          f"quaternion ({', '.join(f'{v:g}' for v in q[r])}) has length "
                          f"{norm[r]:.9g}, not 1 (within {UNIT_TOLERANCE:g}): qw, qx, qy, qz "
                          "must be a unit quaternion, scalar first")
    return q / norm[:, None]


def read_sigma_deg(table: CsvTable, has_quat: bool) -> np.ndarray | None:
    """The ``sigma_deg`` column (positive, finite, at most :data:`MAX_SIGMA_DEG`), or None.

    Refused without the quaternion columns: an uncertainty of orientations that are not
    there is a file that lost columns.
    """
    if "sigma_deg" not in table.col:
        return None
    if not has_quat:
        raise table.error("sigma_deg (the orientation's uncertainty) needs the orientation "
                          f"columns {', '.join(QUAT_COLUMNS)}")
    s = table.numeric("sigma_deg")
    bad = ~((s > 0) & (s <= MAX_SIGMA_DEG))
    if bad.any():
        r = int(np.argmax(bad))
        raise _line_error(table, r, "sigma_deg",
                          f"{s[r]:g} is not a positive uncertainty of at most "
                          f"{MAX_SIGMA_DEG:g} deg")
    return s


def read_tool_ids(table: CsvTable) -> np.ndarray | None:
    """The ``tool_id`` column as an object array of str, or None when absent.

    Every row names its target with a short token (:data:`TOOL_ID`): an empty value or
    one with spaces, quotes or other punctuation is refused, naming its line.
    """
    if "tool_id" not in table.col:
        return None
    ids = table.text("tool_id")
    for r, v in enumerate(ids):
        if not TOOL_ID.fullmatch(v):
            what = "empty value" if v == "" else f"{v[:40]!r} is not a short token"
            raise _line_error(table, r, "tool_id",
                              f"{what} (letters, digits, _ . : -; at most 32 characters, "
                              "starting with a letter or digit)")
    return np.array(ids, dtype=object)


def read_orientation_columns(table: CsvTable) -> OrientationColumns:
    """Every orientation column of ``table`` (see :class:`OrientationColumns`)."""
    quat = read_quaternions(table)
    return OrientationColumns(quat, read_sigma_deg(table, quat is not None),
                              read_tool_ids(table))
