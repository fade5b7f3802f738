"""Universal Robots ``calibration.conf`` deltas, and the exact conversion to pure DH.

A UR controller stores its factory calibration as deltas to the nominal standard-DH
table: ``delta_theta``, ``delta_a``, ``delta_d``, ``delta_alpha`` per joint, in metres
and radians; the calibrated chain is nominal + delta, element-wise.

Our geometric model carries the Hayati tilt beta on rows whose neighbouring axes are
parallel; pure DH cannot hold it. :func:`to_pure_dh` converts a table exactly: each
row's fixed part ``Tx(a) Rx(alpha) Ry(beta)`` is re-expressed through the common
normal of the two joint axes (as lines in space),
``Rz(psi) Tz(dd) Tx(a') Rx(alpha') · Rz(phi') Tz(s')``, and the remainder
``Rz(phi') Tz(s')`` (a turn about and a slide along the next joint's axis) is pushed
into the next row's theta and d, where it commutes with the joint rotation. Nearly
parallel axes have their common normal far away: the conversion gives the huge,
mutually cancelling d-deltas that UR factory calibrations show. Forward kinematics
(the whole flange pose) is preserved to rounding.

Inside: rad and mm tables (N, 5) as :meth:`RobotModel.dh_table`; UR deltas: rad and m.
"""

from __future__ import annotations

import math
import re
from pathlib import Path
from typing import Any

import numpy as np

from ..errors import URConfError
from ..files import write_atomic
from ..model.kinematics import ALPHA, BETA, THETA, A, D
from ..model.robot_model import RobotModel

#: the four delta arrays of calibration.conf, in the order UR writes them
DELTA_KEYS = ("delta_theta", "delta_a", "delta_d", "delta_alpha")


def _decompose(a: float, alpha: float,
               beta: float) -> tuple[float, float, float, float, float, float]:
    """Tx(a) Rx(alpha) Ry(beta) = Rz(psi) Tz(dd) Tx(a') Rx(alpha') Rz(phi') Tz(s').

    Returns psi, dd, a', alpha', phi', s' (rad, mm). The DH x axis is the common normal
    of the z axis and the next joint axis, signed to stay nearest the current x axis.
    """
    sa, ca = math.sin(alpha), math.cos(alpha)
    sb, cb = math.sin(beta), math.cos(beta)
    # G = [Rg | og]; the next joint axis is the line through og along u = Rg e_z
    Rg = np.array([[cb, 0.0, sb], [sa * sb, ca, -sa * cb], [-ca * sb, sa, ca * cb]])
    o = np.array([a, 0.0, 0.0])
    u = Rg[:, 2]
    sxy2 = u[0] * u[0] + u[1] * u[1]
    if sxy2 == 0.0:  # exactly parallel: any normal will do; keep the current one
        t1, s_next = 0.0, 0.0
        a_new, alpha_new, psi = a, math.atan2(0.0, u[2]), 0.0
    else:
        sxy = math.sqrt(sxy2)
        x = np.array([-u[1], u[0], 0.0]) / sxy
        if x[0] < 0 or (x[0] == 0 and x[1] < 0):
            x = -x
        t2 = -(o[0] * u[0] + o[1] * u[1]) / sxy2
        t1 = o[2] + t2 * u[2]
        # P2 - P1 = o + t2 u - t1 e_z, along x by construction
        diff = o + t2 * u - np.array([0.0, 0.0, t1])
        a_new = float(diff @ x)
        alpha_new = math.atan2(-u[1] * x[0] + u[0] * x[1], u[2])
        psi = math.atan2(x[1], x[0])
        s_next = -t2
    cpsi, spsi = math.cos(psi), math.sin(psi)
    cal, sal = math.cos(alpha_new), math.sin(alpha_new)
    Rp = np.array([[cpsi, -spsi * cal, spsi * sal],
                   [spsi, cpsi * cal, -cpsi * sal],
                   [0.0, sal, cal]])
    rem = Rp.T @ Rg  # = Rz(phi')
    phi = math.atan2(rem[1, 0], rem[0, 0])
    return psi, t1, a_new, alpha_new, phi, s_next


def to_pure_dh(table: np.ndarray) -> np.ndarray:
    """An equivalent standard-DH table without beta (same flange pose for every q).

    Parameters
    ----------
    table : array, shape (N, 5), theta_offset, d, a, alpha, beta (rad, mm), ``dh`` rows

    Returns
    -------
    array, shape (N, 5), the same columns with beta = 0

    Raises
    ------
    ValueError when the last row has a beta (the flange frame itself would be tilted).
    """
    t = np.array(table, float)
    if t[-1, BETA] != 0.0:
        raise ValueError("the last row has a beta tilt: pure DH cannot hold the flange frame")
    out = t.copy()
    out[:, BETA] = 0.0
    carry_theta, carry_d = 0.0, 0.0
    for i in range(len(t) - 1):
        psi, dd, a_new, alpha_new, phi, s_next = _decompose(t[i, A], t[i, ALPHA], t[i, BETA])
        out[i, THETA] = t[i, THETA] + carry_theta + psi
        out[i, D] = t[i, D] + carry_d + dd
        out[i, A] = a_new
        out[i, ALPHA] = alpha_new
        carry_theta, carry_d = phi, s_next
    out[-1, THETA] = t[-1, THETA] + carry_theta
    out[-1, D] = t[-1, D] + carry_d
    return out


def deltas_from_table(table: np.ndarray, nominal: np.ndarray) -> dict[str, np.ndarray]:
    """UR deltas (rad, m) that turn the nominal table into ``table`` (converted to pure DH).

    Parameters
    ----------
    table : (N, 5) calibrated table (rad, mm), may carry beta
    nominal : (N, 5) the controller's nominal table (rad, mm), beta = 0
    """
    if np.any(np.asarray(nominal)[:, BETA] != 0.0):
        raise ValueError("the nominal table must be pure DH (beta = 0)")
    pure = to_pure_dh(table)
    delta = pure - nominal
    delta[:, THETA] = (delta[:, THETA] + math.pi) % (2 * math.pi) - math.pi
    return {
        "delta_theta": delta[:, THETA],
        "delta_a": delta[:, A] / 1000.0,
        "delta_d": delta[:, D] / 1000.0,
        "delta_alpha": delta[:, ALPHA],
    }


def table_from_deltas(nominal: np.ndarray, deltas: dict) -> np.ndarray:
    """nominal + deltas, element-wise as the controller does; table (N, 5) rad, mm."""
    nominal = np.asarray(nominal, float)
    N = len(nominal)
    arr = {}
    for k in DELTA_KEYS:
        if k not in deltas:
            raise URConfError(f"delta set lacks {k}")
        v = np.asarray(deltas[k], float)
        if v.shape != (N,):
            raise URConfError(f"{k} has {v.size} values, the model has {N} joints")
        if not np.isfinite(v).all():
            raise URConfError(f"{k} has a non-finite value")
        arr[k] = v
    t = nominal.copy()
    t[:, THETA] += arr["delta_theta"]
    t[:, A] += arr["delta_a"] * 1000.0
    t[:, D] += arr["delta_d"] * 1000.0
    t[:, ALPHA] += arr["delta_alpha"]
    return t


def model_table_ur(nominal: dict) -> np.ndarray:
    """A nominal table (rad, mm) from UR's lists in metres and radians (d, a, theta, alpha)."""
    z = np.zeros(len(nominal["d"]))
    return np.column_stack([np.asarray(nominal.get("theta", z), float),
                            np.asarray(nominal["d"], float) * 1000.0,
                            np.asarray(nominal["a"], float) * 1000.0,
                            np.asarray(nominal["alpha"], float), z])


def model_from_table(model: RobotModel, table: np.ndarray, *, name: str | None = None,
                     tool: np.ndarray | None = None) -> RobotModel:
    """``model`` with its kinematic table replaced (rad, mm in; deg, mm in the model)."""
    joints = [j.model_dump() for j in model.joints]
    for row, j in zip(np.asarray(table, float), joints, strict=True):
        j["theta_offset"] = math.degrees(row[THETA])
        j["d"] = float(row[D])
        j["a"] = float(row[A])
        j["alpha"] = math.degrees(row[ALPHA])
        j["beta"] = math.degrees(row[BETA])
    changes: dict[str, Any] = {"joints": joints}
    if name is not None:
        changes["name"] = name
    if tool is not None:
        changes["tool"] = tuple(float(v) for v in tool)
    return model.with_changes(**changes)


# ---- calibration.conf -----------------------------------------------------------------
_LINE = re.compile(r"^\s*(\w+)\s*=\s*\[(.*)\]\s*$")


def read_calibration_conf(path: str | Path) -> dict[str, np.ndarray]:
    """The four delta arrays (rad, m) of a UR ``calibration.conf`` (``[mounting]`` section)."""
    path = Path(path)
    try:
        text = path.read_text()
    except FileNotFoundError:
        raise URConfError(f"{path}: no such file") from None
    out: dict[str, np.ndarray] = {}
    for line_no, line in enumerate(text.splitlines(), start=1):
        m = _LINE.match(line)
        if not m or m[1] not in DELTA_KEYS:
            continue
        try:
            out[m[1]] = np.array([float(v) for v in m[2].split(",") if v.strip()])
        except ValueError:
            raise URConfError(f"{path}: line {line_no}: {m[1]}: not a list of numbers") from None
    missing = [k for k in DELTA_KEYS if k not in out]
    if missing:
        raise URConfError(f"{path}: missing {', '.join(missing)}")
    return out


def format_calibration_conf(deltas: dict) -> str:
    """calibration.conf text for a delta set (rad, m), full double precision."""
    lines = ["[mounting]"]
    for k in DELTA_KEYS:
        vals = ", ".join(repr(float(v)) for v in deltas[k])
        lines.append(f"  {k} = [{vals}]")
    return "\n".join(lines) + "\n"


def write_calibration_conf(deltas: dict, path: str | Path) -> None:
    write_atomic(path, format_calibration_conf(deltas))
