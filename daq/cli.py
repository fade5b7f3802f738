"""The ``cellcal`` command line.

Each sub-command lives in its own module under :mod:`daq.commands` and
exposes ``register(subparsers)``; adding a command is one line in
``COMMANDS``. Exit codes: 0 success, 1 failure, 2 bad input (a file, a
flag or a model that is refused: :class:`UsageError`, or the capture service's
:class:`~daq.errors.RequestError`), other codes as a command documents
(``zero`` uses 3 for "data too poor to decide", ``capture`` for a plan the tracker
would not see: :class:`~daq.errors.NotEnoughVisible`).

Start-up is kept short (``--help`` and argument errors well under 0.3 s): building the
parser imports no numpy, scipy, matplotlib or pydantic. A command module imports what
its work needs inside its ``run`` function, and the parser's constants (default effects,
solver names, routine summaries) come from :mod:`daq.commands.choices`, which
``tests/daq/test_cli_help.py`` keeps equal to the calibration core's.
"""

from __future__ import annotations

import argparse
import importlib
import re
import sys
import textwrap

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


class HelpFormatter(argparse.HelpFormatter):
    """Descriptions and epilogs keep their paragraphs (blank-line separated) and their
    indented lines (examples); option defaults are said by the help texts themselves."""

    def _fill_text(self, text, width, indent):
        out = []
        for para in re.split(r"\n\s*\n", text.strip("\n")):
            if para.startswith("  "):  # an example block: kept as written
                out.append("\n".join(indent + line for line in para.splitlines()))
            else:
                out.append(textwrap.fill(" ".join(para.split()), width,
                                         initial_indent=indent, subsequent_indent=indent))
        return "\n\n".join(out)


def software_version() -> str:
    """``cellcal X.Y.Z`` of the installed distribution (or of pyproject.toml in a checkout)."""
    try:
        from importlib.metadata import PackageNotFoundError, version

        try:
            return f"cellcal {version('cellcal')}"
        except PackageNotFoundError:
            pass
        import tomllib
        from pathlib import Path

        pyproject = Path(__file__).resolve().parents[1] / "pyproject.toml"
        return f"cellcal {tomllib.loads(pyproject.read_text())['project']['version']}"
    except Exception:  # noqa: BLE001 - a version is informative, never fatal
        return "cellcal (unknown version)"


class _Version(argparse.Action):
    """``--version``: looks the version up only when asked (no start-up cost)."""

    def __init__(self, option_strings, dest=argparse.SUPPRESS, default=argparse.SUPPRESS,
                 help="print the version and exit"):
        super().__init__(option_strings, dest=dest, default=default, nargs=0, help=help)

    def __call__(self, parser, namespace, values, option_string=None):
        print(software_version())
        parser.exit()


def add_subcommands(parser: argparse.ArgumentParser, dest: str, metavar: str):
    """Sub-parsers of ``parser``; without one given, the command prints ``parser``'s help
    (see :func:`main`) instead of an error."""
    sub = parser.add_subparsers(dest=dest, metavar=metavar, title="commands"
                                if dest == "command" else None)
    parser.set_defaults(func=None, help_parser=parser)
    return sub


def command_parser(sub, name: str, *, help: str, description: str | None = None,
                   epilog: str | None = None) -> argparse.ArgumentParser:
    """A sub-command parser with the project's formatter; its description defaults to the
    one-line ``help`` (every sub-command has one)."""
    return sub.add_parser(name, help=help, description=description or help, epilog=epilog,
                          formatter_class=HelpFormatter)


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="cellcal",
        description="Robot calibration with a laser tracker: capture, identify, "
        "diagnose the missing physics, compensate.",
        epilog="`cellcal COMMAND --help` describes a command. Exit codes: 0 done, 1 failed "
        "at run time, 2 bad input, 3 data too poor to decide, 130 interrupted "
        "(docs/formats.md §6).",
        formatter_class=HelpFormatter,
    )
    parser.add_argument("--version", action=_Version)
    sub = add_subcommands(parser, "command", "COMMAND")
    for name in COMMANDS:
        importlib.import_module(name).register(sub)
    return parser


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    if args.func is None:  # `cellcal`, `cellcal sim`, `cellcal capture`: the help
        args.help_parser.print_help()
        return 0
    from .errors import RequestError

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
