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
(:func:`calibration.fit.identifiability.analyse`) is stored in the plan's params.

Line of sight (``cell`` with a tracker position): every candidate is built facing the
tracker (:func:`calibration.cell.visibility.sample_visible`: the SMR axis within the acceptance
cone less the margin, the beam clear of every link and fixture by the clearance), so
random and D-optimal poses alike come from visible ones only; fewer than needed is
:class:`~daq.errors.NotEnoughVisible` (exit 3) saying what to change. ``spares`` more
visible poses (default 5 %, at least 2) follow the plan's poses, marked
``info.spare``: the executor measures one only in place of a pose whose beam stayed
broken.

Order: the poses are visited in a short order (:func:`daq.plans.shortest_order`, on the
move time), opened so that calibration and validation poses both come early and stay
interleaved; the joint travel of this order and that of a random order are in the params.
"""

from __future__ import annotations

import numpy as np

from calibration import Dataset, ErrorModel
from calibration.cell.visibility import sample_visible, workspace_ok
from calibration.fit.identifiability import analyse
from calibration.model.kinematics import run_chain

from ..errors import NotEnoughVisible
from ..plans import Plan, Target, path_time, shortest_order
from ._common import knows_tracker, visibility_params, what_hides


def candidates(model, n: int, rng: np.random.Generator, *, floor_z_mm: float | None = 0.0,
               max_reach_mm: float | None = None, max_abs_deg: float = 180.0,
               cell=None) -> np.ndarray:
    """``n`` random joint vectors (rad) within the limits, above the floor and within reach;
    with ``cell`` (a tracker position) only poses the tracker sees
    (:class:`~daq.errors.NotEnoughVisible` when too few are found)."""
    kw = {"floor_z_mm": floor_z_mm, "max_reach_mm": max_reach_mm}
    if knows_tracker(cell):
        q = sample_visible(model, cell, n, rng, max_abs_deg=max_abs_deg, **kw)
        if len(q) < n:
            cause = what_hides(model, cell, **kw) if len(q) == 0 else ""
            raise NotEnoughVisible(
                f"poses: only {len(q)} of {n} poses found that the tracker at "
                f"{np.round(cell.tracker_mm).tolist()} mm ({cell.tracker_source}) sees with "
                f"the margins (facing within {cell.smr.half_angle_deg:g} - "
                f"{cell.margins.facing_deg:g} deg, beam {cell.margins.clearance_mm:g} mm clear "
                f"of links and fixtures); {f'the cause: {cause}; ' if cause else ''}"
                "change: fewer poses (--count), a lower --floor-z-mm "
                "or no --max-reach-mm, smaller margins or fixtures in the cell file, or move "
                "the tracker nearer the robot's working space")
        return q
    lim = model.sampling_limits_rad(max_abs_deg)
    out = []
    have = 0
    for _ in range(200):
        q = rng.uniform(lim[:, 0], lim[:, 1], size=(max(4 * n, 64), model.n_joints))
        q = q[workspace_ok(model, q, **kw)]
        out.append(q)
        have += len(q)
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
    """O1 of the error model on poses q (rad), see :mod:`calibration.fit.identifiability`."""
    J = scaled_jacobian(error_model, q) / np.asarray(error_model.scales, float)
    fam = [error_model.effect_of(k).family for k in range(error_model.n_params)]
    ident = analyse(J.reshape(-1, error_model.n_params), error_model.names, error_model.scales,
                    fam, n_poses=len(q))
    return float(ident.observability_index)


def make_plan(model, *, count: int = 100, seed: int = 0, method: str = "random",
              valid_fraction: float = 0.0, effects: str = "geometric,base,tool",
              pool: int | None = None, floor_z_mm: float | None = 0.0,
              max_reach_mm: float | None = None, cell=None, spares: int | None = None
              ) -> Plan:
    """The poses plan: ``count`` poses, ``round(valid_fraction·count)`` of them ``valid``.

    ``method`` is ``random`` or ``optimal`` (greedy D-optimal from a pool of ``pool``
    candidates, default 5 × the calibration poses, at most 3000). ``cell``: plan for the
    tracker's line of sight (see the module docstring), with ``spares`` spare poses
    (default 5 % of ``count``, at least 2; none without a cell).
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
    sight = knows_tracker(cell)
    n_spare = (0 if not sight else max(2, int(np.ceil(0.05 * count)))) if spares is None \
        else int(spares)
    kw = {"floor_z_mm": floor_z_mm, "max_reach_mm": max_reach_mm, "cell": cell}
    em = ErrorModel(model, effects)
    if method == "optimal" and n_cal > 0:
        n_pool = pool or min(max(5 * n_cal, 50), 3000)
        cand = candidates(model, max(n_pool, n_cal), rng, **kw)
        pick = greedy_d_optimal(scaled_jacobian(em, cand), min(n_cal, len(cand)))
        q_cal = cand[pick]
    else:
        q_cal = candidates(model, n_cal, rng, **kw) if n_cal else np.zeros((0, model.n_joints))
    q_val = candidates(model, n_valid, rng, **kw) if n_valid else np.zeros((0, model.n_joints))
    q_spare = candidates(model, n_spare, rng, **kw) if n_spare else np.zeros((0, model.n_joints))
    o1 = observability(em, q_cal) if len(q_cal) >= 2 else float("nan")
    q_all = np.vstack([q_cal, q_val])
    sets = np.array(["calib"] * len(q_cal) + ["valid"] * len(q_val))
    # a short order; calibration and validation poses both early and interleaved
    order = shortest_order(q_all, 1.0, sets if n_valid and n_cal else None)
    labels = [f"{sets[j][0]}{j + 1}" for j in order]
    targets = [Target(i, "joints", q=q_all[j], set=str(sets[j]), label=labels[i])
               for i, j in enumerate(order)]
    for k, j in enumerate(shortest_order(q_spare, 1.0) if len(q_spare) else []):
        targets.append(Target(len(targets), "joints", q=q_spare[j], label=f"s{k + 1}",
                              info={"spare": True}))
    rnd = np.mean([path_time(q_all[rng.permutation(len(q_all))], 1.0) for _ in range(5)])
    params = {"count": count, "seed": seed, "method": method, "valid_fraction": valid_fraction,
              "effects": effects, "pool": pool, "floor_z_mm": floor_z_mm,
              "max_reach_mm": max_reach_mm,
              "observability_index": None if not np.isfinite(o1) else o1,
              "joint_travel_rad": path_time(q_all[order], 1.0),
              "joint_travel_random_order_rad": float(rnd)}
    if sight:
        params.update(spares=n_spare, visibility=visibility_params(cell))
    return Plan("poses", params, tuple(targets), model=model.name)
