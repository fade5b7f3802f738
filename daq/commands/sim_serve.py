"""``cellcal sim serve``: run the simulated cell behind its wire protocols until stopped.

Prints one driver URL per line (Modbus robot, line robot, tracker over TCP,
tracker over a pty, emScon tracker ``emscon://127.0.0.1:PORT``, then the
read-only RTDE robot when port 30004 was free), then serves until Ctrl-C or
SIGTERM and stops cleanly (exit code 0).
"""

from __future__ import annotations

import signal
import sys
import threading

from daq.cli import UsageError

from .common import nonneg_float, seed_int


def register(sub) -> None:
    p = sub.add_parser("sim", help="simulated cell: serve it over the real wire protocols")
    ssub = p.add_subparsers(dest="sim_command", metavar="SIM_COMMAND")
    ssub.required = True
    s = ssub.add_parser("serve", help="start the simulated servers and print their URLs")
    s.add_argument("--seed", type=seed_int, default=0,
                   help="random seed of the cell (default 0)")
    s.add_argument("--model", default="ur10e",
                   help="the true robot: a model name or YAML with realistic hidden errors "
                        "(default ur10e), or 'toy' for a 3-joint stand-in arm")
    s.add_argument("--hidden", default=None,
                   help="hidden physical effects of the true robot, e.g. compliance:3")
    s.add_argument("--faults", default=None,
                   help="fault spec, e.g. 'beam=0.05,slow=0.02,drop@3,delay=2'")
    s.add_argument("--time-scale", type=nonneg_float, default=0.0,
                   help="wall seconds per simulated second (0: instantaneous)")
    s.add_argument("--host", default="127.0.0.1", help="address to listen on (default loopback)")
    s.add_argument("--no-pty", action="store_true", help="no tracker on a pseudo-terminal")
    s.add_argument("--no-rtde", action="store_true",
                   help="no RTDE receive server on port 30004 (ur://, read-only)")
    s.set_defaults(func=run)


def run(args) -> int:
    from sim_drivers.serve import ServeConfig, SimStack

    if args.hidden and args.model != "toy":
        from calibration import EffectError, load_model, parse_effects

        model = load_model(args.model)  # a bad model: ModelError, exit 2
        try:
            parse_effects(args.hidden, model)
        except EffectError as e:
            raise UsageError(f"--hidden {args.hidden!r}: {e}") from None
    config = ServeConfig(seed=args.seed, hidden=args.hidden, faults=args.faults,
                         time_scale=args.time_scale, host=args.host, pty=not args.no_pty,
                         rtde=not args.no_rtde)
    if args.model == "toy":
        from sim_drivers.inprocess import default_truth as factory
    else:
        from sim_drivers.model_truth import ModelTruth

        def factory(seed, hidden):
            return ModelTruth.from_spec(args.model, hidden, seed)

    try:
        stack = SimStack(config, truth_factory=factory)
    except ValueError as e:  # ModelError and EffectError are ValueErrors too
        raise UsageError(str(e)) from e
    stop = threading.Event()
    previous = signal.signal(signal.SIGTERM, lambda *_: stop.set())
    try:
        with stack:
            for url in stack.urls:
                print(url)
            for note in stack.notes:
                print(f"cellcal sim: {note}", file=sys.stderr)
            sys.stdout.flush()
            try:
                while not stop.wait(0.2):
                    pass
            except KeyboardInterrupt:
                pass
    finally:
        signal.signal(signal.SIGTERM, previous)
    print("cellcal sim: stopped", file=sys.stderr)
    return 0
