"""A candidate effect's Jacobian columns at a fit: a joint effect's by one multiplication
(dP/dq_J times its partials), harmonics of every order on a joint at once, a measure-stage
effect's from the fit's predictions, others by evaluating the extended model."""

from __future__ import annotations

from typing import TYPE_CHECKING, Any, cast

import numpy as np

from ..data.dataset import Dataset
from ..effects import Effect, JointEffect
from ..effects.physical import Harmonic
from ..fit.error_model import Bound, ErrorModel

if TYPE_CHECKING:
    from .linear_screen import Linearised


def effect_columns(effect: Effect, data: Dataset, bound: Bound, G: np.ndarray, em: ErrorModel,
                   x: np.ndarray, P: np.ndarray | None = None) -> np.ndarray:
    """A candidate's Jacobian columns at the fit ``x`` of ``em``, (n, 3, k). ``P``: the
    fit's predictions on ``data`` when the caller has them (a measure-stage effect, the
    last to act, takes its columns from them instead of a new pass along the chain)."""
    if effect.stage == "joint":
        partials = joint_partials(effect, data, bound)
        joint = cast(JointEffect, effect).joint
        return G[:, :, joint - 1, None] * partials[:, None, :]
    if effect.stage == "measure" and P is not None:
        measure: Any = effect  # a measure-stage effect: it has ``measure``
        return measure.measure(np.zeros(effect.n_params), P)[2]
    # other stages: evaluate the extended model once
    ext = ErrorModel(em.model, em.effects + [effect])
    xe = np.concatenate([x, np.zeros(effect.n_params)])
    _, J = ext.evaluate(xe, ext.bind(data))
    return J[:, :, em.n_params :]


def harmonic_columns(lin: Linearised, effects: list[Harmonic]
                     ) -> dict[int, tuple[np.ndarray, np.ndarray | None]]:
    """The columns of many harmonic candidates at once, ``{id(effect): (C, Cv)}``: per
    joint, the sines and cosines of every order in one call each (what
    :func:`effect_columns` gives one effect at a time: ``Harmonic.bind``'s ``K θ``)."""
    out: dict[int, tuple[np.ndarray, np.ndarray | None]] = {}
    by_joint: dict[int, list[Harmonic]] = {}
    for e in effects:
        by_joint.setdefault(e.joint, []).append(e)
    sets = [(lin.calib, lin.G)]
    if lin.valid is not None and lin.Gv is not None:
        sets.append((lin.valid, lin.Gv))
    for j, group in by_joint.items():
        orders = np.array([float(e.order) for e in group])
        cols = []
        for data, G in sets:
            k_theta = data.q[:, j - 1, None] * orders  # (n, K)
            basis = np.stack([np.sin(k_theta), np.cos(k_theta)], axis=-1)  # (n, K, 2)
            cols.append(G[:, :, j - 1, None, None] * basis[:, None])  # (n, 3, K, 2)
        for a, e in enumerate(group):
            out[id(e)] = (cols[0][:, :, a], cols[1][:, :, a] if len(cols) > 1 else None)
    return out


def joint_partials(effect: Effect, data: Dataset, bound: Bound) -> np.ndarray:
    """d(joint correction)/d(parameters) of a joint effect on ``data``, (n, k)."""
    state = effect.bind(data, bound.nominal)
    return cast(JointEffect, effect).delta(np.zeros(effect.n_params), data, state)[1]


def valid_columns(effect: Effect, lin: Linearised, em: ErrorModel, x: np.ndarray,
                  P: np.ndarray | None = None) -> np.ndarray | None:
    """:func:`effect_columns` on the validation poses of ``lin``, None without them."""
    if lin.valid is None or lin.bound_v is None or lin.Gv is None:
        return None
    return effect_columns(effect, lin.valid, lin.bound_v, lin.Gv, em, x, P)
