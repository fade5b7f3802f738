"""The logging flags every command takes: ``-v``/``--verbose``, ``--log-level LEVEL``,
``--log-file FILE`` (docs/logging.md).

They are global options: the top-level parser has them (``cellcal -v capture ...``) and
so has every sub-command's parser (``cellcal capture poses ... -v``), there with
``SUPPRESS`` defaults so that a sub-command does not reset what was given before its
name. Import-free (the parser is built at start-up); :mod:`cellcal.logs` sets the
handlers up from the values.
"""

from __future__ import annotations

import argparse

#: the levels ``--log-level`` takes (case-insensitive)
LEVELS = ("DEBUG", "INFO", "WARNING", "ERROR", "CRITICAL")
#: the level of no flag, of ``-v`` and of ``-vv``
DEFAULT_LEVEL = "WARNING"
VERBOSE_LEVELS = ("WARNING", "INFO", "DEBUG")


def log_level(text: str) -> str:
    """``--log-level``'s type: a level name, upper-cased; a usage error (exit 2) otherwise."""
    level = str(text).strip().upper()
    if level not in LEVELS:
        raise argparse.ArgumentTypeError(
            f"{text!r} is not a log level: choose one of {', '.join(LEVELS)} "
            "(case-insensitive)")
    return level


def add_log_flags(parser: argparse.ArgumentParser, *, top: bool = False) -> None:
    """The logging flags on ``parser``: with their defaults on the top-level parser
    (``top``), with none (``SUPPRESS``) on a sub-command's."""
    d = (lambda v: v) if top else (lambda v: argparse.SUPPRESS)
    g = parser.add_argument_group("logging (every command)")
    g.add_argument("-v", "--verbose", action="count", default=d(0),
                   help="log more to stderr: -v the capture service's decisions (INFO), "
                   "-vv also the drivers' wire traffic (DEBUG); default: warnings only")
    g.add_argument("--log-level", type=log_level, default=d(None), metavar="LEVEL",
                   help=f"the log level ({', '.join(LEVELS)}; case-insensitive); with -v "
                   "the more verbose of the two applies")
    g.add_argument("--log-file", default=d(None), metavar="FILE",
                   help="write the log to FILE (appended to; an existing file that is not a "
                   "cellcal log is refused, never overwritten); stderr then shows warnings "
                   "only")


def chosen_level(args) -> str:
    """The level the flags of ``args`` ask for: the more verbose of ``--log-level`` and
    ``-v``/``-vv``; WARNING when neither is given."""
    n = int(getattr(args, "verbose", 0) or 0)
    given = getattr(args, "log_level", None)
    if n == 0:
        return given or DEFAULT_LEVEL
    by_v = VERBOSE_LEVELS[min(n, len(VERBOSE_LEVELS) - 1)]
    return by_v if given is None else min(given, by_v, key=LEVELS.index)
