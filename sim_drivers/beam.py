"""The simulated tracker's line of sight: the beam reaches the SMR only when a real one would.

:class:`BeamPhysics` holds the true cell's geometry (always on for a true robot that has
it, :meth:`~sim_drivers.model_truth.ModelTruth.beam_geometry`): the true robot's links as
capsules (the model's ``link_radius``, at the true joints), the true SMR axis on the
flange and the mounted reflector's acceptance half-angle, the tracker where the true
base pose puts it, and the cell's fixtures. :meth:`BeamPhysics.blocked` says why the
beam cannot reach the true SMR centre (no margins: this is the physics, not a plan), or
None. The geometry is :func:`calibration.cell.visibility.assess`, the planner's own, with
the truth in place of the nominal.

The links' pose comes from the nominal chain at the true joints: the hidden geometric
errors (tenths of a millimetre) are far below a link's radius.
"""

from __future__ import annotations

import numpy as np

from calibration.cell.cell import CellSpec, Smr, tracker_in_base
from calibration.cell.visibility import assess


class BeamPhysics:
    """The line of sight of one simulated cell.

    Parameters
    ----------
    model : RobotModel
        The robot's nominal model with its link radii (and tool).
    tracker_T_base : (4, 4)
        The true pose of the robot base in the tracker frame (mm).
    smr_axis : (3,)
        The true SMR axis in the flange frame.
    acceptance_deg : float
        The mounted reflector's acceptance half-angle.
    cell : CellSpec, optional
        The cell's fixtures (base frame).
    """

    def __init__(self, model, tracker_T_base, smr_axis, acceptance_deg: float,
                 cell: CellSpec | None = None) -> None:
        T = np.asarray(tracker_T_base, float)
        self.model = model
        self.base_T_tracker = np.linalg.inv(T)
        self.cell = (cell or CellSpec()).model_copy(update={
            "smr": Smr(axis=tuple(float(v) for v in smr_axis), acceptance_deg=acceptance_deg)})
        self.cell = self.cell.with_tracker(tracker_in_base(T), "the simulated cell")

    def sight(self, q: np.ndarray, p_tracker: np.ndarray):
        """The :class:`~calibration.cell.visibility.Sight` of the true SMR centre ``p_tracker``
        (mm, tracker frame) at the true joints ``q`` (rad, (N,)), without margins."""
        p = self.base_T_tracker[:3, :3] @ np.asarray(p_tracker, float) + self.base_T_tracker[:3, 3]
        return assess(self.model, np.asarray(q, float)[None], self.cell, margins=False,
                      smr_p=p[None])

    def blocked(self, q: np.ndarray, p_tracker: np.ndarray) -> str | None:
        """Why the beam cannot reach the SMR at ``q`` (see :meth:`sight`), or None."""
        s = self.sight(q, p_tracker)
        return None if bool(s.visible[0]) else s.reason(0)
