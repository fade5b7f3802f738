"""Helpers shared by the sub-commands: loading inputs with user-facing errors, the guards
on outputs and on numbers, printing.

Guards
    :func:`check_outputs` refuses an output path that is one of the command's inputs, a
    run store (any SQLite file), a directory, in a missing folder, or named twice; every
    write then goes through :func:`calibration.files.write_atomic`. The argparse types
    (:func:`positive_float`, :func:`nonneg_int`, ...) refuse NaN, infinities and
    out-of-range numbers with a message naming the flag (exit 2).
"""

from __future__ import annotations

import argparse
import contextlib
import json
import math
import os
import sys
from pathlib import Path

from ..cli import UsageError
from .choices import DEFAULT_EFFECTS, solver_help

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
def _same_file(a: Path, b: Path) -> bool:
    try:
        return a.exists() and b.exists() and os.path.samefile(a, b)
    except OSError:
        return False


def check_outputs(outputs: dict[str, str | None], inputs=(), *, stdout: bool = False) -> None:
    """Refuse output paths that would destroy something (UsageError, exit 2).

    ``outputs`` maps a flag (``--out``) to its path (None: not given); ``inputs`` are the
    command's input paths (None and non-paths such as built-in model names are skipped).
    Refused: an output that is an input, any SQLite file (a run store is never
    overwritten), a directory, a path in a missing folder, a folder not writable, and one
    path given for two outputs. ``stdout``: ``-`` means standard output.
    """
    from calibration.files import is_sqlite_file

    seen: dict[str, str] = {}
    ins = [Path(i) for i in inputs if i]
    for flag, out in outputs.items():
        if out is None or (stdout and out == "-"):
            continue
        p = Path(out)
        if p.is_dir():
            raise UsageError(f"{flag} {out}: is a directory; give a file name")
        folder = p.parent
        if not folder.is_dir():
            raise UsageError(f"{flag} {out}: the folder {folder} does not exist (no such "
                             "directory)")
        for i in ins:
            if _same_file(p, i) or p.resolve() == i.resolve():
                raise UsageError(f"{flag} {out} is an input of this command; write to a new "
                                 "file (cellcal never overwrites its inputs)")
        if is_sqlite_file(p):
            raise UsageError(f"{flag} {out}: is a run store (an SQLite database); cellcal "
                             "never overwrites one: give a new file name")
        if p.exists() and not p.is_file():
            continue  # /dev/null, /dev/stdout, a FIFO: written directly
        if not os.access(folder, os.W_OK):
            raise UsageError(f"{flag} {out}: the folder {folder} is not writable")
        key = str(p.resolve())
        if key in seen:
            raise UsageError(f"{seen[key]} and {flag} name the same file {out}; give two "
                             "different files")
        seen[key] = flag


def input_paths(args, *names: str) -> list[str]:
    """The values of these argparse attributes that name existing files (lists flattened;
    a built-in model name is no path)."""
    out = []
    for n in names:
        v = getattr(args, n, None)
        for item in v if isinstance(v, list) else [v]:
            if item and isinstance(item, str) and Path(item).exists():
                out.append(item)
    return out


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
def error_model_of(model, spec: str, flag: str = "--effects"):
    """``ErrorModel(model, spec)``; a bad effect list is a UsageError naming the flag."""
    from calibration import ErrorModel
    from calibration.effects import EffectError

    try:
        return ErrorModel(model, spec)
    except EffectError as e:
        raise UsageError(f"{flag} {spec!r}: {e}") from None


def current_model(args, model):
    """The current model of diagnose/report: (error model, params source for
    :func:`calibration.workflow.current_fit` or None, notes). ``--params`` is read
    strictly and checked against ``--model``; else ``--effects`` on the model."""
    from calibration.params_io import read_params

    if getattr(args, "params", None):
        p = read_params(args.params, model=model)
        return p.error_model, (p.error_model, p.values), p.notes
    return error_model_of(model, args.effects), None, []


def check_data(error_model, data) -> list[str]:
    """Refuse data too poor to identify ``error_model`` (InsufficientData: exit 3); the
    notes on marginal data otherwise."""
    from calibration.data_quality import check_for_fit

    return check_for_fit(error_model, data).notes


def print_note(text: str) -> None:
    """A remark for the user on stderr (stdout stays for results and JSON)."""
    print(f"note: {text}", file=sys.stderr)


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


@contextlib.contextmanager
def store_errors(path):
    """Turn a store that cannot be read (damage found late: ``PATH: damaged run store``)
    into a UsageError; a server gone away is left to say so itself (transient). ``path``
    is the store as given: the store's own message names it already."""
    from daq.store import StoreError, StoreUnavailable

    del path

    try:
        yield
    except StoreUnavailable:
        raise
    except StoreError as e:
        raise UsageError(str(e)) from None


#: the ``--db`` help of every command that reads or writes a run store
DB_HELP = ("run store: a SQLite file or a PostgreSQL URL postgresql://user@host[:port]/db "
           "(password from PGPASSWORD or ~/.pgpass)")


def open_store(address, synchronous: str = "FULL", *, read_only: bool = False):
    """An existing run store (a file or a ``postgresql://`` URL); a missing or unreadable
    store, or a server that cannot be reached, is a UsageError (never create an empty
    store for a mistyped address). ``read_only``: for commands that only read (no WAL
    switch, no upgrade written, works on a read-only file)."""
    from daq.store import StoreError
    from daq.store import open_store as open_run_store

    try:
        return open_run_store(address, create=False, read_only=read_only,
                              synchronous=synchronous)
    except (StoreError, OSError) as e:
        raise UsageError(str(e)) from None
