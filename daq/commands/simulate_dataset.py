"""``cellcal simulate``: write a measurement CSV from a simulated robot with hidden errors."""

from __future__ import annotations

import json

import numpy as np

from calibration import DEFAULT_EFFECTS
from calibration.effects import display_unit
from calibration.files import write_atomic
from calibration.simulate import random_joints, realistic_truth, simulate

from ..cli import UsageError
from .common import (
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
    p = sub.add_parser(
        "simulate",
        help="write a measurement CSV of a simulated robot with hidden errors",
        description="Draw realistic hidden errors (geometric, base 2-3 m from the tracker, "
        "tool, plus any --hidden effects), measure random poses with a noisy tracker and "
        "write the measurement CSV. The truth goes to --truth for checking.",
    )
    p.add_argument("--model", required=True, metavar="NAME|PATH")
    p.add_argument("--effect-file", action="append", default=[], metavar="FILE.py")
    p.add_argument("--hidden", default="", metavar="EFFECTS",
                   help="extra hidden effects besides geometric,base,tool (e.g. compliance:2)")
    p.add_argument("--poses", type=bounded_int(1, MAX_POSES), default=300,
                   help="calibration poses (default 300)")
    p.add_argument("--valid", type=bounded_int(0, MAX_POSES), default=300,
                   help="validation poses (default 300)")
    p.add_argument("--sigma", type=positive_float, default=0.015,
                   help="tracker noise per axis, mm")
    p.add_argument("--seed", type=seed_int, default=1)
    p.add_argument("--out", required=True, metavar="FILE.csv")
    p.add_argument("--truth", metavar="FILE.json", help="write the hidden parameters here")
    p.set_defaults(func=run, data=None, json=False)


def run(args) -> int:
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
    data.meta = {"source": f"cellcal simulate --model {args.model} --seed {args.seed}"
                 + (f" --hidden {args.hidden}" if args.hidden else ""), **data.meta}
    data.to_csv(args.out)
    if args.truth:
        rows = []
        for k, name in enumerate(em.names):
            unit, f = display_unit(em.units[k])
            rows.append({"name": name, "value": float(x[k] * f), "unit": unit})
        write_atomic(args.truth, json.dumps({"effects": em.labels, "parameters": rows},
                                            indent=1))
    print(f"wrote {args.out}: {args.poses} calibration + {args.valid} validation poses of a "
          f"simulated {model.name} ({','.join(em.labels)} hidden), tracker sigma {args.sigma} mm")
    return 0
