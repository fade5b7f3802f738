"""``cellcal sim serve``: run the simulated cell behind its wire protocols until stopped.

Prints one driver URL per line (Modbus robot, line robot, tracker over TCP,
tracker over a pty, emScon tracker ``emscon://127.0.0.1:PORT``, then the
read-only RTDE robot when port 30004 was free), then serves until Ctrl-C or
SIGTERM and stops cleanly (exit code 0). The simulated tracker's line of sight is honest
(:mod:`sim_drivers.beam`): ``--tracker-at`` places it, ``--cell`` adds fixtures.
"""

from __future__ import annotations

import signal
import sys
import threading

from daq.cli import UsageError


def register(sub) -> None:
    p = sub.add_parser("sim", help="simulated cell: serve it over the real wire protocols")
    ssub = p.add_subparsers(dest="sim_command", metavar="SIM_COMMAND")
    ssub.required = True
    s = ssub.add_parser("serve", help="start the simulated servers and print their URLs")
    s.add_argument("--seed", type=int, default=0, help="random seed of the cell (default 0)")
    s.add_argument("--model", default="ur10e",
                   help="the true robot: a model name or YAML with realistic hidden errors "
                        "(default ur10e), or 'toy' for a 3-joint stand-in arm")
    s.add_argument("--tracker-at", metavar="X,Y,Z", default=None,
                   help="where the simulated tracker stands, robot base frame, mm (default "
                   "2500,0,500; write --tracker-at=-2500,0,500 for a negative first value)")
    s.add_argument("--cell", metavar="cell.yaml", default=None,
                   help="the simulated cell: fixtures that break the beam, the SMR axis and "
                   "acceptance, the tracker position (docs/formats.md section 7)")
    s.add_argument("--hidden", default=None,
                   help="hidden physical effects of the true robot, e.g. compliance:3")
    s.add_argument("--faults", default=None,
                   help="fault spec, e.g. 'beam=0.05,slow=0.02,drop@3,delay=2'; "
                        "'blunder=0.03': 3 %% of tracker readings off by 0.5-5 mm")
    s.add_argument("--time-scale", type=float, default=0.0,
                   help="wall seconds per simulated second (0: instantaneous)")
    s.add_argument("--host", default="127.0.0.1", help="address to listen on (default loopback)")
    s.add_argument("--no-pty", action="store_true", help="no tracker on a pseudo-terminal")
    s.add_argument("--no-rtde", action="store_true",
                   help="no RTDE receive server on port 30004 (ur://, read-only)")
    s.add_argument("--no-weather-station", action="store_true",
                   help="the tracker has no weather station (give it the air: capture --meteo)")
    s.add_argument("--tracker-collimation-urad", type=float, default=0.0, metavar="URAD",
                   help="the tracker's two-face (collimation) error, µrad (default 0)")
    s.add_argument("--tracker-warmup-s", type=float, default=0.0, metavar="S",
                   help="simulated seconds until the tracker is warmed up (default 0)")
    s.set_defaults(func=run)


def run(args) -> int:
    from sim_drivers.serve import ServeConfig, SimStack

    if args.time_scale < 0:
        raise UsageError(f"--time-scale must be >= 0, got {args.time_scale}")
    from calibration.cell import load_cell

    from .routine_args import floats

    config = ServeConfig(seed=args.seed, hidden=args.hidden, faults=args.faults,
                         time_scale=args.time_scale, host=args.host, pty=not args.no_pty,
                         rtde=not args.no_rtde)
    try:
        tracker_at = floats(args.tracker_at, 3, "--tracker-at")
        cell = load_cell(args.cell) if args.cell else None
    except ValueError as e:
        raise UsageError(str(e)) from None
    if args.model == "toy":
        from sim_drivers.inprocess import default_truth as factory
    else:
        from sim_drivers.model_truth import DEFAULT_TRACKER_AT_MM, ModelTruth

        at = tracker_at or (cell.tracker_mm if cell is not None and cell.tracker is not None
                            else DEFAULT_TRACKER_AT_MM)
        axis = (0.0, 0.0, 1.0) if cell is None else cell.smr.axis

        def factory(seed, hidden):
            return ModelTruth.from_spec(args.model, hidden, seed, tracker_at=at, smr_axis=axis)

    if args.tracker_warmup_s < 0:
        raise UsageError(f"--tracker-warmup-s must be >= 0, got {args.tracker_warmup_s}")
    try:
        stack = SimStack(config, truth_factory=factory, cell=cell,
                         weather_station=not args.no_weather_station,
                         tracker_collimation_rad=args.tracker_collimation_urad * 1e-6,
                         warmup_s=args.tracker_warmup_s)
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
