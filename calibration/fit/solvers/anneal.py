"""Simulated annealing on the full nonlinear model: Be-SA (improved) and classic SA.

Both minimise the objective of the published Be-SA method: the mean squared
difference between the position the error model predicts and the measured one,

    f(x) = 1/n sum_i |p_meas,i - p_model,i(x)|^2     (mm^2),

i.e. the mean squared 3-D residual of the full nonlinear model (not a linearised
one). Both run on the same budget of model evaluations, in the same coordinates
and with the same seeded random generator, and return the best state seen.

Coordinates
-----------
States are ``z = (x - x0) * d`` over the free parameters, ``x0`` the problem's start.
``space="equilibrated"`` (default) takes ``d`` = column norms of the Jacobian at the
start (one Jacobian evaluation), so a unit step in any coordinate moves the residual
vector by about 1 mm; ``space="scales"`` takes ``d = 1 / scale`` (each parameter in
units of its typical magnitude), as the published method works on raw parameters.
The robot's column norms differ by orders of magnitude in scale units, which makes
isotropic random steps very inefficient there; the default is the scaled space in
which random search is well posed.

Temperature
-----------
A dimensionless temperature T falls from ``t_max`` to ``t_min``. Be-SA cools in three
zones, ``t_max -> t_mid1 -> t_mid2 -> t_min``, multiplying T by ``rates[z]`` after each
level of ``L`` evaluations, with a decay (1 - rate) that falls zone by zone (fast
cooling while far from the optimum, slow cooling near it). Classic SA cools
geometrically over the same number of levels with one rate. ``L`` is chosen so
both spend ``max_evals`` evaluations.

Moves and acceptance
--------------------
Classic SA:  ``z' = z + T D0 rho u``, with ``u`` uniform in [-1, 1]^p, ``rho = sqrt(3/p)``
(so ``|rho u|`` is about 1) and ``D0 = sqrt(n f(x0))`` (the initial residual norm).
Accepted if ``f' < f`` or with the Metropolis probability ``exp(-(f' - f) / (T f0))``.

Be-SA: the move is guided by the historical best ``z*`` and by the ideal value
``f_ideal`` (the objective expected at the noise floor, ``3 sigma^2 (1 - m / 3n)``,
when the data's tracker sigma is known, else 0):

    z' = z + a r (z* - z) + T D* rho u,   D* = sqrt(n max(f* - f_ideal, 0.01 f*)),

``r`` uniform in [0, 1], ``a = 0.5``: the random part shrinks with the distance still
to go to the ideal value (the residual norm in excess of the noise), the
deterministic part pulls towards the best state. Downhill moves are accepted;
uphill ones with probability ``exp(-(f' - f) / (T f*))``, relative to the best
value (the published rule, read literally, "accept if it also beats the historical
best" can never accept an uphill move, since an uphill move from a state no better
than the best cannot beat the best; we use Metropolis and keep the best separately).
The search stops early when ``f* <= f_ideal``.

``solve_besa_lm`` (``--solver besa+lm``, or ``polish=True``) runs LM from Be-SA's best:
the annealer as a global start when the nominal model is far off.

Every evaluation of the model is one vectorised pass over all poses (about 0.5 ms
for 300 poses); the chain is sequential in the candidates, because
:meth:`ErrorModel.evaluate` takes one parameter vector per call.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from .common import Problem, SolverResult
from .lm import solve_lm


def _levels(t_max: float, bounds: list[float], rates: list[float]) -> list[float]:
    """Temperatures of every level, zone by zone."""
    temps = []
    t = t_max
    for end, rate in zip(bounds, rates, strict=True):
        while t > end * (1 + 1e-12):
            temps.append(t)
            t *= rate
        t = end
    return temps


def _anneal(problem: Problem, guided: bool, max_evals: int, seed: int, t_max: float,
            t_mid1: float, t_mid2: float, t_min: float, rates: tuple[float, float, float],
            ideal: float | None, space: str, pull: float,
            xf0: np.ndarray | None) -> SolverResult:
    rng = np.random.default_rng(seed)
    x0 = problem.xf0.copy() if xf0 is None else np.asarray(xf0, float).copy()
    p = x0.size
    n = problem.n_poses
    if p == 0:
        r = problem.residual(x0)
        return SolverResult(x0, True, "no free parameters", 0, [{"iter": 0, "f": r @ r / n}])
    if space == "equilibrated":
        _, J = problem.residual_and_jacobian(x0)
        d = np.linalg.norm(J, axis=0)
        d[d == 0] = 1.0
    elif space == "scales":
        d = 1.0 / np.asarray(problem.scales, float)
    else:
        raise ValueError(f"space must be 'equilibrated' or 'scales', not {space!r}")

    evals = 0

    def f(z: np.ndarray) -> float:
        nonlocal evals
        evals += 1
        r = problem.residual(x0 + z / d)
        v = float(r @ r) / n
        return v if math.isfinite(v) else math.inf

    if ideal is None:
        s = problem.bound.data.sigma()
        ideal = 3.0 * s**2 * max(1.0 - p / (3.0 * n), 0.0) if s else 0.0
    temps = (_levels(t_max, [t_mid1, t_mid2, t_min], list(rates)) if guided
             else list(t_max * (t_min / t_max) ** (np.arange(
                 len(_levels(t_max, [t_mid1, t_mid2, t_min], list(rates))))
                 / max(len(_levels(t_max, [t_mid1, t_mid2, t_min], list(rates))) - 1, 1))))
    per_level = max(1, (max_evals - 2) // len(temps))
    z = np.zeros(p)
    fz = f(z)
    f0 = fz
    z_best, f_best = z.copy(), fz
    d0 = math.sqrt(n * f0)
    rho = math.sqrt(3.0 / p)
    history = [{"iter": 0, "T": t_max, "f_best": f_best, "rms_mm": math.sqrt(f_best),
                "evals": evals}]
    reason, converged = "reached the minimum temperature", True
    accepted = 0
    done = False
    for level, T in enumerate(temps, 1):
        for _ in range(per_level):
            u = rng.uniform(-1.0, 1.0, p)
            if guided:
                gap = math.sqrt(n * max(f_best - ideal, 0.01 * f_best))
                z_new = z + pull * rng.uniform() * (z_best - z) + T * gap * rho * u
            else:
                z_new = z + T * d0 * rho * u
            f_new = f(z_new)
            delta = f_new - fz
            ref = f_best if guided else f0
            if delta < 0 or rng.uniform() < math.exp(-delta / max(T * ref, 1e-300)):
                z, fz = z_new, f_new
                accepted += 1
                if fz < f_best:
                    z_best, f_best = z.copy(), fz
            if guided and f_best <= ideal:
                reason, done = "reached the ideal value (noise floor)", True
                break
        history.append({"iter": level, "T": T, "f_best": f_best, "rms_mm": math.sqrt(f_best),
                        "evals": evals})
        if done:
            break
    if not np.isfinite(f_best):
        converged, reason = False, "no finite objective value found"
    info = {"evaluations": evals, "accepted": accepted, "levels": len(history) - 1,
            "f_best_mm2": f_best, "f_start_mm2": f0, "ideal_mm2": ideal, "seed": seed,
            "space": space}
    return SolverResult(x0 + z_best / d, converged, reason, len(history) - 1, history, info)


def solve_besa(
    problem: Problem,
    max_evals: int = 6000,
    seed: int = 0,
    t_max: float = 1.0,
    t_mid1: float = 0.3,
    t_mid2: float = 0.1,
    t_min: float = 0.01,
    rates: tuple[float, float, float] = (0.8, 0.9, 0.95),
    ideal: float | None = None,
    space: str = "equilibrated",
    pull: float = 0.5,
    polish: bool = False,
    xf0: np.ndarray | None = None,
) -> SolverResult:
    """Be-SA: simulated annealing guided by the historical best and the ideal value.

    Parameters
    ----------
    problem : the problem (free parameters; the start is the initial state)
    max_evals : budget of model evaluations (each one pass over all poses)
    seed : seed of the random generator (fixed by default: reproducible)
    t_max, t_mid1, t_mid2, t_min : zone boundaries of the dimensionless temperature
    rates : per-level cooling factor in each zone (increasing: slower cooling later)
    ideal : target of the objective, mm^2 (default from the data's tracker sigma, else 0)
    space : ``"equilibrated"`` or ``"scales"`` (see the module docstring)
    pull : weight of the pull towards the historical best
    polish : run LM from the best state found (a global start for LM)
    xf0 : initial state (default the problem's start)

    Returns
    -------
    SolverResult
        ``xf`` the best state; ``iterations`` temperature levels; ``info`` holds
        ``evaluations``, ``accepted``, ``f_best_mm2``, ``ideal_mm2``, ``seed``.
    """
    res = _anneal(problem, True, max_evals, seed, t_max, t_mid1, t_mid2, t_min, rates,
                  ideal, space, pull, xf0)
    return _polish(problem, res) if polish else res


def solve_sa(
    problem: Problem,
    max_evals: int = 6000,
    seed: int = 0,
    t_max: float = 1.0,
    t_min: float = 0.01,
    space: str = "equilibrated",
    polish: bool = False,
    xf0: np.ndarray | None = None,
    t_mid1: float = 0.3,
    t_mid2: float = 0.1,
    rates: tuple[float, float, float] = (0.8, 0.9, 0.95),
) -> SolverResult:
    """Classic simulated annealing: random moves scaled by T, Metropolis, geometric cooling.

    Same budget (``max_evals``), coordinates, number of temperature levels and seed
    handling as :func:`solve_besa` (``t_mid1``, ``t_mid2`` and ``rates`` only set the
    number of levels, so both use the same), without the guidance or the early stop.
    Returns the best state seen.
    """
    res = _anneal(problem, False, max_evals, seed, t_max, t_mid1, t_mid2, t_min, rates,
                  0.0, space, 0.0, xf0)
    return _polish(problem, res) if polish else res


def solve_besa_lm(problem: Problem, max_iter: int = 100, **options: Any) -> SolverResult:
    """Be-SA as a global start, then Levenberg-Marquardt from its best state."""
    return _polish(problem, solve_besa(problem, **options), max_iter)


def _polish(problem: Problem, res: SolverResult, max_iter: int = 100) -> SolverResult:
    lm = solve_lm(problem, max_iter=max_iter, xf0=res.xf)
    info = dict(res.info, anneal_reason=res.reason, anneal_levels=res.iterations,
                lm_iterations=lm.iterations)
    history = res.history + [dict(h, iter=res.iterations + h["iter"], stage="lm")
                             for h in lm.history[1:]]
    return SolverResult(lm.xf, lm.converged, f"annealing, then LM: {lm.reason}",
                        res.iterations + lm.iterations, history, info)
