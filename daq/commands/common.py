"""Helpers shared by the sub-commands: loading inputs with user-facing errors, printing.

Import-light (the parser is built without the calibration core, :mod:`daq.cli`): the
core is imported inside the functions that load data.
"""

from __future__ import annotations

import json
import math
import sys
from pathlib import Path

from ..cli import UsageError
from .choices import DEFAULT_EFFECTS, solver_help

#: what --model says when the data may name the model
MODEL_HELP = ("built-in model name (see `cellcal models`) or a model YAML file (default: "
              "the model the CSV's `# model:` line names, as `cellcal export` writes it)")


def add_model_args(p, data: bool = True) -> None:
    if data:
        p.add_argument("data", metavar="DATA.csv",
                       help="measurement CSV (docs/formats.md §1), e.g. from `cellcal export`; "
                       "its `# key: value` header (model, tool, measurement frame, tracker "
                       "sigma) is used")
    p.add_argument("--model", default=None, metavar="NAME|PATH", help=MODEL_HELP)
    p.add_argument("--effect-file", action="append", default=[], metavar="FILE.py",
                   help="load user-defined effects from a Python file (repeatable)")
    p.add_argument("--sigma", type=float, default=None, metavar="MM",
                   help="tracker standard uncertainty per axis, mm (default: from the CSV's "
                   "sigma_mm column or `# tracker_sigma_mm:` line)")
    p.add_argument("--json", action="store_true", help="print one JSON object instead of tables")


def add_current_model_args(p, params_help: str, solver_what: str = "identification method"
                           ) -> None:
    """``--effects``, ``--params`` and ``--solver``: the current model, as
    :func:`calibration.workflow.current_fit` takes it (given parameters, or fitted)."""
    from .choices import SOLVERS

    p.add_argument("--effects", default=DEFAULT_EFFECTS, metavar="LIST",
                   help=f"the current model's effects, comma-separated (default "
                   f"{DEFAULT_EFFECTS}; see docs/formats.md §3)")
    p.add_argument("--params", metavar="params.json", help=params_help)
    p.add_argument("--solver", default="lm", choices=list(SOLVERS), metavar="SOLVER",
                   help=solver_help(solver_what))


def model_name(args, what: str = "DATA.csv") -> str:
    """``--model``, else the model the data file's metadata names; UsageError when neither."""
    if args.model:
        return args.model
    from calibration.dataset import read_meta

    name = read_meta(args.data).get("model") if getattr(args, "data", None) else None
    if not name:
        raise UsageError(f"give --model: {getattr(args, 'data', None) or what} names no model "
                         "(no `# model:` line)")
    return name


def load_inputs(args):
    """(model, dataset) from the common arguments; bad input becomes a UsageError.

    The model gets the capture's tool (the controller's TCP, ``# tool_mm:`` in the CSV's
    metadata) as its nominal tool, so every fit starts from what the controller knew.
    """
    from calibration import DataError, ModelError, load_csv, load_model
    from calibration.effects import EffectError, load_effect_file

    try:
        for f in args.effect_file:
            load_effect_file(f)
        model = load_model(model_name(args))
        data = load_csv(args.data, model) if getattr(args, "data", None) else None
    except (ModelError, DataError, EffectError) as e:
        raise UsageError(str(e)) from None
    if data is not None:
        model = data.capture.with_tool(model)
    if data is not None and args.sigma is not None:
        if not (args.sigma > 0 and math.isfinite(args.sigma)):
            raise UsageError("--sigma must be a positive number of mm")
        data.sigma_mm = None
        data.meta["tracker_sigma_mm"] = repr(args.sigma)
    return model, data


def tool_text(model, data, params: str | None = None) -> str:
    """``tool 0, 0, 60 mm (capture run 2)``: the nominal tool and where it came from."""
    cap = data.capture
    if params:
        where = params
    elif cap.tool_mm is not None:
        where = "capture" + (f" run {cap.run}" if cap.run is not None else "")
    else:
        where = "model"
    return "tool " + ", ".join(f"{v:g}" for v in model.tool) + f" mm ({where})"


def wrap_errors(fn, *exc):
    """Run fn(); turn the given exception types into UsageError."""
    from calibration import DataError, ModelError
    from calibration.effects import EffectError
    from calibration.params_io import ParamsError

    try:
        return fn()
    except (ModelError, DataError, EffectError, ParamsError, *exc) as e:
        raise UsageError(str(e)) from None


def print_json(obj) -> None:
    def default(o):
        if hasattr(o, "tolist"):
            return o.tolist()
        if isinstance(o, Path):
            return str(o)
        raise TypeError(type(o).__name__)

    def clean(o):
        if isinstance(o, float) and not math.isfinite(o):
            return None
        if isinstance(o, dict):
            return {k: clean(v) for k, v in o.items()}
        if isinstance(o, (list, tuple)):
            return [clean(v) for v in o]
        return o

    json.dump(clean(obj), sys.stdout, default=default)
    sys.stdout.write("\n")


def fmt(v, digits: int = 3) -> str:
    if v is None or (isinstance(v, float) and not math.isfinite(v)):
        return "-"
    return f"{v:.{digits}f}"


def table(rows: list[list[str]], header: list[str], left: tuple[int, ...] = (0,)) -> str:
    """A plain-text table: columns in ``left`` left-aligned, the others right-aligned."""
    widths = [max(len(str(r[i])) for r in [header, *rows]) for i in range(len(header))]
    lines = ["  ".join(str(h).ljust(w) for h, w in zip(header, widths, strict=True))]
    lines.append("  ".join("-" * w for w in widths))
    for r in rows:
        lines.append("  ".join(
            str(c).ljust(w) if i in left else str(c).rjust(w)
            for i, (c, w) in enumerate(zip(r, widths, strict=True))
        ))
    return "\n".join(line.rstrip() for line in lines)


def print_outliers(screen, context: str = "fit") -> None:
    """The blunder verdict: one sentence, and a table of the blunders."""
    if screen is None or (screen.clean_cloud and not screen.blunders):
        return
    print(f"blunders  {screen.message(context, list_points=False)}")
    if screen.blunders:
        rows = [[b.pose_id, b.line or "-", fmt(b.residual_mm), fmt(b.ratio, 1),
                 {True: "along", False: "across", None: "-"}[b.along_beam],
                 fmt(b.angle_deg, 0)] for b in screen.blunders]
        print(table(rows, ["pose", "line", "residual mm", "x threshold", "beam",
                           "angle deg"]))


#: the ``--db`` help of every command that reads or writes a run store
DB_HELP = ("run store: a SQLite file or a PostgreSQL URL postgresql://user@host[:port]/db "
           "(password from PGPASSWORD or ~/.pgpass)")


def open_store(address, synchronous: str = "FULL", *, read_only: bool = False):
    """An existing run store (a file or a ``postgresql://`` URL); a missing or unreadable
    store, or a server that cannot be reached, is a UsageError (never create an empty
    store for a mistyped address)."""
    from ..store import StoreError
    from ..store import open_store as open_run_store

    try:
        return open_run_store(address, create=False, read_only=read_only,
                              synchronous=synchronous)
    except (StoreError, OSError) as e:
        raise UsageError(str(e)) from None
