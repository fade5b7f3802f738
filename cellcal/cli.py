"""The ``cellcal`` command line.

Each sub-command lives in its own module under :mod:`cellcal.commands` and
exposes ``register(subparsers)``; adding a command is one line in
``COMMANDS``. Exit codes: docs/formats.md §6 (the only place they are listed).
:func:`main` maps every error family of every layer, each class carrying its
``exit_code``, in one place: :class:`UsageError` (2), the core's
:class:`calibration.errors.CalibrationError` (2 bad input, 3 the data are too poor:
``InsufficientData``), the capture service's :class:`daq.errors.DaqError` (2 a request it
refuses, 3 a plan the tracker would not see, 1 the devices unreachable), the run store's
:class:`daq.store.errors.StoreError` (2, 1 unreachable) and the drivers'
:class:`drivers.errors.DriverError` (1).

Whatever goes wrong, the user gets one line, never a traceback: an error of the
operating system (a missing folder, a permission, a full disk) is named with its
file; stdout closed by its reader (``cellcal runs --json | head``) ends quietly; an
unexpected exception is reported as an internal error (``CELLCAL_TRACEBACK=1`` shows
the traceback).

Start-up is kept short (``--help`` and argument errors well under 0.3 s): building the
parser imports no numpy, scipy, matplotlib or pydantic. A command module imports what
its work needs inside its ``run`` function, and the parser's constants (default effects,
solver names, routine summaries) come from :mod:`cellcal.flags.choices`, which
``tests/cellcal/test_cli_help.py`` keeps equal to the calibration core's. The error
families are caught only once their module is loaded (:func:`_Loaded`).

Logging is set up here, once per command (:func:`cellcal.logs.configured`), from the
flags every command takes before or after its name (``-v``, ``--log-level``,
``--log-file``: :mod:`cellcal.flags.log_flags`); the command line and how it ended are
logged at INFO, an error's traceback at DEBUG.
"""

from __future__ import annotations

import argparse
import errno
import importlib
import logging
import os
import sys

from .commands.parsers import HelpFormatter, add_subcommands
from .errors import UsageError
from .flags.log_flags import add_log_flags

log = logging.getLogger(__name__)

#: sub-command modules, in the order ``cellcal --help`` lists them
COMMANDS = [
    "cellcal.commands.demo",
    "cellcal.commands.capture",
    "cellcal.commands.runs",
    "cellcal.commands.resume",
    "cellcal.commands.export_run",
    "cellcal.commands.calibrate",
    "cellcal.commands.check",
    "cellcal.commands.history",
    "cellcal.commands.diagnose",
    "cellcal.commands.models",
    "cellcal.commands.sim_serve",
    "cellcal.commands.simulate_dataset",
    "cellcal.commands.zero",
    "cellcal.commands.report",
    "cellcal.commands.compensate",
    "cellcal.commands.validate",
]




class _Version(argparse.Action):
    """``--version``: looks the version up only when asked (no start-up cost)."""

    def __init__(self, option_strings, dest=argparse.SUPPRESS, default=argparse.SUPPRESS,
                 help="print the version and exit"):
        super().__init__(option_strings, dest=dest, default=default, nargs=0, help=help)

    def __call__(self, parser, namespace, values, option_string=None):
        from calibration.version import software_version  # loaded when asked: start-up

        print(software_version())
        parser.exit()



def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="cellcal",
        description="Robot calibration with a laser tracker: capture, identify, "
        "diagnose the missing physics, compensate.",
        epilog="`cellcal COMMAND --help` describes a command. Exit codes: 0 done, 1 failed "
        "at run time, 2 bad input, 3 data too poor for what was asked, 130 interrupted; "
        "what they mean for each command: docs/formats.md §6.",
        formatter_class=HelpFormatter,
    )
    parser.add_argument("--version", action=_Version)
    add_log_flags(parser, top=True)
    sub = add_subcommands(parser, "command", "COMMAND")
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


#: the error family of each layer, (module, class name) pairs: every class in them has
#: its ``exit_code`` (docs/formats.md §6)
_FAMILIES = ("calibration.errors", "CalibrationError", "daq.errors", "DaqError",
             "daq.store.errors", "StoreError", "drivers.errors", "DriverError")


def _Loaded(*pairs: str) -> tuple[type, ...]:  # noqa: N802 - used as an exception type
    """The exception classes named by (module, class) pairs whose modules are loaded: a
    module never imported raised nothing, and the parser stays free of the core."""
    out = []
    for mod, cls in zip(pairs[::2], pairs[1::2], strict=True):
        c = getattr(sys.modules.get(mod), cls, None)
        if c is not None:
            out.append(c)
    return tuple(out)


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)  # a usage error: argparse prints it and exits with 2
    if args.func is None:  # `cellcal`, `cellcal sim`, `cellcal capture`: the help
        args.help_parser.print_help()
        return 0
    from cellcal.url_schemes import register_schemes  # after parsing: a short start-up

    register_schemes()  # sim:// (drivers.urls knows the real cell's schemes itself)
    name = args.command + (f" {args.sim_command}" if getattr(args, "sim_command", None) else "")
    from .logs import configured  # after parsing: a short start-up

    args.command_line = "cellcal " + " ".join(sys.argv[1:] if argv is None else argv)
    try:
        with configured(args):
            log.info("%s", args.command_line)
            try:
                rc = int(args.func(args) or 0)
                sys.stdout.flush()  # a reader that went away shows here, not at the exit
            except BaseException as e:
                log.info("cellcal %s ended by %s: %s", name, type(e).__name__, _one_line(e))
                log.debug("the traceback", exc_info=True)
                raise
            log.info("cellcal %s: exit %d", name, rc)
        return rc
    except BrokenPipeError:
        _quiet_stdout()
        return 0
    except (UsageError, *_Loaded(*_FAMILIES)) as e:
        poor = isinstance(e, _Loaded("calibration.errors", "InsufficientData"))
        print(f"cellcal {name}: {'data too poor' if poor else 'error'}: {_one_line(e)}",
              file=sys.stderr)
        return e.exit_code
    except KeyboardInterrupt:
        print(f"cellcal {name}: interrupted", file=sys.stderr)
        return 130
    except MemoryError as e:  # what the estimate before the work did not foresee
        print(f"cellcal {name}: error: out of memory{f' ({_one_line(e)})' if str(e) else ''}: "
              "the data are too large for the memory this machine has left; split them "
              "or run where there is more memory", file=sys.stderr)
        return 3
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
