"""Constants the ``cellcal`` parser shows (defaults, choices), without importing the
calibration core: building the parser must stay fast (see :mod:`cellcal.cli`).

Each is a copy of the core's own value; ``tests/cellcal/test_cli_help.py`` checks that they
agree, so a change in the core that is not made here fails the tests.
"""

from __future__ import annotations

#: :data:`calibration.effects.DEFAULT_EFFECTS`
DEFAULT_EFFECTS = "geometric,base,tool"

#: the keys of :data:`calibration.fit.solvers.SOLVERS`, with what each is
SOLVERS = {
    "lm": "Levenberg-Marquardt",
    "ridge": "robust ridge estimation: IGG3 pose weights, Tikhonov ridge",
    "besa": "improved simulated annealing (seeded)",
    "sa": "classic simulated annealing (seeded)",
    "besa+lm": "annealing as a global start, polished by Levenberg-Marquardt",
}

#: :data:`calibration.fit.outliers.MODES`: what ``--outliers`` does with blunders
OUTLIER_MODES = ("exclude", "flag", "keep")


def solver_help(what: str = "identification method") -> str:
    """The ``--solver`` help text: the choices and what each is."""
    return f"{what} (default lm): " + "; ".join(f"{k}: {v}" for k, v in SOLVERS.items())

#: the most poses one ``cellcal simulate`` CSV holds (calibration plus validation)
MAX_SIMULATED_POSES = 1_000_000

#: the ``--db`` help of every command that reads or writes a run store
DB_HELP = ("run store: a SQLite file or a PostgreSQL URL postgresql://user@host[:port]/db "
           "(password from PGPASSWORD or ~/.pgpass)")

#: :data:`sim_drivers.thermal.STARTS`: the thermal starts of a simulated robot
THERMAL_STARTS = ("cold", "warm")

#: ``compensate --joints-tolerance-mm``: how far (mm) the nominal point of a target's joints
#: may lie from its x, y, z (:mod:`cellcal.usecases.target_checks`): far above joints
#: written to 0.01 deg (a 1.3 m arm: ~0.2 mm per joint) and a calibration's corrections (a
#: few mm), far below joints of another target or configuration (hundreds of mm)
JOINTS_TOLERANCE_MM = 10.0

#: the keys of :data:`cellcal.usecases.demo.DEMO_ROBOTS`: the demo robot's controllers
DEMO_ROBOTS = ("modbus", "abb")
