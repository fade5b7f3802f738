"""Solvers for :func:`calibration.identify.identify`.

A solver is a function ``solve(problem, **options) -> SolverResult`` registered in
:data:`SOLVERS` under the name ``--solver`` uses. ``lm`` (Levenberg-Marquardt) is the
default.
"""

from __future__ import annotations

from .common import Problem, SolverResult
from .lm import solve_lm

SOLVERS = {"lm": solve_lm}

__all__ = ["SOLVERS", "Problem", "SolverResult", "solve_lm"]
