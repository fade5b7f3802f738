"""A flag's default is declared twice and the two must agree: by the parser (argparse,
``register`` of :mod:`cellcal.commands`, built without pydantic so ``--help`` stays fast)
and by the typed request the command builds (:mod:`cellcal.usecases`, fields whose alias
is the flag). A request keeps its defaults: it is also built from a parser that lacks some
of its flags (``validate`` builds :class:`~cellcal.usecases.capture.CaptureArgs`).

Walks every sub-command's parser: each field of its requests whose flag the parser has is
read from the attribute of the field's name (``Request.from_args``) and defaults to the
same value. Likewise a capture routine's flags and its ``make_plan`` keyword defaults, and
the numbers the help texts give as ``(default N``.
"""

from __future__ import annotations

import argparse
import importlib
import inspect
import re

import pytest

from cellcal.cli import build_parser
from cellcal.flags.routine_args import ROUTINE_ARGS

#: the typed requests each sub-command builds (``module:Class`` of cellcal.usecases); a
#: command group (``capture``) covers its sub-commands
REQUESTS = {
    "demo": ["demo:DemoRequest"],
    "capture": ["capture:CaptureArgs"],
    "runs": ["runs:RunsRequest"],
    "resume": ["resume:ResumeArgs"],
    "export": ["export_run:ExportRequest"],
    "calibrate": ["calibrate:CalibrateRequest"],
    "check": ["check:CheckRequest"],
    "history": ["history:HistoryRequest"],
    "diagnose": ["diagnose:DiagnoseRequest"],
    "models": [],  # no request: it lists the built-in models
    "sim serve": ["sim_serve:SimServeRequest"],
    "simulate": ["simulate:SimulateRequest"],
    "zero": ["zero:ZeroRequest"],
    "report": ["report:ReportRequest"],
    "compensate": ["compensate:CompensateRequest", "compensate_program:ProgramRequest"],
    "validate": ["validate:ValidateRequest", "capture:CaptureArgs"],
}

#: (routine, make_plan keyword): why the command line's default differs from the keyword's
ROUTINE_EXCEPTIONS = {
    ("validate", "variants"): "`cellcal validate` runs every variant by default (the DH "
    "table's too); make_plan's keyword default, for callers in Python, runs two",
}


def leaves(parser: argparse.ArgumentParser, path: tuple[str, ...] = ()):
    """(command words, parser) of every sub-command that runs something."""
    groups = [a for a in parser._actions if isinstance(a, argparse._SubParsersAction)]
    if not groups:
        yield " ".join(path), parser
    for group in groups:
        for name, sub in group.choices.items():
            yield from leaves(sub, (*path, name))


COMMANDS = dict(leaves(build_parser()))


def requests_of(command: str) -> list[type]:
    key = command if command in REQUESTS else command.split()[0]
    out = []
    for spec in REQUESTS[key]:
        module, cls = spec.split(":")
        out.append(getattr(importlib.import_module(f"cellcal.usecases.{module}"), cls))
    return out


def flags(parser: argparse.ArgumentParser) -> dict[str, argparse.Action]:
    """The parser's actions by option string (a positional by its metavar)."""
    out = {}
    for action in parser._actions:
        for name in action.option_strings or [action.metavar or action.dest]:
            out[name] = action
    return out


def same(a, b) -> bool:
    """Equal defaults, a list and a tuple of the same items alike."""
    if isinstance(a, list | tuple) and isinstance(b, list | tuple):
        return len(a) == len(b) and all(same(x, y) for x, y in zip(a, b, strict=True))
    return type(a) is type(b) and a == b or (
        isinstance(a, int | float) and isinstance(b, int | float)
        and not isinstance(a, bool) and not isinstance(b, bool) and a == b)


def test_every_command_is_mapped():
    groups = {c if c in REQUESTS else c.split()[0] for c in COMMANDS}
    assert groups == set(REQUESTS)
    assert len(COMMANDS) > len(REQUESTS)  # capture's routines, sim serve


@pytest.mark.parametrize("command", sorted(COMMANDS))
def test_parser_and_request_defaults_agree(command):
    parser = COMMANDS[command]
    actions = flags(parser)
    wrong = []
    compared = 0
    for request in requests_of(command):
        for name, field in request.model_fields.items():
            action = actions.get(field.alias or "")
            if action is None:  # not a flag of this command: the request's default applies
                continue
            where = f"{command} {field.alias} ({request.__name__}.{name})"
            if action.dest != name:  # from_args reads the attribute of the field's name
                wrong.append(f"{where}: the parser stores it as {action.dest!r}")
                continue
            if field.is_required():
                continue
            compared += 1
            given = parser.get_default(action.dest)
            default = field.get_default(call_default_factory=True)
            if not same(given, default):
                wrong.append(f"{where}: parser default {given!r}, request default {default!r}")
    assert not wrong, "\n".join(wrong)
    assert compared or not requests_of(command)


def _routine_parser(routine: str) -> argparse.ArgumentParser:
    spec = ROUTINE_ARGS[routine]
    return COMMANDS[spec.command] if spec.command else COMMANDS[f"capture {routine}"]


def _defaults(parser: argparse.ArgumentParser, **given) -> argparse.Namespace:
    """The namespace of a command line that gives no flag but ``given``."""
    values = {a.dest: parser.get_default(a.dest) for a in parser._actions
              if a.dest != argparse.SUPPRESS}
    return argparse.Namespace(**{**values, **given})


#: the flags a routine needs to make its parameters at all (left out of the comparison)
_REQUIRED = {"zero20": {"target_xyz": "1000,0,500"}}


@pytest.mark.parametrize("routine", sorted(ROUTINE_ARGS))
def test_routine_flags_and_make_plan_defaults_agree(routine):
    """What the command line passes to the routine's ``make_plan`` when no flag is given
    is the keyword's own default."""
    parser = _routine_parser(routine)
    given = _REQUIRED.get(routine, {})
    params = ROUTINE_ARGS[routine].params(_defaults(parser, **given))
    keywords = inspect.signature(
        importlib.import_module(f"daq.routines.{routine}").make_plan).parameters
    wrong = []
    for key, value in params.items():
        keyword = keywords.get(key)
        if key in given or (routine, key) in ROUTINE_EXCEPTIONS:
            continue
        if keyword is None:
            wrong.append(f"{routine}: {key} is no keyword of make_plan")
        elif keyword.default is inspect.Parameter.empty:
            continue  # required by make_plan: the command line always gives it
        elif not same(value, keyword.default):
            wrong.append(f"{routine} {key}: the command line passes {value!r}, make_plan's "
                         f"default is {keyword.default!r}")
    assert not wrong, "\n".join(wrong)


def test_routine_exceptions_still_differ():
    """An exception above that no longer differs is removed."""
    for routine, key in ROUTINE_EXCEPTIONS:
        args = _defaults(_routine_parser(routine), **_REQUIRED.get(routine, {}))
        value = ROUTINE_ARGS[routine].params(args)[key]
        keyword = inspect.signature(
            importlib.import_module(f"daq.routines.{routine}").make_plan).parameters[key]
        assert not same(value, keyword.default), (routine, key)


#: ``(default 12``, ``(default: 0.5;``: a number the help text gives as the default
_HELP_DEFAULT = re.compile(r"\(default:? (-?\d+(?:\.\d+)?)(?=[\s;),:]|$)")


@pytest.mark.parametrize("command", sorted(COMMANDS))
def test_help_texts_say_the_parser_defaults(command):
    """A help text that names a number as the default of a flag with a default names the
    parser's (a flag whose default is None takes it from the layer below: not compared)."""
    parser = COMMANDS[command]
    wrong = []
    for action in parser._actions:
        said = _HELP_DEFAULT.search(action.help or "")
        default = parser.get_default(action.dest)
        if said is None or default is None or isinstance(default, bool | str | list):
            continue
        if float(said.group(1)) != default:
            wrong.append(f"{command} {action.option_strings}: help says {said.group(1)}, "
                         f"the parser's default is {default!r}")
    assert not wrong, "\n".join(wrong)
