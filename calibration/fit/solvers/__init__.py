"""Solvers for :func:`calibration.fit.identify.identify`.

A solver is a function ``solve(problem, **options) -> SolverResult`` registered in
:data:`SOLVERS` under the name ``--solver`` uses. ``lm`` (Levenberg-Marquardt) is the
default; ``ridge`` is robust ridge estimation (IGG3 pose weights + Tikhonov, see
:mod:`.ridge`); ``besa`` and ``sa`` are the improved and the classic simulated
annealing (see :mod:`.anneal`); ``besa+lm`` is Be-SA as a global start polished by LM.

Modules
-------
common  Problem (what a solver receives) and SolverResult (what it returns)
lm      Levenberg-Marquardt with diagonal scaling and Nielsen's damping update
ridge   robust ridge estimation: IGG3 pose weights, ridge parameter by GCV or L-curve
anneal  simulated annealing: Be-SA (improved), classic SA, Be-SA polished by LM
"""

from __future__ import annotations

from collections.abc import Callable

from .anneal import solve_besa, solve_besa_lm, solve_sa
from .common import Problem, SolverResult
from .lm import solve_lm
from .ridge import igg3_weights, solve_ridge

#: each solver: ``solve(problem, **options) -> SolverResult``
SOLVERS: dict[str, Callable[..., SolverResult]] = {
    "lm": solve_lm,
    "ridge": solve_ridge,
    "besa": solve_besa,
    "sa": solve_sa,
    "besa+lm": solve_besa_lm,
}

__all__ = [
    "SOLVERS",
    "Problem",
    "SolverResult",
    "igg3_weights",
    "solve_besa",
    "solve_besa_lm",
    "solve_lm",
    "solve_ridge",
    "solve_sa",
]
