"""``cellcal demo``: the whole cell on the simulator, from capture to a more accurate robot."""

from __future__ import annotations

from ..flags.choices import DEMO_ROBOTS
from .common import bounded_int, seed_int
from .parsers import command_parser


def register(sub) -> None:
    p = command_parser(
        sub, "demo",
        help="run the whole workflow on the simulated cell (no robot needed)",
        description="Start a simulated UR10e with hidden errors and one hidden physical effect "
        "behind real wire protocols, capture through the real drivers, calibrate, diagnose, "
        "add the missing effect, calibrate again and write an HTML report.\n\n"
        "Writes into --out: cell.db (the run store), capture.csv, params.json, report.html "
        "and demo.json (what was hidden and found, the validation RMS of each stage, the "
        "files). Exit 0 when the diagnosis found the hidden effect, 1 otherwise "
        "(docs/formats.md §6).",
    )
    p.add_argument("--seed", type=seed_int, default=1,
                   help="chooses the cell and its hidden effect (default 1)")
    p.add_argument("--hidden", default=None, metavar="EFFECT",
                   help="the hidden physical effect (default: chosen by the seed)")
    p.add_argument("--out", default="cellcal-demo", metavar="DIR",
                   help="where the run store, CSV, params.json, report.html and demo.json go "
                   "(default cellcal-demo)")
    p.add_argument("--poses", type=bounded_int(50, 100_000), default=300, metavar="N",
                   help="calibration poses (default 300, at least 50)")
    p.add_argument("--valid", type=bounded_int(20, 100_000), default=150, metavar="N",
                   help="validation poses (default 150, at least 20)")
    p.add_argument("--cold-start", action="store_true",
                   help="the robot starts cold and warms up while it is captured (drift "
                   "checks every 25 points); no physical effect hidden unless --hidden; exit "
                   "0 when the diagnosis adds a drift effect")
    p.add_argument("--robot", choices=DEMO_ROBOTS, default="modbus",
                   help="the simulated robot: modbus (a UR10e behind a PLC-style controller "
                   "over Modbus TCP, the default) or abb (an IRB 2600-12/1.65 behind an ABB "
                   "IRC5 over Robot Web Services, moved through the RAPID server module; "
                   "docs/abb.md)")
    p.add_argument("--quiet", action="store_true", help="no progress lines")
    p.add_argument("--force", action="store_true",
                   help="write into a folder that holds other files (the demo's own file "
                   "names are replaced; a run store the demo did not create never is)")
    p.set_defaults(func=run)


def run(args) -> int:
    from ..progress import Progress
    from ..usecases.demo import DemoRequest, demo

    result = demo(DemoRequest.from_args(args), say=lambda text: print(text, flush=True),
                  progress=None if args.quiet else Progress)
    return 0 if result.found == result.hidden else 1
