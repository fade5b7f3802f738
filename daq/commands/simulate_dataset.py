"""``cellcal simulate``: write a measurement CSV from a simulated robot with hidden errors."""

from __future__ import annotations

import json

from ..cli import UsageError, command_parser
from .choices import DEFAULT_EFFECTS
from .common import load_inputs, wrap_errors


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
    p.add_argument("--poses", type=int, default=300, help="calibration poses (default 300)")
    p.add_argument("--valid", type=int, default=300, help="validation poses (default 300)")
    p.add_argument("--sigma", type=float, default=0.015, metavar="MM",
                   help="tracker noise per axis, mm (default 0.015)")
    p.add_argument("--seed", type=int, default=1, help="random seed (default 1)")
    p.add_argument("--out", required=True, metavar="FILE.csv", help="the CSV to write")
    p.add_argument("--truth", metavar="FILE.json", help="write the hidden parameters here")
    p.set_defaults(func=run, data=None, json=False)


def run(args) -> int:
    import numpy as np

    from calibration import ErrorModel
    from calibration.effects import display_unit
    from calibration.simulate import random_joints, realistic_truth, simulate

    model, _ = load_inputs(args)
    if args.poses < 1 or args.valid < 0:
        raise UsageError("--poses must be >= 1 and --valid >= 0")
    if not args.sigma > 0:
        raise UsageError("--sigma must be positive")
    spec = DEFAULT_EFFECTS + ("," + args.hidden if args.hidden else "")
    em = wrap_errors(lambda: ErrorModel(model, spec))
    rng = np.random.default_rng(args.seed)
    x = realistic_truth(em, rng)
    n = args.poses + args.valid
    q = random_joints(model, n, rng)
    data = simulate(em, x, q, args.sigma, rng, is_valid=np.arange(n) >= args.poses)
    data.meta = {"source": f"cellcal simulate --model {args.model} --seed {args.seed}"
                 + (f" --hidden {args.hidden}" if args.hidden else ""), **data.meta}
    data.to_csv(args.out)
    if args.truth:
        rows = []
        for k, name in enumerate(em.names):
            unit, f = display_unit(em.units[k])
            rows.append({"name": name, "value": float(x[k] * f), "unit": unit})
        with open(args.truth, "w") as fh:
            json.dump({"effects": em.labels, "parameters": rows}, fh, indent=1)
    print(f"wrote {args.out}: {args.poses} calibration + {args.valid} validation poses of a "
          f"simulated {model.name} ({','.join(em.labels)} hidden), tracker sigma {args.sigma} mm")
    return 0
