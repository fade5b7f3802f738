"""Targets that contradict themselves: nominal joints that do not reach their own x, y, z.

A targets CSV may give each target's nominal joints (``q1..qN``, the joints the program
uses today) next to its point. :func:`compensate <calibration.compensation.compensation.compensate>`
starts from those joints and reports the correction against their nominal point, so
joints that put the tool somewhere else give a "correction" of that distance and new
joints far from the given ones, reported as reached. :func:`check_joints_reach` refuses
them first, naming the rows and the distances.

Targets beyond the calibrated envelope (:class:`calibration.fit.envelope.Envelope`, the
ranges the calibration data covered): :func:`outside_envelope` names, per target, the
joints (and thermal quantities) that lie beyond it; :func:`refuse_outside` is
``--strict-range`` (exit 3).
"""

from __future__ import annotations

import numpy as np

from calibration.compensation.compensation import Targets
from calibration.fit.envelope import outside_envelope, refuse_outside
from calibration.model.inverse import ChainFK

from ..errors import UsageError
from ..flags.choices import JOINTS_TOLERANCE_MM

__all__ = ["JOINTS_TOLERANCE_MM", "check_joints_reach", "no_envelope_note", "outside_envelope",
           "refuse_outside"]



def no_envelope_note(params: str, what: str = "targets") -> str:
    """What is said when a params.json records no envelope (``what``: the targets, the
    poses... that are not checked against it)."""
    return (f"{params} records no calibrated envelope (written before cellcal recorded "
            f"one): the {what} are not checked against the ranges the calibration "
            "measured; calibrate again to have them checked")


def check_joints_reach(targets: Targets, model, tolerance_mm: float, source: str) -> None:
    """Refuse (UsageError, exit 2) targets whose nominal joints put the tool (``model``'s
    nominal chain and tool) more than ``tolerance_mm`` from their x, y, z; the message
    names the file ``source``, the rows (line, pose_id) and the distances."""
    if targets.q is None:
        return
    d = np.linalg.norm(ChainFK.from_model(model).point(targets.q) - targets.base_p_tcp, axis=1)
    bad = np.flatnonzero(~(d <= tolerance_mm))
    if bad.size == 0:
        return
    lines = targets.lines or [None] * len(d)
    rows = [f"{'' if lines[i] is None else f'line {lines[i]} '}(pose_id "
            f"{targets.pose_id[i]}): {d[i]:.1f} mm" for i in bad[:10]]
    more = f", and {bad.size - 10} more" if bad.size > 10 else ""
    raise UsageError(
        f"{source}: the joints q1..q{model.n_joints} of {bad.size} of {len(d)} targets do not "
        f"reach their x, y, z on the nominal model (more than --joints-tolerance-mm "
        f"{tolerance_mm:g} mm away): {'; '.join(rows)}{more}. Fix the joints or the point, "
        "leave q1..qN out to have them solved, or raise --joints-tolerance-mm")
