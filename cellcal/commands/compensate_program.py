"""``cellcal compensate --program``: the command's program path (its flags are registered
by :mod:`cellcal.commands.compensate`; the work is
:func:`cellcal.usecases.compensate_program.compensate_program`)."""

from __future__ import annotations

import sys

from ..flags.program_flags import add_program_flags
from .common import print_json

#: what ``--program`` says in ``cellcal compensate --help``
PROGRAM_HELP = ("compensate a robot program (URScript .script, KUKA KRL .dat, ABB RAPID "
                ".mod) into --out: its targets rewritten, every other byte kept "
                "(docs/programs.md); exit 1 when a target cannot be compensated (nothing "
                "written unless --allow-partial)")


def add_flags(p) -> None:
    """The program path's own flags (beside ``--params``, ``--out``, ``--start``, ``--json``)."""
    add_program_flags(p, program_help=PROGRAM_HELP)
    p.add_argument("--allow-partial", action="store_true",
                   help="with --program: write the program even when some targets cannot be "
                   "compensated (they stay as written and are listed; exit 0)")


#: flags that only go with --program (attribute, flag)
_PROGRAM_ONLY = (("language", "--language"), ("frames", "--frames"), ("temp_c", "--temp-c"),
                 ("payload_kg", "--payload-kg"), ("allow_partial", "--allow-partial"))


def uses_program(args) -> bool:
    """``--program`` or one of its own flags was given."""
    return bool(args.program) or any(getattr(args, a) not in (None, False)
                                      for a, _ in _PROGRAM_ONLY)


def run_program(args) -> int:
    """Compensate the program; print the report (text or ``--json``); the exit code."""
    from ..errors import UsageError
    from ..usecases.compensate_program import (
        ProgramRequest,
        compensate_program,
        refuse_other_flags,
    )

    if not args.program:
        given = [f for a, f in _PROGRAM_ONLY if getattr(args, a) not in (None, False)]
        raise UsageError(f"{', '.join(given)}: only with --program")
    refuse_other_flags(args)
    from presentation.compensation_text import outside_warning

    report = compensate_program(ProgramRequest.from_args(args))
    warning = outside_warning(report.outside, where="the report (outside_range)")
    if warning:
        print(warning, file=sys.stderr)
    if args.json:
        print_json(report.to_json())
    else:
        print("\n".join(report.lines()))
    return 0 if report.written and args.allow_partial else report.exit_code
