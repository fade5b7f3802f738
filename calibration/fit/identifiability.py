"""Which parameters a data set can determine: QR with column pivoting of the scaled Jacobian.

Columns are normalised to unit length (so units do not matter) and ranked by
pivoted QR in tiers: first the frame parameters (base, tool),
then the geometric ones, then every other effect, each tier after projecting
out the columns already kept. A parameter whose pivot falls below ``rtol`` (default
1e-3: its independent effect is under 0.1 % of a unit column, which keeps the
condition number of the free set below about 1e3) is unidentifiable (no effect
on the measured points) or redundant (its effect is a combination of the
others') and is fixed at its starting value. The tiers make
the choice between exactly redundant parameters stable and readable: with
position-only data joint 1's offset and d are fixed, not the base; within a
tier, exact ties go to the parameter declared first.

Penalised parameters (a correction table's knots, tied together by a smoothness penalty)
are determined by data and penalty together: only the directions the penalty leaves free
(its null space: a table's constant and linear parts) are ranked, as pseudo-columns in the
last tier; for each of those that is redundant one parameter is held at its start (a
table's constant is the joint's zero offset), and the others are free and listed in
``penalised``.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np

from ..numerics.linalg import qr_pivoted

if TYPE_CHECKING:
    from .error_model import ErrorModel

#: tiers for breaking exact redundancies: a parameter is only fixed in favour of
#: parameters of the same or an earlier tier
_TIERS = ({"base", "tool", "tool_rotation"}, {"geometric"})


def _tier(family: str) -> int:
    for i, t in enumerate(_TIERS):
        if family in t:
            return i
    return len(_TIERS)


@dataclass
class Identifiability:
    """Result of the identifiability analysis.

    Attributes
    ----------
    free : (p,) bool, True for the identifiable parameters
    names : all parameter names
    fixed : names of the fixed ones, each with a reason
    condition_number : of the column-normalised Jacobian of the free parameters
        (penalised ones left out: the penalty, not the data alone, determines them)
    observability_index : O1 = (s1 ... sm)^(1/m) / sqrt(n_poses) of the Jacobian scaled by
        the parameters' typical magnitudes (mm per typical error; larger is better), over
        the same parameters
    penalised : names of the free parameters that a penalty helps determine
    """

    free: np.ndarray
    names: list[str]
    fixed: dict[str, str] = field(default_factory=dict)
    condition_number: float = float("nan")
    observability_index: float = float("nan")
    penalised: list[str] = field(default_factory=list)

    @property
    def unidentifiable(self) -> list[str]:
        return list(self.fixed)

    @property
    def n_identifiable(self) -> int:
        return int(self.free.sum())


def analyse(
    J: np.ndarray,
    names: list[str],
    scales: np.ndarray,
    families: list[str] | None = None,
    rtol: float = 1e-3,
    always_free: np.ndarray | None = None,
    n_poses: int | None = None,
    penalised: list[tuple[np.ndarray, np.ndarray]] | None = None,
    normal: np.ndarray | None = None,
) -> Identifiability:
    """Rank the columns of a Jacobian ``J`` (m, p) and decide which parameters are free.

    ``always_free`` (bool mask) keeps parameters free whatever their pivot (rarely needed);
    ``families`` (per parameter) sets the tie-breaking preference; ``penalised`` lists
    groups (parameter indices (k,), null space of their penalty (k, d)) determined with
    the help of a penalty (see the module docstring and :func:`penalised_groups`).
    ``normal``: ``JᵀJ`` (p, p) when the caller has it (the solver's normal matrix at the
    same point): the column geometry then comes from its eigen-decomposition, a p x p
    factor ``F`` with ``FᵀF = JᵀJ``, instead of a QR of the m x p ``J`` (the same
    geometry: a pivot is exact to ~1e-8 of a unit column, far below ``rtol``). With
    penalised groups only while the free columns are well conditioned (condition number
    below :data:`GUARD_COND`, so that a redundancy's coefficients over them are exact to
    ~1e-8 too); else the analysis is made again from the QR (a table's columns need not
    be of full rank: their coefficients would depend on the factor's rounding).
    """
    if penalised and normal is not None and J.shape[0] > J.shape[1]:
        out = _analyse(J, names, scales, families, rtol, always_free, n_poses, penalised,
                       normal, guard=True)
        if out is not None:
            return out
        normal = None
    out = _analyse(J, names, scales, families, rtol, always_free, n_poses, penalised,
                   normal)
    assert out is not None  # unguarded: always an analysis
    return out


#: with penalised groups, the normal matrix's factor serves only when the free columns'
#: condition number is below this (else the QR of the Jacobian)
GUARD_COND = 1e4


def _analyse(J: np.ndarray, names: list[str], scales: np.ndarray, families: list[str] | None,
             rtol: float, always_free: np.ndarray | None, n_poses: int | None,
             penalised: list[tuple[np.ndarray, np.ndarray]] | None,
             normal: np.ndarray | None, guard: bool = False) -> Identifiability | None:
    """:func:`analyse`; with ``guard`` None when the free columns are too ill-conditioned
    for the normal matrix's factor."""
    m, p = J.shape
    norms = np.linalg.norm(J, axis=0) if normal is None else \
        np.sqrt(np.clip(np.diag(normal), 0.0, None))
    fixed: dict[str, str] = {}
    live = norms > 1e-12 * max(float(norms.max()), 1e-300)
    for k in np.flatnonzero(~live):
        fixed[names[k]] = "no effect on the measured points"
    in_group = np.zeros(p, bool)
    for idx, _ in penalised or []:
        in_group[idx] = True
    tiers = np.array([_tier(f) for f in (families or [""] * p)])
    # all that follows depends only on the column geometry, which the p x p triangular
    # factor of the normalised Jacobian keeps: work on it instead of the 3n x p matrix
    if normal is not None and m > p:
        Jn = _normal_factor(normal, norms, live)
    else:
        scaled = np.zeros_like(J, dtype=float)
        scaled[:, live] = J[:, live] / norms[live]
        Jn = np.asarray(np.linalg.qr(scaled, mode="r")) if m > p else scaled
    free = np.zeros(p, bool)
    basis = np.zeros((Jn.shape[0], 0))
    for tier in sorted(set(tiers[live & ~in_group])):
        idx = np.flatnonzero(live & ~in_group & (tiers == tier))
        # exact ties go to the parameter declared first (joint order; theta, d, a, alpha)
        order_weight = 1.0 - 0.01 * np.arange(idx.size) / max(idx.size, 1)
        cols = (Jn[:, idx] - basis @ (basis.T @ Jn[:, idx])) * order_weight
        R, piv = qr_pivoted(cols)
        diag = np.abs(np.diag(R))
        keep = idx[piv[: diag.size][diag > rtol]]
        free[keep] = True
        basis, _ = np.linalg.qr(Jn[:, free])
    held = {}
    for idx, null in penalised or []:
        idx = np.asarray(idx)
        held.update(_penalised_group(Jn, norms, idx[live[idx]], null[live[idx]], basis,
                                     rtol))
        free[idx[live[idx]]] = True
        free[list(held)] = False
        basis, _ = np.linalg.qr(Jn[:, free & ~in_group])
    if always_free is not None:
        free |= always_free & live
    dropped = [k for k in np.flatnonzero(live & ~in_group) if not free[k]]
    gram = None
    if guard and free.any():
        gram = Jn[:, free].T @ Jn[:, free]
        w = np.linalg.eigvalsh(gram)
        if not w[0] > w[-1] / GUARD_COND**2:
            return None
    if dropped:
        # explain each dropped column as a combination of the kept ones (guarded: the
        # normal equations of the well-conditioned free columns, the same to ~1e-8)
        if gram is not None:
            coef = np.linalg.solve(gram, Jn[:, free].T @ Jn[:, dropped])
        else:
            coef, *_ = np.linalg.lstsq(Jn[:, free], Jn[:, dropped], rcond=None)
        free_names = [names[k] for k in np.flatnonzero(free)]
        for c, k in enumerate(dropped):
            order = np.argsort(-np.abs(coef[:, c]))[:3]
            parts = [
                f"{free_names[i]} ({coef[i, c]:+.2f})" for i in order if abs(coef[i, c]) > 0.05
            ]
            fixed[names[k]] = "redundant with " + (", ".join(parts) if parts else "the others")
    for key, why in held.items():
        fixed[names[key]] = why
    cond = obs = float("nan")
    plain = free & ~in_group
    if plain.any():
        s = np.linalg.svd(Jn[:, plain], compute_uv=False)
        cond = float(s[0] / s[-1]) if s[-1] > 0 else float("inf")
        phys = (norms * np.asarray(scales, float))[plain]
        ss = np.linalg.svd(Jn[:, plain] * phys, compute_uv=False)
        npose = n_poses if n_poses else max(m // 3, 1)
        obs = float(np.exp(np.mean(np.log(np.maximum(ss, 1e-300)))) / np.sqrt(npose))
    position = {n: i for i, n in enumerate(names)}
    fixed = dict(sorted(fixed.items(), key=lambda kv: position[kv[0]]))
    pen_names = [names[k] for k in np.flatnonzero(free & in_group)]
    return Identifiability(free, list(names), fixed, cond, obs, pen_names)


def _normal_factor(normal: np.ndarray, norms: np.ndarray, live: np.ndarray) -> np.ndarray:
    """F (p, p) with ``FᵀF`` the normal matrix of the unit-normalised live columns (the
    others zero): ``sqrt(w) Vᵀ`` from its eigen-decomposition (semi-definite: eigenvalues
    below zero, rounding, are clipped)."""
    s = np.where(live, 1.0 / np.where(live, norms, 1.0), 0.0)
    G = normal * np.outer(s, s)
    G = 0.5 * (G + G.T)
    if G.shape[0] > CHOLESKY_FACTOR_ABOVE:
        # a large model (tables): the Cholesky factor of G + δ I, a twentieth of the
        # eigen-decomposition's time; δ (1e-14 of a unit column's square) moves a pivot
        # by 1e-7 of a unit column at most, four decades below rtol
        try:
            return np.linalg.cholesky(G + _FACTOR_NUDGE * np.eye(G.shape[0])).T
        except np.linalg.LinAlgError:
            pass
    w, V = np.linalg.eigh(G)
    return np.sqrt(np.clip(w, 0.0, None))[:, None] * V.T


#: the normal matrix's factor is its nudged Cholesky factor above this many parameters
#: (:func:`_normal_factor`), its eigen-decomposition's below (models without tables)
CHOLESKY_FACTOR_ABOVE = 96
_FACTOR_NUDGE = 1e-14


def _penalised_group(Jn: np.ndarray, norms: np.ndarray, idx: np.ndarray, null: np.ndarray,
                     basis: np.ndarray, rtol: float) -> dict[int, str]:
    """Parameters of one penalised group to hold at their start: one per direction of the
    penalty's null space that the data (beyond the parameters kept so far) cannot
    determine. The first is the parameter with the strongest column (a table's best
    covered knot), the next the one furthest from it."""
    if idx.size == 0:
        return {}
    cols = Jn[:, idx] @ (norms[idx, None] * null)
    cn = np.linalg.norm(cols, axis=0)
    cols = cols / np.where(cn > 0, cn, 1.0)
    cols = cols - basis @ (basis.T @ cols)
    diag = np.abs(np.diag(qr_pivoted(cols)[0]))
    n_redundant = null.shape[1] - int(np.count_nonzero(diag > rtol))
    if n_redundant <= 0:
        return {}
    first = int(np.argmax(norms[idx]))
    picks = [first, int(np.argmax(np.abs(np.arange(idx.size) - first)))][:n_redundant]
    part = "constant part is" if n_redundant == 1 else "constant and linear parts are"
    why = (f"the penalised group's {part} redundant with the other parameters (a constant "
           "joint correction is the joint's zero offset): held at its start")
    return {int(idx[k]): why for k in picks}


def penalised_groups(error_model: ErrorModel) -> list[tuple[np.ndarray, np.ndarray]]:
    """The penalised groups of an error model for :func:`analyse`: every effect with a
    ``null_space()`` (the directions its penalty leaves free)."""
    groups = []
    effects: list[Any] = error_model.effects  # the penalised ones have ``null_space``
    for e, sl in zip(effects, error_model.slices, strict=True):
        if hasattr(e, "null_space"):
            groups.append((np.arange(sl.start, sl.stop), np.asarray(e.null_space(), float)))
    return groups
