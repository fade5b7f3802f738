"""The parsers' shape: the project's help formatter, sub-command parsers with a one-line
help, and command groups (``cellcal sim``, ``cellcal capture``) that print their help
when no sub-command is given. Import-free (the parser is built at start-up)."""

from __future__ import annotations

import argparse
import re
import textwrap

from ..flags.log_flags import add_log_flags


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


def add_subcommands(parser: argparse.ArgumentParser, dest: str, metavar: str):
    """Sub-parsers of ``parser``; without one given, the command prints ``parser``'s help
    (see :func:`main`) instead of an error."""
    sub = parser.add_subparsers(dest=dest, metavar=metavar, title="commands"
                                if dest == "command" else None)
    parser.set_defaults(func=None, help_parser=parser)
    return sub


def command_parser(sub, name: str, *, help: str, description: str | None = None,
                   epilog: str | None = None) -> argparse.ArgumentParser:
    """A sub-command parser with the project's formatter and the logging flags every
    command takes (:mod:`cellcal.flags.log_flags`); its description defaults to the
    one-line ``help`` (every sub-command has one)."""
    p = sub.add_parser(name, help=help, description=description or help, epilog=epilog,
                       formatter_class=HelpFormatter)
    add_log_flags(p)
    return p
