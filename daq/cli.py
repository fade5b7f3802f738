"""The ``cellcal`` command line.

Each sub-command lives in its own module under :mod:`daq.commands` and
exposes ``register(subparsers)``; adding a command is one line in
``COMMANDS``. Exit codes: 0 success, 1 failure, 2 bad input (a file, a
flag or a model that is refused: :class:`UsageError`, or the capture service's
:class:`~daq.errors.RequestError`), other codes as a command documents
(``zero`` uses 3 for "data too poor to decide", ``capture`` for a plan the tracker
would not see: :class:`~daq.errors.NotEnoughVisible`).
"""

from __future__ import annotations

import argparse
import importlib
import sys

#: sub-command modules, in the order ``cellcal --help`` lists them
COMMANDS = [
    "daq.commands.demo",
    "daq.commands.capture",
    "daq.commands.runs",
    "daq.commands.resume",
    "daq.commands.export_run",
    "daq.commands.calibrate",
    "daq.commands.history",
    "daq.commands.diagnose",
    "daq.commands.models",
    "daq.commands.sim_serve",
    "daq.commands.simulate_dataset",
    "daq.commands.zero",
    "daq.commands.report",
    "daq.commands.compensate",
]


class UsageError(Exception):
    """Bad input from the user: printed without a traceback, exit code 2."""


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="cellcal",
        description="Robot calibration with a laser tracker: capture, identify, "
        "diagnose the missing physics, compensate.",
    )
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    sub.required = True
    for name in COMMANDS:
        importlib.import_module(name).register(sub)
    return parser


def main(argv: list[str] | None = None) -> int:
    from .errors import RequestError

    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        return int(args.func(args) or 0)
    except (UsageError, RequestError) as e:
        print(f"cellcal {args.command}: error: {e}", file=sys.stderr)
        return getattr(e, "exit_code", 2)
    except KeyboardInterrupt:
        print(f"cellcal {args.command}: interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
