"""The ``cellcal`` command line.

Each sub-command lives in its own module under :mod:`daq.commands` and
exposes ``register(subparsers)``; adding a command is one line in
``COMMANDS``. Exit codes (docs/formats.md §6): 0 success, 1 failure at run time,
2 bad input (a file, a flag or a model that is refused: :class:`UsageError`, the
capture service's :class:`~daq.errors.RequestError`, or a reader's own error such as
``DataError``), 3 the data are too poor for what was asked
(:class:`calibration.data_quality.InsufficientData`), 130 interrupted.

Whatever goes wrong, the user gets one line, never a traceback: an error of the
operating system (a missing folder, a permission, a full disk) is named with its
file; stdout closed by its reader (``cellcal runs --json | head``) ends quietly; an
unexpected exception is reported as an internal error (``CELLCAL_TRACEBACK=1`` shows
the traceback).
"""

from __future__ import annotations

import argparse
import errno
import importlib
import os
import sys

#: sub-command modules, in the order ``cellcal --help`` lists them
COMMANDS = [
    "daq.commands.demo",
    "daq.commands.capture",
    "daq.commands.runs",
    "daq.commands.resume",
    "daq.commands.export_run",
    "daq.commands.calibrate",
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


#: errors of the operating system that mean a bad path or permission (exit 2, not 1)
_INPUT_ERRNOS = {errno.ENOENT, errno.EACCES, errno.EPERM, errno.EISDIR, errno.ENOTDIR,
                 errno.EROFS, errno.ENAMETOOLONG, errno.ELOOP, errno.EEXIST}


def _one_line(e: BaseException) -> str:
    text = " ".join(str(e).split("\n")) if str(e) else type(e).__name__
    return text if len(text) <= 2000 else text[:2000] + " ..."


def _os_error(e: OSError) -> str:
    what = e.strerror or str(e)
    return f"{e.filename}: {what}" if e.filename else what


def main(argv: list[str] | None = None) -> int:
    from calibration import DataError, EffectError, ModelError
    from calibration.data_quality import InsufficientData
    from calibration.params_io import ParamsError

    from .errors import RequestError

    parser = build_parser()
    try:
        args = parser.parse_args(argv)
    except SystemExit as e:  # a usage error (argparse printed it): the exit code, returned
        if e.code in (0, None):
            raise  # --help
        return e.code if isinstance(e.code, int) else 2
    name = args.command + (f" {args.sim_command}" if getattr(args, "sim_command", None) else "")
    try:
        rc = int(args.func(args) or 0)
        sys.stdout.flush()  # a reader that went away shows here, not at the exit
        return rc
    except BrokenPipeError:
        _quiet_stdout()
        return 0
    except (UsageError, RequestError, DataError, ModelError, EffectError, ParamsError) as e:
        print(f"cellcal {name}: error: {_one_line(e)}", file=sys.stderr)
        return 2
    except InsufficientData as e:
        print(f"cellcal {name}: data too poor: {_one_line(e)}", file=sys.stderr)
        return 3
    except KeyboardInterrupt:
        print(f"cellcal {name}: interrupted", file=sys.stderr)
        return 130
    except OSError as e:
        print(f"cellcal {name}: error: {_os_error(e)}", file=sys.stderr)
        return 2 if e.errno in _INPUT_ERRNOS else 1
    except Exception as e:  # noqa: BLE001 - the last resort: one line, never a traceback
        if os.environ.get("CELLCAL_TRACEBACK"):
            raise
        print(f"cellcal {name}: internal error: {type(e).__name__}: {_one_line(e)} "
              "(please report it; CELLCAL_TRACEBACK=1 shows the traceback)", file=sys.stderr)
        return 1


def _quiet_stdout() -> None:
    """stdout's reader is gone: point stdout at /dev/null so the interpreter's final flush
    does not fail again (the Python documentation's recipe for SIGPIPE)."""
    try:
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
        os.close(devnull)
    except (OSError, ValueError, AttributeError):  # stdout is no file (captured in a test)
        pass


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
