"""The :class:`Effect` interface: one physical cause of error.

An effect owns named parameters (with internal units and a typical scale) and
perturbs the chain at one *stage*; the :class:`~calibration.fit.error_model.ErrorModel`
composes the stages in this order:

``joint``   adds a correction to one joint's angle, per pose
            (compliance, harmonics, backlash, scale, coupling, tables, ...)
``table``   adds deltas to the (n_joints, 5) parameter table (geometric errors)
``length``  grows every link length by a per-pose factor (thermal)
``tool``    gives the target centre in the flange frame (tool)
``target``  gives a 6-DoF target's orientation in the flange frame (tool_rotation)
``base``    maps base-frame points into the tracker frame (base)
``drift``   moves the point in the tracker frame per pose, over time (base_drift)
``measure`` distorts the tracker's reading (tracker_scale)

A user-defined effect is a subclass of :class:`JointEffect` in a short Python
file (see the README); it is named and used like a built-in.

Internal units: mm, rad, s, N·m, °C; ``units`` names them per parameter. In
files a person reads, angles are written in degrees (see ``display_unit``).
"""

from __future__ import annotations

from typing import Any, ClassVar

import numpy as np

from ..data.dataset import Dataset
from ..errors import EffectError
from ..model.robot_model import RobotModel


def display_unit(unit: str) -> tuple[str, float]:
    """The unit a parameter is written in files, and the factor from the internal unit.

    Angles (``rad``) are written in degrees; every other unit as it is (a compliance stays
    in rad/(N*m), as drive makers quote it)."""
    if unit == "rad":
        return "deg", float(np.degrees(1.0))
    return unit, 1.0


class Effect:
    """Base class of every effect. Subclasses set the class attributes and one stage hook.

    Parameters
    ----------
    model : the nominal robot
    joint : 1-based joint for per-joint families, None otherwise
    order : harmonic order K (only for families that take one)
    """

    #: family name as on the command line ("compliance")
    family: ClassVar[str] = ""
    #: stage at which it acts (see the module docstring)
    stage: ClassVar[str] = ""
    #: True when the family is named per joint ("compliance:3")
    per_joint: ClassVar[bool] = False
    #: True when the family takes an order ("harmonic12:1")
    takes_order: ClassVar[bool] = False
    #: one line of physics for listings
    summary: ClassVar[str] = ""
    #: a user's effect file's (name, sha256), set by ``load_effect_file`` (absent otherwise)
    _cellcal_source: ClassVar[tuple[str, str]]

    def __init__(
        self, model: RobotModel, joint: int | None = None, order: int | None = None
    ) -> None:
        if self.per_joint:
            if joint is None:
                raise EffectError(f"effect {self.family!r} needs a joint: {self.family}:J")
            if not 1 <= joint <= model.n_joints:
                raise EffectError(
                    f"effect {self.family}:{joint}: the model has joints 1..{model.n_joints}"
                )
        elif joint is not None:
            raise EffectError(f"effect {self.family!r} is not per joint; drop ':{joint}'")
        if order is not None and not self.takes_order:
            raise EffectError(f"effect {self.family!r} takes no order")
        self.model = model
        self.joint = joint
        self.order = order
        #: local parameter names, internal units and typical magnitudes
        self.param_names: list[str] = []
        self.units: list[str] = []
        self.scales: np.ndarray = np.zeros(0)

    # ---- naming -------------------------------------------------------------
    @property
    def label(self) -> str:
        """The effect's name as on the command line: ``compliance:3``, ``harmonic12:1``."""
        fam = self.family + (str(self.order) if self.order not in (None, 1) else "")
        return fam if self.joint is None else f"{fam}:{self.joint}"

    @property
    def prefix(self) -> str:
        fam = self.family + (str(self.order) if self.order not in (None, 1) else "")
        return fam if self.joint is None else f"{fam}.j{self.joint}"

    @property
    def full_names(self) -> list[str]:
        return [f"{self.prefix}.{n}" for n in self.param_names]

    @property
    def n_params(self) -> int:
        return len(self.param_names)

    def __repr__(self) -> str:
        return f"<{type(self).__name__} {self.label}>"

    # ---- lifecycle ------------------------------------------------------------
    def bind(self, data: Dataset, nominal: Any) -> Any:
        """Precompute what this effect needs from a data set (gravity torques, directions...).

        ``nominal`` is the nominal model's :class:`~calibration.model.kinematics.ChainResult` for
        the data's joints. Returns an opaque state handed back to the stage hook. Raise
        :class:`EffectError` when the data lack what the effect needs.
        """
        return None

    def prepare(self, data: Dataset) -> Dataset:
        """Called once on the whole data set, in capture order, before calibration and
        validation rows are split (e.g. to derive approach directions). Returns the data,
        possibly with columns added."""
        return data

    def pinned(self, state: Any) -> dict[str, str]:
        """Local parameter names to hold at their start value for this data, with reasons."""
        return {}

    def initial(self, data: Dataset, nominal: Any, state: Any) -> np.ndarray:
        """Starting values (internal units); zeros unless the effect knows better."""
        return np.zeros(self.n_params)

    def describe(self, state: Any) -> list[str]:
        """Notes for the user about how the effect was applied (e.g. derived directions)."""
        return []


class JointEffect(Effect):
    """An effect that corrects one joint's angle per pose: θ_true = θ_reported + Δθ(p).

    Subclasses implement :meth:`delta`, returning the correction (rad) and its exact
    partial derivatives with respect to the effect's parameters.
    """

    stage: ClassVar[str] = "joint"
    per_joint: ClassVar[bool] = True
    joint: int  # 1-based, always given for a per-joint family

    def delta(self, p: np.ndarray, data: Dataset, state: Any) -> tuple[np.ndarray, np.ndarray]:
        """Joint correction for every pose.

        Returns
        -------
        delta : (n,) rad
        partials : (n, n_params), d delta / d p
        """
        raise NotImplementedError
