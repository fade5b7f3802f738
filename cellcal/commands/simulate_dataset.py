"""``cellcal simulate``: write a measurement CSV from a simulated robot with hidden errors."""

from __future__ import annotations

import json

from ..cli import UsageError, command_parser
from .choices import DEFAULT_EFFECTS
from .common import (
    bounded_float,
    bounded_int,
    check_outputs,
    error_model_of,
    input_paths,
    load_inputs,
    positive_float,
    seed_int,
)

#: the most poses one simulated CSV holds
MAX_POSES = 1_000_000


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
    p.set_defaults(func=run, data=None, json=False)


def run(args) -> int:
    import numpy as np

    from calibration.effects import display_unit
    from calibration.files import write_atomic
    from calibration.simulate import add_blunders, random_joints, realistic_truth, simulate

    check_outputs({"--out": args.out, "--truth": args.truth},
                  input_paths(args, "model", "effect_file"))
    model, _ = load_inputs(args)
    if args.poses + args.valid > MAX_POSES:
        raise UsageError(f"--poses plus --valid must be at most {MAX_POSES}")
    spec = DEFAULT_EFFECTS + ("," + args.hidden if args.hidden else "")
    em = error_model_of(model, spec, "--hidden")
    rng = np.random.default_rng(args.seed)
    x = realistic_truth(em, rng)
    n = args.poses + args.valid
    q = random_joints(model, n, rng)
    data = simulate(em, x, q, args.sigma, rng, is_valid=np.arange(n) >= args.poses)
    blunders = None
    if args.blunders > 0:
        data, blunders = add_blunders(data, args.blunders, np.random.default_rng([args.seed, 1]),
                                      rows=~data.is_valid)
    data.meta = {"source": f"cellcal simulate --model {args.model} --seed {args.seed}"
                 + (f" --hidden {args.hidden}" if args.hidden else "")
                 + (f" --blunders {args.blunders:g}" if args.blunders else ""), **data.meta}
    data.to_csv(args.out)
    if args.truth:
        rows = []
        for k, name in enumerate(em.names):
            unit, f = display_unit(em.units[k])
            rows.append({"name": name, "value": float(x[k] * f), "unit": unit})
        truth = {"effects": em.labels, "parameters": rows}
        if blunders is not None:
            truth["blunders"] = blunders.to_json()
        write_atomic(args.truth, json.dumps(truth, indent=1))
    print(f"wrote {args.out}: {args.poses} calibration + {args.valid} validation poses of a "
          f"simulated {model.name} ({','.join(em.labels)} hidden), tracker sigma {args.sigma} mm"
          + (f"; {len(blunders.index)} blunders" if blunders is not None else ""))
    return 0
