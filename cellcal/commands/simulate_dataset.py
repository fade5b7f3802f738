"""``cellcal simulate``: write a measurement CSV from a simulated robot with hidden errors
(:mod:`cellcal.usecases.simulate`)."""

from __future__ import annotations

from ..flags.choices import MAX_SIMULATED_POSES as MAX_POSES
from .common import bounded_float, bounded_int, positive_float, seed_int
from .parsers import command_parser


def register(sub) -> None:
    p = command_parser(
        sub, "simulate",
        help="write a measurement CSV of a simulated robot with hidden errors",
        description="Draw realistic hidden errors (geometric, base 2-3 m from the tracker, "
        "tool, plus any --hidden effects), measure random poses with a noisy tracker and "
        "write the measurement CSV. The truth goes to --truth for checking.",
    )
    p.add_argument("--model", required=True, metavar="NAME|PATH",
                   help="built-in model name (see `cellcal models`) or a model YAML file")
    p.add_argument("--effect-file", action="append", default=[], metavar="FILE.py",
                   help="load user-defined effects from a Python file (repeatable)")
    p.add_argument("--hidden", default="", metavar="EFFECTS",
                   help="extra hidden effects besides geometric,base,tool (e.g. compliance:2)")
    p.add_argument("--poses", type=bounded_int(1, MAX_POSES), default=300, metavar="N",
                   help="calibration poses (default 300)")
    p.add_argument("--valid", type=bounded_int(0, MAX_POSES), default=300, metavar="N",
                   help="validation poses (default 300)")
    p.add_argument("--sigma", type=positive_float, default=0.015, metavar="MM",
                   help="tracker noise per axis, mm (default 0.015)")
    p.add_argument("--blunders", type=bounded_float(0.0, 1.0), default=0.0, metavar="RATE",
                   help="probability that a calibration reading is a blunder: displaced by "
                   "0.5-5 mm along the line of sight or in a random direction (default 0; "
                   "validation rows stay clean; which ones goes to --truth)")
    p.add_argument("--seed", type=seed_int, default=1, help="random seed (default 1)")
    p.add_argument("--out", required=True, metavar="FILE.csv", help="the CSV to write")
    p.add_argument("--truth", metavar="FILE.json", help="write the hidden parameters here")
    p.set_defaults(func=run)


def run(args) -> int:
    from presentation.simulation_text import simulation_line

    from ..usecases.simulate import SimulateRequest, simulate_dataset

    request = SimulateRequest.from_args(args)
    sim = simulate_dataset(request)
    print(simulation_line(request.out, sim.data, sim.error_model, request.sigma, sim.blunders))
    return 0
