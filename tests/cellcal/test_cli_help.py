"""The command line's help and start-up: every command and option says what it is, choices
are listed, the parser's constants agree with the core's, building the parser imports no
heavy library."""

from __future__ import annotations

import argparse
import subprocess
import sys

import pytest

from calibration.version import software_version
from cellcal.cli import build_parser, main
from tests.daq.capture_helpers import ROOT


def _parsers(parser: argparse.ArgumentParser, path=("cellcal",)):
    """(command path, parser) for the parser and every sub-command, depth first."""
    yield path, parser
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            for name, sub in action.choices.items():
                yield from _parsers(sub, (*path, name))


def test_every_command_and_option_has_help_and_no_rst_markup():
    for path, p in _parsers(build_parser()):
        name = " ".join(path)
        assert p.description and len(p.description) > 20, f"{name}: no description"
        assert "``" not in (p.description or "") + (p.epilog or ""), f"{name}: RST markup"
        for action in p._actions:
            if isinstance(action, argparse._SubParsersAction):
                for choice in action._choices_actions:
                    assert choice.help, f"{name} {choice.dest}: no help"
                continue
            if action.help == argparse.SUPPRESS:
                continue
            label = "/".join(action.option_strings) or action.dest
            assert action.help and "``" not in action.help, f"{name} {label}: no help"


def test_choices_are_listed_in_the_help():
    help_text = {" ".join(path): p.format_help() for path, p in _parsers(build_parser())}
    for cmd in ("cellcal calibrate", "cellcal diagnose", "cellcal report"):
        assert "{lm,ridge,besa,sa,besa+lm}" not in help_text[cmd]  # a readable metavar...
        for solver in ("lm", "ridge", "besa", "sa", "besa+lm"):  # ...and each one described
            assert f"{solver}:" in " ".join(help_text[cmd].split()), (cmd, solver)


def test_routine_options_are_the_routines_own():
    help_text = {" ".join(path): p.format_help() for path, p in _parsers(build_parser())}
    assert "--zero-tol-mm" in help_text["cellcal capture zero20"]
    for routine in ("frame", "steps", "poses", "iso9283"):
        assert "--zero-" not in help_text[f"cellcal capture {routine}"], routine


def test_parser_constants_agree_with_the_core():
    from calibration import DEFAULT_EFFECTS
    from calibration.diagnosis.history import DEFAULT_SIGMA
    from calibration.fit.outliers import MODES as OUTLIER_MODES
    from calibration.fit.solvers import SOLVERS
    from calibration.zero_point import DEFAULT_SIGMA_MM
    from cellcal.commands import history, sim_serve, zero
    from cellcal.flags import choices
    from cellcal.flags.routine_args import ROUTINE_ARGS
    from daq.routines import ROUTINES, get
    from sim_drivers.serve import ABB_PORT, DEFAULT_PORTS

    assert choices.DEFAULT_EFFECTS == DEFAULT_EFFECTS
    assert list(choices.SOLVERS) == list(SOLVERS)
    assert choices.OUTLIER_MODES == OUTLIER_MODES
    assert zero.DEFAULT_SIGMA_MM == DEFAULT_SIGMA_MM
    assert history.DEFAULT_SIGMA == DEFAULT_SIGMA
    assert sim_serve.DEFAULT_PORTS == DEFAULT_PORTS
    assert sim_serve.ABB_PORT == ABB_PORT
    from cellcal.usecases.demo import DEMO_ROBOTS

    assert tuple(DEMO_ROBOTS) == choices.DEMO_ROBOTS
    assert list(ROUTINE_ARGS) == list(ROUTINES)
    for name, spec in ROUTINE_ARGS.items():  # the summary is the routine's docstring's
        first = get(name).__doc__.strip().splitlines()[0]
        assert first == f"``{name}``: {spec.summary}", name


def test_bare_commands_print_help_and_version(capsys):
    assert main([]) == 0
    out = capsys.readouterr().out
    assert out.startswith("usage: cellcal") and "calibrate" in out and "compensate" in out
    assert main(["sim"]) == 0 and "serve" in capsys.readouterr().out
    assert main(["capture"]) == 0 and "zero20" in capsys.readouterr().out
    with pytest.raises(SystemExit) as e:
        main(["--version"])
    assert e.value.code == 0
    assert capsys.readouterr().out.strip() == software_version()
    assert software_version().startswith("cellcal 0.")


def test_building_the_parser_imports_no_heavy_library():
    code = ("import sys; from cellcal.cli import build_parser; build_parser(); "
            "print(sorted(m for m in ('numpy', 'scipy', 'matplotlib', 'pydantic', "
            "'calibration', 'presentation', 'drivers', 'sim_drivers') if m in sys.modules))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         cwd=ROOT, check=True)
    assert out.stdout.strip() == "[]"


def test_argument_errors_exit_2_before_any_heavy_import():
    code = ("import sys; from cellcal.cli import main\ntry:\n    main(['calibrate'])\n"
            "except SystemExit as e:\n    print(e.code, 'numpy' in sys.modules)")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         cwd=ROOT, check=True)
    assert out.stdout.split() == ["2", "False"]
    assert "required: DATA.csv" in out.stderr


def test_calibrate_loads_no_scipy_and_no_device_protocols(tmp_path):
    # scipy's import alone is half of a default `cellcal calibrate` (issue 30): the default
    # fit (geometric,base,tool, lm, the blunder test) runs on numpy; it opens no device
    csv = tmp_path / "p.csv"
    assert main(["simulate", "--model", "ur10e", "--poses", "40", "--valid", "0",
                 "--seed", "1", "--out", str(csv)]) == 0
    code = ("import sys; from cellcal.cli import main\n"
            f"rc = main(['calibrate', '--model', 'ur10e', {str(csv)!r}])\n"
            "print(rc, sorted(m for m in ('scipy', 'matplotlib', 'drivers.protocols', "
            "'sim_drivers', 'daq') if m in sys.modules), file=sys.stderr)")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         cwd=ROOT, check=True)
    assert out.stderr.split("\n")[-2] == "0 []", out.stderr
