"""Helpers shared by the sub-commands: the argparse types of numbers, the options several
commands share, printing (notes, JSON, tables), and the guards the commands call before
their work.

Guards
    :func:`check_outputs` (:mod:`cellcal.usecases.outputs`) refuses an output path that is
    one of the command's inputs, a run store (any SQLite file), a directory, in a missing
    folder, or named twice; every write then goes through
    :func:`calibration.files.write_atomic`. The argparse types (:func:`positive_float`,
    :func:`nonneg_int`, ...) refuse NaN, infinities and out-of-range numbers with a
    message naming the flag (exit 2). :func:`open_store` (:mod:`cellcal.usecases.stores`)
    opens an existing run store or names why it cannot.

The commands' typed requests and the functions that do their work are in
:mod:`cellcal.usecases`; the text they print is made in :mod:`presentation`.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
from pathlib import Path

from ..flags.choices import DB_HELP, DEFAULT_EFFECTS, solver_help
from ..usecases.input_errors import wrap_errors
from ..usecases.outputs import check_outputs, existing_paths
from ..usecases.stores import open_store, store_errors

__all__ = ["DB_HELP", "MODEL_HELP", "add_current_model_args", "add_model_args", "bounded_float",
           "bounded_int", "check_outputs", "finite_float", "fmt", "input_paths", "nonneg_float",
           "nonneg_int", "open_store", "positive_float", "positive_int", "print_json",
           "print_note", "seed_int", "store_errors", "table", "wrap_errors"]

#: what --model says when the data may name the model
MODEL_HELP = ("built-in model name (see `cellcal models`) or a model YAML file (default: "
              "the model the CSV's `# model:` line names, as `cellcal export` writes it)")


# ------------------------------------------------------------------ number arguments
def _number_type(kind, lo=None, hi=None, lo_open=False, what="a number"):
    def parse(text: str):
        try:
            v = kind(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"{text!r} is not {what}") from None
        if isinstance(v, float) and not math.isfinite(v):
            raise argparse.ArgumentTypeError(f"{text!r} is not {what} (finite)")
        if lo is not None and (v <= lo if lo_open else v < lo):
            raise argparse.ArgumentTypeError(f"{text} is not {what}")
        if hi is not None and v > hi:
            raise argparse.ArgumentTypeError(
                f"{text} is not {what}" + ("" if lo is not None else f" (at most {hi:g})"))
        return v
    parse.__name__ = what  # argparse names the type in its messages
    return parse


#: argparse types: finite numbers within their range (messages name the expected form)
positive_float = _number_type(float, 0.0, None, True, "a positive number")
nonneg_float = _number_type(float, 0.0, None, False, "a number >= 0")
finite_float = _number_type(float, None, None, False, "a finite number")
nonneg_int = _number_type(int, 0, None, False, "an integer >= 0")
positive_int = _number_type(int, 1, None, False, "an integer >= 1")
seed_int = _number_type(int, 0, 2**63 - 1, False, "a seed (an integer 0 .. 2**63-1)")


def bounded_int(lo: int, hi: int):
    """An argparse type: an integer in [lo, hi]."""
    return _number_type(int, lo, hi, False, f"an integer {lo} .. {hi}")


def bounded_float(lo: float, hi: float):
    """An argparse type: a finite number in [lo, hi]."""
    return _number_type(float, lo, hi, False, f"a number {lo:g} .. {hi:g}")


# ------------------------------------------------------------------------- outputs
def input_paths(args, *names: str) -> list[str]:
    """The values of these argparse attributes that name existing files (lists flattened;
    a built-in model name is no path): :func:`~cellcal.usecases.outputs.existing_paths`."""
    return existing_paths(*(getattr(args, n, None) for n in names))


def add_model_args(p, data: bool = True) -> None:
    if data:
        p.add_argument("data", metavar="DATA.csv",
                       help="measurement CSV (docs/formats.md §1), e.g. from `cellcal export`; "
                       "its `# key: value` header (model, tool, measurement frame, tracker "
                       "sigma) is used")
    p.add_argument("--model", default=None, metavar="NAME|PATH", help=MODEL_HELP)
    p.add_argument("--effect-file", action="append", default=[], metavar="FILE.py",
                   help="load user-defined effects from a Python file (repeatable)")
    p.add_argument("--sigma", type=positive_float, default=None, metavar="MM",
                   help="tracker standard uncertainty per axis, mm (default: from the CSV's "
                   "sigma_mm column or `# tracker_sigma_mm:` line)")
    p.add_argument("--json", action="store_true", help="print one JSON object instead of tables")


def add_current_model_args(p, params_help: str, solver_what: str = "identification method"
                           ) -> None:
    """``--effects``, ``--params`` and ``--solver``: the current model, as
    :func:`calibration.workflow.current_fit` takes it (given parameters, or fitted)."""
    from ..flags.choices import SOLVERS

    p.add_argument("--effects", default=DEFAULT_EFFECTS, metavar="LIST",
                   help=f"the current model's effects, comma-separated (default "
                   f"{DEFAULT_EFFECTS}; see docs/formats.md §3)")
    p.add_argument("--params", metavar="params.json", help=params_help)
    p.add_argument("--solver", default="lm", choices=list(SOLVERS), metavar="SOLVER",
                   help=solver_help(solver_what))


def print_note(text: str) -> None:
    """A remark for the user on stderr (stdout stays for results and JSON)."""
    print(f"note: {text}", file=sys.stderr)


def print_json(obj) -> None:
    from calibration.files import json_ready

    def default(o):
        if hasattr(o, "tolist"):
            return o.tolist()
        if isinstance(o, Path):
            return str(o)
        raise TypeError(type(o).__name__)

    json.dump(json_ready(obj), sys.stdout, default=default)
    sys.stdout.write("\n")


def fmt(v, digits: int = 3) -> str:
    """:func:`presentation.text_table.fmt` (imported when called: start-up)."""
    from presentation.text_table import fmt as fmt_number

    return fmt_number(v, digits)


def table(rows: list[list[str]], header: list[str], left: tuple[int, ...] = (0,)) -> str:
    """:func:`presentation.text_table.table` (imported when called: start-up)."""
    from presentation.text_table import table as text_table

    return text_table(rows, header, left)


