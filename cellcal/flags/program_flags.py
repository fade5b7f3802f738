"""The flags of a robot program (``cellcal compensate --program``, ``cellcal validate``):
the program, its language, the frames a KRL program refers to by number, the robot's
temperature and payload. Free of heavy imports (the parser is built from it)."""

from __future__ import annotations

#: languages of :mod:`cellcal.programs` (``--language``)
LANGUAGES = ("urscript", "krl", "rapid")


def add_program_flags(p, *, program_help: str) -> None:
    """``--program``, ``--language``, ``--frames``, ``--temp-c``, ``--payload-kg``."""
    p.add_argument("--program", metavar="PROGRAM", help=program_help)
    p.add_argument("--language", choices=LANGUAGES, default=None,
                   help="the program's language (default from its suffix: .script, "
                   ".urscript, .txt URScript; .dat KUKA KRL; .mod, .modx, .sys, .sysx ABB "
                   "RAPID)")
    p.add_argument("--frames", metavar="frames.yaml", default=None,
                   help="KRL: the tools and bases the program's FDAT refers to by number "
                   "(tools: {1: [X, Y, Z, A, B, C]}, bases: {...}; mm, deg; docs/programs.md)")
    p.add_argument("--temp-c", type=float, default=None, metavar="C",
                   help="the robot's temperature when the program runs, °C (needed when the "
                   "calibration has thermal growth)")
    p.add_argument("--payload-kg", type=float, default=None, metavar="KG",
                   help="the payload where the program does not set one (default the "
                   "calibration's)")
