"""``poses``: calibration and validation pose sets, random or chosen for observability.

Candidates are drawn uniformly within the joint limits (clipped to +-180 deg,
seeded) and kept when every link origin and the tool point are above the
floor and the tool point is within the reach limit. ``method="random"`` takes
the first ones; ``method="optimal"`` picks the calibration poses greedily from
a pool, each time the candidate that most increases log det(JᵀJ + εI) of the
scaled identification Jacobian of the error model (D-optimal design; J from
:class:`calibration.ErrorModel`, scaled by the parameters' typical sizes).
A fraction ``valid_fraction`` of the poses (random, not optimised) is marked
``set=valid``. The observability index O1 of the calibration poses
(:func:`calibration.identifiability.analyse`) is stored in the plan's params.
"""

from __future__ import annotations

import numpy as np

from calibration import Dataset, ErrorModel
from calibration.identifiability import analyse
from calibration.kinematics import run_chain

from ..plans import Plan, Target


def candidates(model, n: int, rng: np.random.Generator, *, floor_z_mm: float | None = 0.0,
               max_reach_mm: float | None = None, max_abs_deg: float = 180.0) -> np.ndarray:
    """``n`` random joint vectors (rad) within the limits, above the floor and within reach."""
    lim = model.sampling_limits_rad(max_abs_deg)
    out = []
    have = 0
    for _ in range(200):
        q = rng.uniform(lim[:, 0], lim[:, 1], size=(max(4 * n, 64), model.n_joints))
        r = run_chain(model.convention, model.dh_table(), q, model.tool_mm(), jacobian=False,
                      prismatic=model.prismatic_mask())
        ok = np.ones(len(q), bool)
        if floor_z_mm is not None:
            ok &= ((r.frames_p[:, 1:, 2] >= floor_z_mm).all(axis=1)
                   & (r.base_p_tcp[:, 2] >= floor_z_mm))
        if max_reach_mm is not None:
            ok &= np.linalg.norm(r.base_p_tcp, axis=1) <= max_reach_mm
        out.append(q[ok])
        have += int(ok.sum())
        if have >= n:
            break
    q = np.vstack(out)
    if len(q) < n:
        raise ValueError(f"poses: only {len(q)} of {n} random poses are above the floor and "
                         "within reach")
    return q[:n]


def scaled_jacobian(error_model: ErrorModel, q: np.ndarray) -> np.ndarray:
    """Identification Jacobian at the nominal (base = identity) per pose, scaled by the
    parameters' typical sizes: shape (n, 3, p), mm per typical error."""
    model = error_model.model
    pts = run_chain(model.convention, model.dh_table(), q, model.tool_mm(), jacobian=False,
                    prismatic=model.prismatic_mask()).base_p_tcp
    data = error_model.prepare(Dataset(q=q, tracker_p_smr=pts, source="<candidate poses>"))
    bound = error_model.bind(data)
    _, J = error_model.evaluate(error_model.initial(bound), bound)
    return J * np.asarray(error_model.scales, float)


def greedy_d_optimal(J: np.ndarray, k: int, eps: float = 1e-6, start: int = 0) -> np.ndarray:
    """Greedy D-optimal selection of ``k`` of the poses whose Jacobian blocks are ``J``
    (n, 3, p): each step adds the pose with the largest log det(I + Jc M⁻¹ Jcᵀ)
    (matrix determinant lemma), M = εI + Σ chosen JᵢᵀJᵢ. Returns the chosen indices in
    order of selection."""
    n, _, p = J.shape
    M = eps * np.eye(p)
    chosen = [start]
    M += J[start].T @ J[start]
    free = np.ones(n, bool)
    free[start] = False
    for _ in range(k - 1):
        Minv = np.linalg.inv(M)
        idx = np.flatnonzero(free)
        Jc = J[idx]
        G = np.einsum("cip,pq,cjq->cij", Jc, Minv, Jc, optimize=True)
        _, gain = np.linalg.slogdet(np.eye(3) + G)
        best = int(idx[np.argmax(gain)])
        chosen.append(best)
        free[best] = False
        M += J[best].T @ J[best]
    return np.array(chosen)


def observability(error_model: ErrorModel, q: np.ndarray) -> float:
    """O1 of the error model on poses q (rad), see :mod:`calibration.identifiability`."""
    J = scaled_jacobian(error_model, q) / np.asarray(error_model.scales, float)
    fam = [error_model.effect_of(k).family for k in range(error_model.n_params)]
    ident = analyse(J.reshape(-1, error_model.n_params), error_model.names, error_model.scales,
                    fam, n_poses=len(q))
    return float(ident.observability_index)


def make_plan(model, *, count: int = 100, seed: int = 0, method: str = "random",
              valid_fraction: float = 0.0, effects: str = "geometric,base,tool",
              pool: int | None = None, floor_z_mm: float | None = 0.0,
              max_reach_mm: float | None = None) -> Plan:
    """The poses plan: ``count`` poses, ``round(valid_fraction·count)`` of them ``valid``.

    ``method`` is ``random`` or ``optimal`` (greedy D-optimal from a pool of ``pool``
    candidates, default 5 × the calibration poses, at most 3000).
    """
    if count < 1:
        raise ValueError("poses: count must be >= 1")
    if not 0.0 <= valid_fraction < 1.0:
        raise ValueError("poses: valid_fraction must be in [0, 1)")
    if method not in ("random", "optimal"):
        raise ValueError(f"poses: method must be random or optimal, got {method!r}")
    rng = np.random.default_rng(seed)
    n_valid = int(round(valid_fraction * count))
    n_cal = count - n_valid
    kw = {"floor_z_mm": floor_z_mm, "max_reach_mm": max_reach_mm}
    em = ErrorModel(model, effects)
    if method == "optimal" and n_cal > 0:
        n_pool = pool or min(max(5 * n_cal, 50), 3000)
        cand = candidates(model, n_pool, rng, **kw)
        pick = greedy_d_optimal(scaled_jacobian(em, cand), min(n_cal, n_pool))
        q_cal = cand[pick]
    else:
        q_cal = candidates(model, n_cal, rng, **kw) if n_cal else np.zeros((0, model.n_joints))
    q_val = candidates(model, n_valid, rng, **kw) if n_valid else np.zeros((0, model.n_joints))
    o1 = observability(em, q_cal) if len(q_cal) >= 2 else float("nan")
    # interleave validation poses so a stopped run still has both kinds
    q_all = np.vstack([q_cal, q_val])
    sets = ["calib"] * len(q_cal) + ["valid"] * len(q_val)
    order = rng.permutation(len(q_all)) if n_valid else np.arange(len(q_all))
    targets = tuple(Target(i, "joints", q=q_all[j], set=sets[j], label=f"{sets[j][0]}{j + 1}")
                    for i, j in enumerate(order))
    params = {"count": count, "seed": seed, "method": method, "valid_fraction": valid_fraction,
              "effects": effects, "pool": pool, "floor_z_mm": floor_z_mm,
              "max_reach_mm": max_reach_mm,
              "observability_index": None if not np.isfinite(o1) else o1}
    return Plan("poses", params, targets, model=model.name)
