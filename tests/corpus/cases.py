"""The corpus table: every CLI command over bad inputs, with the documented outcome (a
long module because it is one table: the inputs of each command and what must come of them).

A :class:`Case` is one command line run in a fresh copy of the workspace
(:mod:`tests.corpus.workspace`) after its ``setup`` wrote the bad input
(:mod:`tests.corpus.inputs`). :func:`run_case` runs it (in-process through
``cellcal.cli.main``, or as a subprocess where the input could hang or the process state
matters) and :func:`judge` names what went wrong, if anything:

``traceback``  an exception escaped (or a subprocess printed a traceback / hung)
``accepted``   the command ran on input it should refuse (exit 0 or 1)
``loss``       an input file changed or vanished, or a refused command left files behind
``code``       another exit code than documented
``message``    the right code, but the message does not name the problem

Exit codes (docs/formats.md §6): 0 done, 2 bad input, 3 data too poor.
"""

from __future__ import annotations

import contextlib
import hashlib
import io
import json
import os
import re
import stat
import subprocess
import sys
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

from . import inputs as I  # noqa: N812

ROOT = Path(__file__).resolve().parents[2]
Setup = Callable[[Path], None]


@dataclass
class Case:
    """One command line over one input and what must come of it."""

    command: str
    name: str
    argv: list[str]
    rc: int
    msg: str = ""                      # regex (case-insensitive) the output must match
    setup: list[Setup] = field(default_factory=list)
    creates: tuple[str, ...] = ()       # files the command may write
    forbid: tuple[str, ...] = ("PWNED",)  # files that must not appear
    mode: str = "inproc"                # or "subprocess"
    slow: bool = False
    unprivileged: bool = False          # subprocess that may not override file permissions
    stdout_closed: bool = False         # subprocess whose stdout pipe has no reader
    stores: bool = False                # a non-zero exit that still writes ``creates`` (a
                                        # capture stored that ended incomplete)

    @property
    def id(self) -> str:
        return f"{self.command}/{self.name}"


@dataclass
class Outcome:
    rc: int | None
    out: str
    err: str
    exception: str | None = None
    hung: bool = False


# ------------------------------------------------------------------------ setups
def write(name: str, make) -> Setup:
    """Setup: write ``make(ws)`` (text or bytes) to ``name``."""
    def go(ws: Path) -> None:
        data = make(ws) if callable(make) else make
        p = ws / name
        p.parent.mkdir(parents=True, exist_ok=True)
        p.write_bytes(data if isinstance(data, bytes) else data.encode("utf-8"))
    return go


def mkdir(name: str) -> Setup:
    return lambda ws: (ws / name).mkdir(parents=True, exist_ok=True)


def chmod_ro(name: str) -> Setup:
    def go(ws):
        p = ws / name
        p.chmod(stat.S_IRUSR | stat.S_IRGRP | stat.S_IROTH)
    return go


def store(name: str, variant: str) -> Setup:
    maker = I.store_variants()[variant]
    return lambda ws: maker(ws, name)


def fifo(name: str) -> Setup:
    return lambda ws: I.fifo(ws, name)


def copy(src: str, dst: str) -> Setup:
    return lambda ws: (ws / dst).write_bytes((ws / src).read_bytes())


# ------------------------------------------------------------------ expectations
MISSING = r"no such|does not exist|not found"
DIRECTORY = r"directory|not a (regular )?file"
NO_FOLDER = r"no such (directory|folder|file)|does not exist|folder"
NOT_NUMBER = r"not a (finite )?number|finite|nan|inf"
NOT_TEXT = r"utf-8|not a text file|binary|encoding"
IS_INPUT = r"input|would overwrite|same file"
IS_STORE = r"run store|database"
TOO_POOR = r"pose|observation|radian|calibration rows|parameter"
NOT_STORE = r"not a (cellcal )?run store|not an sqlite|damaged|malformed|not a database"
BAD_FILE_CSV = {
    "empty": (2, r"empty|no header"), "blank": (2, r"empty|no header"),
    "comments_only": (2, r"no header|empty"), "header_only": (2, r"no data rows|no rows"),
    "no_x": (2, r"missing.*column"), "no_q3": (2, r"missing.*q3|q3"),
    "dup_col": (2, r"duplicated column"),
    "nan": (2, NOT_NUMBER), "inf": (2, NOT_NUMBER), "neg_inf": (2, NOT_NUMBER),
    "overflow": (2, NOT_NUMBER), "text_value": (2, NOT_NUMBER), "empty_value": (2, r"empty"),
    "hex_value": (2, NOT_NUMBER), "short_row": (2, r"fields"), "long_row": (2, r"fields"),
    "semicolons": (2, r"semicolon|';'"), "tabs": (2, r"tab"),
    "binary": (2, NOT_TEXT), "latin1": (2, NOT_TEXT), "nul": (2, r"nul|binary|utf-8"),
    "huge_field": (2, r"field|too long|characters"), "dup_id": (2, r"already used|duplicat"),
    "utf16": (2, NOT_TEXT), "huge_xyz": (2, r"plausible|too large|out of range|outside"),
    "ok_bom": (0, ""), "ok_crlf": (0, ""),
    "one_pose": (3, TOO_POOR), "five_poses": (3, TOO_POOR), "eight_poses": (3, TOO_POOR),
    "identical_100": (3, r"identical|distinct"), "radians": (3, r"radian"),
    "all_valid": (3, r"calibration (rows|poses)|set=valid"),
    "out_of_limits": (2, r"limits"), "bad_set": (2, r"calib.*valid"),
    "sigma_neg": (2, r"sigma_mm.*positive|positive"), "sigma_nan": (2, NOT_NUMBER),
    "payload_neg": (2, r"payload_kg"), "temp_absurd": (2, r"temp_c"),
    "meta_sigma_text": (2, r"tracker_sigma_mm"), "meta_sigma_neg": (2, r"tracker_sigma_mm"),
    "bad_dir": (2, r"dir3"), "half_dirs": (2, r"dir"), "cmd_partial": (2, r"cmd_"),
    "ok_extra_col": (0, ""),
}
PARAMS = {
    "empty": (2, r"empty|not valid json"), "not_json": (2, r"json"),
    "truncated": (2, r"json"), "array": (2, r"params|format|object"),
    "wrong_format": (2, r"format|not a cellcal params"), "future_version": (2, r"version"),
    "nan_value": (2, NOT_NUMBER), "inf_value": (2, NOT_NUMBER),
    "huge_value": (2, r"plausible|too large|value"), "string_value": (2, r"value|number"),
    "null_value": (2, r"value"), "bool_value": (2, r"value|number"),
    "missing_value": (2, r"value|missing"), "neg_std": (2, r"std"),
    "no_parameters": (2, r"parameters"), "null_parameters": (2, r"parameters"),
    "no_model_definition": (2, r"model_definition"), "no_effects": (2, r"effects"),
    "unknown_effect": (2, r"nosuch|unknown effect"), "missing_row": (2, r"missing"),
    "unknown_row": (2, r"unknown parameter|geometric.j9"), "wrong_unit": (2, r"unit"),
    "model_nan": (2, r"model_definition|finite|nan"),
    "model_tampered": (2, r"model|hash|definition"),
    "other_model": (2, r"model|ur10e"), "binary": (2, NOT_TEXT + r"|json"),
    "latin1": (2, NOT_TEXT + r"|json"),
    "evil_effect_path": (2, r"effect.file|evil"), "evil_effect_abs": (2, r"effect.file|evil"),
    "evil_effect_record": (2, r"effect.file|evil"),
    "ok_v1": (0, ""),
}
MODEL = {
    "empty": (2, r"empty|mapping"), "list": (2, r"mapping"), "scalar": (2, r"mapping"),
    "syntax": (2, r"yaml"), "nan": (2, r"finite|nan"), "inf": (2, r"finite|inf"),
    "huge": (2, r"plausible|large|magnitude|between"), "bool_min": (2, r"min"),
    "string_a": (2, r"a:|number"), "min_gt_max": (2, r"min.*max"), "no_joints": (2, r"joints"),
    "zero_joints": (2, r"joints"), "unknown_field": (2, r"colour|unknown field"),
    "bad_convention": (2, r"convention"), "neg_payload": (2, r"mass_kg|payload"),
    "nan_tool": (2, r"tool"), "huge_gravity": (2, r"gravity"),
    "non_utf8": (2, NOT_TEXT), "binary": (2, NOT_TEXT + r"|yaml|mapping"),
    "dup_key": (2, r"duplicate|twice|name"),
}
STORE = {
    "text": (2, NOT_STORE), "binary": (2, NOT_STORE), "csv": (2, NOT_STORE),
    "empty": (2, NOT_STORE + r"|empty"), "truncated": (2, NOT_STORE + r"|truncated"),
    "zeroed": (2, NOT_STORE), "header_only": (2, NOT_STORE + r"|truncated"),
    "foreign": (2, r"not a cellcal run store|invoices"),
    "versioned_foreign": (2, r"not a cellcal run store"),
    "runs_no_version": (2, r"not a cellcal run store|no schema version"),
    "newer": (2, r"newer"),
}
REGISTER_MAP = {
    "not_mapping": r"mapping", "syntax": r"yaml|expected", "unknown_field": r"comand",
    "negative": r"command", "string": r"speed", "overlap": r"overlap", "bits": r"busy",
    "word_order": r"word_order", "binary": NOT_TEXT + r"|yaml|mapping", "n_joints": r"n_joints",
}
CELL = {
    "empty_list": r"mapping", "syntax": r"yaml", "unknown_key": r"trackre|unknown",
    "zero_axis": r"axis", "unknown_reflector": r"reflector|bogus",
    "nan_position": r"position|finite|nan", "two_shapes": r"shape|box|cylinder",
    "dup_key": r"twice", "binary": NOT_TEXT + r"|yaml|mapping", "latin1": NOT_TEXT,
}
EFFECT_FILE = {
    "syntax": r"syntax|could not load", "raises": r"boom|could not load",
    "no_effect": r"no effect|defines no", "replaces_builtin": r"built-in|geometric",
    "bad_family": r"family", "binary": r"could not load|utf-8|not a text|null bytes|source",
}


def _file_cases(command, argv, slot, variants, table, *, src=None, skip=(), slow_ok=False,
                extra_setup=(), creates=()):
    """Cases putting each file variant into ``argv`` at the placeholder ``slot``."""
    out = []
    for name, make in variants.items():
        if name in skip or name not in table:
            continue
        rc, msg = table[name]
        fname = f"x_{name}{Path(src or 'f').suffix or '.txt'}"
        args = [fname if a == slot else a for a in argv]
        expect = msg
        if rc == 2 and not name.startswith("ok_"):
            expect = f"(?=.*{re.escape(fname)})(?=.*(?:{msg}))" if msg else re.escape(fname)
        out.append(Case(command, f"{slot.strip('{}')}:{name}", args, rc, expect,
                        [*extra_setup, write(fname, make)], creates=creates,
                        slow=slow_ok and rc == 0))
    return out


def _path_cases(command, argv, slot, good, *, creates=(), slow_ok=False):
    """Missing file, missing folder, a directory, a read-only good file, a unicode name."""
    def sub(p):
        return [p if a == slot else a for a in argv]
    uni = "mein ordner ü/" + Path(good).name
    return [
        Case(command, f"{slot.strip('{}')}:missing", sub("missing" + Path(good).suffix), 2,
             f"(?=.*missing)(?=.*(?:{MISSING}))", creates=creates),
        Case(command, f"{slot.strip('{}')}:missing_folder", sub("nofolder/x" + Path(good).suffix),
             2, MISSING, creates=creates),
        Case(command, f"{slot.strip('{}')}:directory", sub("adir" + Path(good).suffix), 2,
             DIRECTORY, [mkdir("adir" + Path(good).suffix)], creates=creates),
        Case(command, f"{slot.strip('{}')}:ok_readonly", sub(good), 0, "", [chmod_ro(good)],
             creates=creates, slow=slow_ok),
        Case(command, f"{slot.strip('{}')}:ok_unicode_path", sub(uni), 0, "",
             [write(uni, lambda ws, g=good: (ws / g).read_bytes())], creates=creates,
             slow=slow_ok),
    ]


def _special_file_cases(command, argv, slot):
    """/dev/zero and a FIFO as the input: in a subprocess (they could hang)."""
    def sub(p):
        return [p if a == slot else a for a in argv]
    return [
        Case(command, f"{slot.strip('{}')}:dev_zero", sub("/dev/zero"), 2,
             r"not a regular file|device|directory", mode="subprocess", slow=True),
        Case(command, f"{slot.strip('{}')}:fifo", sub("afifo.csv"), 2,
             r"not a regular file|fifo|pipe", [fifo("afifo.csv")], mode="subprocess",
             slow=True),
    ]


def _number_cases(command, argv, options, creates=()):
    """``options``: (flag, [bad values]) pairs; each is appended to ``argv``."""
    out = []
    for flag, values in options:
        for v in values:
            out.append(Case(command, f"num:{flag}={v}", [*argv, flag, v], 2,
                            re.escape(flag.lstrip("-").split("-")[0]), creates=creates))
    return out


def _out_cases(command, argv, outs, creates=()):
    """``outs``: (name, extra argv, regex); all must be refused with exit 2."""
    return [Case(command, f"out:{name}", [*argv, *extra], 2, msg, creates=creates,
                 setup=setup)
            for name, extra, msg, *rest in outs for setup in [rest[0] if rest else []]]


# ----------------------------------------------------------------------- the table
def build_cases() -> list[Case]:
    csv_m = I.csv_variants("good.csv", measurement=True)
    csv_t = I.csv_variants("targets.csv", measurement=False)
    params_v = I.params_variants()
    model_v = I.model_variants()
    cases: list[Case] = []

    # ---- calibrate / diagnose / report: the measurement CSV
    base = {
        "calibrate": ["calibrate", "{DATA}", "--model", "ur5", "--out", "out.json"],
        "diagnose": ["diagnose", "{DATA}", "--model", "ur5"],
        "report": ["report", "{DATA}", "--model", "ur5", "--out", "out.html"],
    }
    creates = {"calibrate": ("out.json",), "diagnose": (), "report": ("out.html",)}
    for cmd, argv in base.items():
        slow = cmd in ("report", "diagnose")
        cases += _file_cases(cmd, argv, "{DATA}", csv_m, BAD_FILE_CSV, src="good.csv",
                             creates=creates[cmd], slow_ok=slow)
        cases += _path_cases(cmd, argv, "{DATA}", "good.csv", creates=creates[cmd],
                             slow_ok=slow)
        cases += _special_file_cases(cmd, argv, "{DATA}")
        # the model YAML
        margv = [a if a != "ur5" else "{MODEL}" for a in argv]
        margv = [a if a != "{DATA}" else "good.csv" for a in margv]
        cases += _file_cases(cmd, margv, "{MODEL}", model_v, MODEL | {"seven_joints": (
            2, r"q7|joints")}, src="model.yaml", creates=creates[cmd])
        cases += _path_cases(cmd, margv, "{MODEL}", "model.yaml", creates=creates[cmd],
                             slow_ok=slow)[:3]
        # params.json as the current model / start
        pargv = [a if a != "{DATA}" else "good.csv" for a in argv] + ["--params", "{PARAMS}"]
        cases += _file_cases(cmd, pargv, "{PARAMS}", params_v, PARAMS, src="params.json",
                             creates=creates[cmd], slow_ok=slow)
        cases += _path_cases(cmd, pargv, "{PARAMS}", "params.json", creates=creates[cmd],
                             slow_ok=slow)[:3]
        # effect files
        eargv = [a if a != "{DATA}" else "good.csv" for a in argv] + ["--effect-file",
                                                                        "{EFFECT}"]
        for name, body in I.effect_file_variants().items():
            fname = f"e_{name}.py"
            cases.append(Case(cmd, f"effect_file:{name}",
                              [fname if a == "{EFFECT}" else a for a in eargv], 2,
                              EFFECT_FILE[name], [write(fname, body)], creates=creates[cmd]))
        cases += _path_cases(cmd, eargv, "{EFFECT}", "effect.py", creates=creates[cmd])[:3]
        good = [a if a != "{DATA}" else "good.csv" for a in argv]
        cases += _number_cases(cmd, good, [
            ("--sigma", ["nan", "-1", "0", "inf", "abc"]),
            ("--solver", ["bogus"]),
            ("--effects", ["bogus", "", "geometric,geometric", "compliance:9"]),
        ], creates=creates[cmd])

    good_cal = ["calibrate", "good.csv", "--model", "ur5"]
    cases += _number_cases("calibrate", good_cal, [
        ("--seed", ["-1", str(2**70)]), ("--monte-carlo", ["1", "-3"]),
    ])
    cases += _file_cases("calibrate", good_cal + ["--valid", "{VALID}"], "{VALID}",
                         {k: csv_m[k] for k in ("empty", "nan", "binary", "no_q3", "huge_field",
                                                 "semicolons")},
                         BAD_FILE_CSV, src="good.csv")
    cases += _out_cases("calibrate", good_cal, [
        ("is_data", ["--out", "good.csv"], IS_INPUT),
        ("is_params", ["--params", "params.json", "--out", "params.json"], IS_INPUT),
        ("is_valid", ["--valid", "ur10e.csv", "--out", "ur10e.csv"], IS_INPUT),
        ("is_model", ["--model", "model.yaml", "--out", "model.yaml"], IS_INPUT),
        ("is_effect", ["--effect-file", "effect.py", "--out", "effect.py"], IS_INPUT),
        ("is_store", ["--out", "cell.db"], IS_STORE),
        ("directory", ["--out", "adir"], DIRECTORY, [mkdir("adir")]),
        ("no_folder", ["--out", "nofolder/p.json"], NO_FOLDER),
        ("ridge_plot_is_data", ["--solver", "ridge", "--ridge-plot", "good.csv"], IS_INPUT),
        ("same_out_twice", ["--solver", "ridge", "--out", "o.json", "--ridge-plot", "o.json"],
         r"twice|same|both"),
    ])
    good_diag = ["diagnose", "good.csv", "--model", "ur5"]
    cases += _number_cases("diagnose", good_diag, [("--top", ["0", "-1"])])
    good_rep = ["report", "good.csv", "--model", "ur5"]
    cases += _out_cases("report", good_rep, [
        ("is_data", ["--out", "good.csv"], IS_INPUT),
        ("is_params", ["--params", "params.json", "--out", "params.json"], IS_INPUT),
        ("is_model", ["--model", "model.yaml", "--out", "model.yaml"], IS_INPUT),
        ("is_store", ["--out", "cell.db"], IS_STORE),
        ("directory", ["--out", "adir"], DIRECTORY, [mkdir("adir")]),
        ("no_folder", ["--out", "nofolder/r.html"], NO_FOLDER),
    ])
    cases.append(Case("calibrate", "out:ok_dev_null",
                      [*good_cal, "--out", "/dev/null"], 0, ""))

    # ---- compensate
    comp = ["compensate", "{TARGETS}", "--params", "params.json", "--out", "comp.csv"]
    cases += _file_cases("compensate", comp, "{TARGETS}", csv_t, BAD_FILE_CSV,
                         src="targets.csv", creates=("comp.csv",))
    cases += _path_cases("compensate", comp, "{TARGETS}", "targets.csv", creates=("comp.csv",))
    cases += _special_file_cases("compensate", comp, "{TARGETS}")
    pcomp = ["compensate", "targets.csv", "--params", "{PARAMS}", "--out", "comp.csv"]
    cases += _file_cases("compensate", pcomp, "{PARAMS}", params_v, PARAMS, src="params.json",
                         skip=("other_model",), creates=("comp.csv",))
    cases += _path_cases("compensate", pcomp, "{PARAMS}", "params.json",
                         creates=("comp.csv",))[:3]
    gcomp = ["compensate", "targets.csv", "--params", "params.json"]
    cases += _thermal_compensate_cases()
    cases += _envelope_cases()
    cases += _number_cases("compensate", gcomp, [
        ("--start", ["nan,0,0,0,0,0", "1,2,3", "a,b,c,d,e,f", "1e400,0,0,0,0,0"])])
    cases += _out_cases("compensate", gcomp, [
        ("is_targets", ["--out", "targets.csv"], IS_INPUT),
        ("is_params", ["--out", "params.json"], IS_INPUT),
        ("model_is_params", ["--export-model", "params.json"], IS_INPUT),
        ("ur_is_targets", ["--export-ur", "targets.csv"], IS_INPUT),
        ("is_store", ["--out", "cell.db"], IS_STORE),
        ("model_is_store", ["--export-model", "cell.db"], IS_STORE),
        ("directory", ["--out", "adir"], DIRECTORY, [mkdir("adir")]),
        ("no_folder", ["--export-model", "nofolder/m.yaml"], NO_FOLDER),
        ("same_out_twice", ["--out", "o.csv", "--export-model", "o.csv"], r"twice|same|both"),
    ])
    cases += _out_cases("compensate", gcomp, [
        ("urdf_is_params", ["--export-urdf", "params.json"], IS_INPUT),
        ("ur_yaml_is_targets", ["--export-ur-yaml", "targets.csv"], IS_INPUT),
        ("dh_is_store", ["--export-dh", "cell.db"], IS_STORE),
        ("urdf_no_folder", ["--export-urdf", "nofolder/c.urdf"], NO_FOLDER),
        ("dh_directory", ["--export-dh", "adir"], DIRECTORY, [mkdir("adir")]),
        ("urdf_and_dh_same", ["--export-urdf", "o.x", "--export-dh", "o.x"],
         r"twice|same|both"),
    ])
    # ---- the automatic diagnosis: its numbers and its params.json output
    auto = ["diagnose", "good.csv", "--model", "ur5", "--auto"]
    cases += _number_cases("diagnose", auto, [
        ("--max-steps", ["0", "-1", "x"]), ("--budget-s", ["nan", "-1", "0"])])
    cases += _out_cases("diagnose", auto, [
        ("auto_is_data", ["--out", "good.csv"], IS_INPUT),
        ("auto_is_params", ["--params", "params.json", "--out", "params.json"], IS_INPUT),
        ("auto_is_store", ["--out", "cell.db"], IS_STORE),
        ("auto_no_folder", ["--out", "nofolder/p.json"], NO_FOLDER),
    ])
    cases += _number_cases("report", ["report", "good.csv", "--model", "ur5", "--auto",
                                      "--out", "r.html"],
                           [("--max-steps", ["0"]), ("--budget-s", ["nan", "-1"])])
    # a params.json recording a user effect: loading it needs --effect-file, same hash
    cases += _effect_record_cases()
    cases += _check_cases(csv_m, params_v, model_v)
    cases += _issue36_cases()

    # ---- zero: postures CSV, model, params, replay, store
    post_v = I.csv_variants("postures.csv", measurement=False, cols=("q4", "q2", "q3"))
    post_v |= {
        "bad_plane": lambda ws: I.Table((ws / "postures.csv").read_text()).set(2, "plane", "7")
        .text(),
        "no_plane": lambda ws: I.Table((ws / "postures.csv").read_text()).drop("plane").text(),
    }
    post_tab = BAD_FILE_CSV | {"bad_plane": (2, r"plane"), "no_plane": (2, r"plane"),
                               "no_x": (2, r"missing.*q4"), "huge_xyz": (2, r"limits")}
    zero = ["zero", "{POST}", "--model", "ur10e"]
    cases += _file_cases("zero", zero, "{POST}", post_v, post_tab, src="postures.csv")
    cases += _path_cases("zero", zero, "{POST}", "postures.csv")
    cases += _special_file_cases("zero", zero, "{POST}")
    # (the ur5 params with the ur10e postures read as ur5: a bad params file is refused first)
    zp = ["zero", "postures.csv", "--model", "ur5", "--params", "{PARAMS}"]
    cases += _file_cases("zero", zp, "{PARAMS}", params_v, PARAMS, src="params.json",
                         skip=("ok_v1",))
    zm = ["zero", "postures.csv", "--model", "{MODEL}"]
    cases += _file_cases("zero", zm, "{MODEL}", model_v, MODEL | {"seven_joints": (
        2, r"q7|joints")}, src="model.yaml")
    zr = ["zero", "postures.csv", "--model", "ur10e", "--replay", "{REPLAY}"]
    replay_v = {
        "empty": lambda ws: b"", "not_json": lambda ws: "offsets: 1\n",
        "array": lambda ws: "[1,2]\n", "no_offsets": lambda ws: '{"status": "ok"}\n',
        "nan": lambda ws: '{"offsets_deg": [NaN, 0, 0, 0, 0, 0]}\n',
        "strings": lambda ws: '{"offsets_deg": ["a", 0, 0, 0, 0, 0]}\n',
        "short": lambda ws: '{"offsets_deg": [0, 0]}\n',
        "nested": lambda ws: '{"offsets_deg": [[0], 0, 0, 0, 0, 0]}\n',
        "binary": lambda ws: I._rand_bytes(300, 9),
        "huge": lambda ws: '{"offsets_deg": [1e300, 0, 0, 0, 0, 0]}\n',
    }
    cases += _file_cases("zero", zr, "{REPLAY}", replay_v, {
        "empty": (2, r"json|empty"), "not_json": (2, r"json"), "array": (2, r"offsets|object"),
        "no_offsets": (2, r"offsets"), "nan": (2, NOT_NUMBER + r"|offsets"),
        "strings": (2, r"offsets|number"), "short": (2, r"offsets"),
        "nested": (2, r"offsets|number"), "binary": (2, NOT_TEXT + r"|json"),
        "huge": (2, r"offsets|plausible|large"),
    }, src="zero.json")
    gz = ["zero", "postures.csv", "--model", "ur10e"]
    cases += _number_cases("zero", gz, [
        ("--sigma", ["nan", "0", "-1", "inf"]), ("--tolerance-deg", ["nan", "0", "-1", "inf"]),
        ("--seed", ["-1"])])
    cases += _out_cases("zero", gz, [
        ("is_postures", ["--out", "postures.csv"], IS_INPUT + r"|\.yaml"),
        ("is_params", ["--params", "params_ur10e.json", "--out", "params_ur10e.json"], IS_INPUT),
        ("is_replay", ["--replay", "zero.json", "--out", "zero.json"], IS_INPUT),
        ("directory", ["--out", "adir.yaml"], DIRECTORY, [mkdir("adir.yaml")]),
        ("no_folder", ["--out", "nofolder/z.yaml"], NO_FOLDER),
    ])
    zdb = ["zero", "--db", "{DB}"]
    cases += _store_cases("zero", zdb, ok=False)
    cases.append(Case("zero", "out:is_store", ["zero", "--db", "cell.db", "--out", "cell.db"],
                      2, IS_INPUT + r"|" + IS_STORE))
    cases += _number_cases("zero", ["zero", "--db", "cell.db"], [("--run", ["-1", "99"])])

    # ---- runs / export
    cases += _store_cases("runs", ["runs", "--db", "{DB}"], ok=True)
    cases += _store_cases("export", ["export", "--db", "{DB}", "--out", "x.csv"], ok=True,
                          creates=("x.csv",))
    cases += [Case("runs", f"num:run={v}", ["runs", v, "--db", "cell.db"], 2, r"run")
              for v in ("-1", "99", "abc")]
    cases += [Case("export", f"num:run={v}", ["export", v, "--db", "cell.db", "--out", "x.csv"],
                   2, r"run") for v in ("-1", "99")]
    cases.append(Case("export", "postures_of_frame_run",
                      ["export", "1", "--postures", "--db", "cell.db", "--out", "x.csv"], 2,
                      r"zero20|run 1"))
    cases += _out_cases("export", ["export", "--db", "cell.db"], [
        ("is_store", ["--out", "cell.db"], IS_INPUT + r"|" + IS_STORE),
        ("other_store", ["--out", "v2.db"], IS_STORE),
        ("directory", ["--out", "adir"], DIRECTORY, [mkdir("adir")]),
        ("no_folder", ["--out", "nofolder/x.csv"], NO_FOLDER),
    ])
    cases.append(Case("export", "out:ok_stdout", ["export", "--db", "cell.db", "--out", "-"],
                      0, ""))
    cases.append(Case("runs", "ok_json", ["runs", "--db", "cell.db", "--json"], 0, ""))

    # ---- simulate
    sim = ["simulate", "--model", "ur5", "--poses", "20", "--valid", "5", "--out", "sim.csv"]
    cases += _number_cases("simulate", sim, [
        ("--poses", ["0", "-1", "100000000"]), ("--valid", ["-1"]),
        ("--sigma", ["nan", "0", "-1", "inf"]), ("--seed", ["-1"]),
        ("--hidden", ["bogus", "compliance:9"])])
    cases += _out_cases("simulate", ["simulate", "--model", "ur5", "--poses", "20"], [
        ("is_store", ["--out", "cell.db"], IS_STORE),
        ("directory", ["--out", "adir"], DIRECTORY, [mkdir("adir")]),
        ("no_folder", ["--out", "nofolder/s.csv"], NO_FOLDER),
        ("truth_is_out", ["--out", "s.csv", "--truth", "s.csv"], r"twice|same|both"),
        ("truth_is_store", ["--out", "s.csv", "--truth", "cell.db"], IS_STORE),
        ("truth_no_folder", ["--out", "s.csv", "--truth", "nofolder/t.json"], NO_FOLDER),
    ])
    cases += _out_cases("simulate", ["simulate", "--poses", "20"], [
        ("is_model", ["--model", "model.yaml", "--out", "model.yaml"], IS_INPUT),
        ("is_effect", ["--model", "ur5", "--effect-file", "effect.py", "--out", "effect.py"],
         IS_INPUT),
    ])
    sm = ["simulate", "--model", "{MODEL}", "--poses", "20", "--out", "sim.csv"]
    cases += _file_cases("simulate", sm, "{MODEL}", model_v, MODEL, src="model.yaml",
                         creates=("sim.csv",))
    cases.append(Case("simulate", "ok", sim, 0, "", creates=("sim.csv",)))

    # ---- demo: refusals before anything runs
    cases += [
        Case("demo", "out:user_folder", ["demo", "--out", ".", "--quiet"], 2,
             r"holds|not written by|--force"),
        Case("demo", "out:is_file", ["demo", "--out", "good.csv", "--quiet"], 2,
             r"not a (folder|directory)|directory"),
        Case("demo", "out:force_foreign_store", ["demo", "--out", "dfold", "--force",
                                                  "--quiet"], 2,
             r"run store|cell.db", [mkdir("dfold"), copy("cell.db", "dfold/cell.db")]),
        Case("demo", "out:user_files", ["demo", "--out", "dfold", "--quiet"], 2,
             r"holds|--force", [mkdir("dfold"), copy("good.csv", "dfold/capture.csv")]),
    ]
    cases += _number_cases("demo", ["demo", "--out", "newdemo", "--quiet"], [
        ("--seed", ["-1"]), ("--poses", ["10", "-5"]), ("--valid", ["5"]),
        ("--hidden", ["bogus", "compliance:9"])])
    cases += _number_cases("demo", ["demo", "--out", "newdemo", "--quiet", "--cold-start"], [
        ("--poses", ["10"]), ("--hidden", ["bogus"])])
    cases.append(Case("demo", "cold_start:value", ["demo", "--out", "newdemo", "--quiet",
                                                   "--cold-start=yes"], 2, r"cold-start"))

    # ---- models
    cases.append(Case("models", "ok", ["models"], 0, ""))
    cases.append(Case("models", "ok_json", ["models", "--json"], 0, ""))

    # ---- capture: run store, model, URLs, register maps (refused before any motion)
    cap = ["capture", "poses", "--model", "ur5", "--count", "5", "--db", "{DB}",
           "--robot", "socket://127.0.0.1:9", "--tracker", "tracker+tcp://127.0.0.1:9",
           "--tool-mm", "0,0,60", "--tracker-at", "2500,0,500"]
    cases += _store_cases("capture", cap, ok=False, skip=("empty", "missing", "missing_folder"))
    cmodel = [a if a != "ur5" else "{MODEL}" for a in cap]
    cmodel = [a if a != "{DB}" else "new.db" for a in cmodel]
    cases += _file_cases("capture", cmodel, "{MODEL}", model_v, MODEL, src="model.yaml")
    urls = {
        "ipv6_unclosed": ("--robot", "socket://[::1"),
        "unit_negative": ("--robot", "modbus+tcp://127.0.0.1:9?unit=-1"),
        "unit_big": ("--robot", "modbus+tcp://127.0.0.1:9?unit=999"),
        "unit_text": ("--robot", "modbus+tcp://127.0.0.1:9?unit=one"),
        "port_big": ("--robot", "modbus+tcp://127.0.0.1:99999"),
        "port_zero": ("--tracker", "tracker+tcp://127.0.0.1:0"),
        "no_port": ("--tracker", "tracker+tcp://127.0.0.1"),
        "unknown_param": ("--robot", "modbus+tcp://127.0.0.1:9?speed=3"),
        "baud_negative": ("--robot", "serial:///dev/ttyUSB0?baud=-5"),
        "unknown_scheme": ("--robot", "ftp://127.0.0.1:9"),
        "no_scheme": ("--tracker", "127.0.0.1:9"),
        "empty": ("--robot", ""),
        "map_missing": ("--robot", "modbus+tcp://127.0.0.1:9?map=nomap.yaml"),
        "emscon_param": ("--tracker", "emscon://127.0.0.1?bogus=1"),
    }
    good_cap = [a if a != "{DB}" else "new.db" for a in cap]
    for name, (flag, url) in urls.items():
        argv = list(good_cap)
        argv[argv.index(flag) + 1] = url
        cases.append(Case("capture", f"url:{name}", argv, 2,
                          r"url|unit|port|scheme|baud|map|host|parameter"))
    for name, body in I.register_map_variants().items():
        argv = list(good_cap)
        fname = f"rm_{name}.yaml"
        argv[argv.index("--robot") + 1] = f"modbus+tcp://127.0.0.1:9?map={fname}"
        cases.append(Case("capture", f"register_map:{name}", argv, 2,
                          f"(?=.*{re.escape(fname)})(?=.*(?:{REGISTER_MAP[name]}))",
                          [write(fname, body)]))

    # ---- capture: the cell YAML and the tracker position (refused before any motion)
    for name, body in I.cell_variants().items():
        fname = f"c_{name}.yaml"
        cases.append(Case("capture", f"cell:{name}", [*good_cap, "--cell", fname], 2,
                          f"(?=.*{re.escape(fname)})(?=.*(?:{CELL[name]}))",
                          [write(fname, body)]))
    cases += _path_cases("capture", [*good_cap, "--cell", "{CELL}"], "{CELL}", "cell.yaml")[:3]
    cases += _number_cases("capture", good_cap, [
        ("--tracker-at", ["nan,0,0", "1,2", "a,b,c", "1e400,0,0"]),
        ("--count", ["0", "-1", "x"]), ("--smr-radius-mm", ["-1", "nan"]),
        ("--drift-check", ["0", "-5", "x", "2.5", "nanmin", "0min"]),
        ("--drift-references", ["0", "x"]), ("--drift-bound-mm", ["0", "-1", "x"]),
        ("--require-warm", ["-1", "x"])])
    warm_cap = [a if a != "poses" else "warmup" for a in good_cap]
    cases += _number_cases("capture", warm_cap, [
        ("--window-min", ["0", "-1", "x", "90"]), ("--max-min", ["-5", "x"]),
        ("--threshold-mm", ["0", "-1"]), ("--cycles", ["0", "x"]), ("--count", ["0"])])
    cases.append(Case("capture", "drift_options_without_drift_check",
                      [*good_cap, "--drift-bound-mm", "0.1"], 2, r"--drift-check"))
    cases.append(Case("capture", "six_dof_with_value", [*good_cap, "--six-dof=yes"], 2,
                      r"--six-dof"))

    # ---- calibrate --db: the store a calibration is recorded in (a new file is made)
    cases += _store_cases("calibrate", [*good_cal, "--db", "{DB}", "--robot-id", "R1"],
                          ok=False, skip=("missing", "empty"))
    cases.append(Case("calibrate", "robot_id_without_db", [*good_cal, "--robot-id", "R1"], 2,
                      r"--robot-id needs --db"))
    cases.append(Case("calibrate", "position_only_with_value",
                      [*good_cal, "--position-only=yes"], 2, r"--position-only"))

    # ---- history: the run store, the threshold, the plot (never over an input or a store)
    cases += _store_cases("history", ["history", "R1", "--db", "{DB}"], ok=False)
    cases.append(Case("history", "no_calibrations", ["history", "R1", "--db", "cell.db"], 2,
                      r"no calibrations of robot 'R1'"))
    cases += _number_cases("history", ["history", "R1", "--db", "cell.db"], [
        ("--sigma", ["0", "-1", "nan", "inf", "x"])])
    cases += _out_cases("history", ["history", "R1", "--db", "cell.db"], [
        ("plot_is_store", ["--plot", "cell.db"], r"html|png|run store"),
        ("plot_is_store_png", ["--plot", "v2.db.png", "--db", "v2.db.png"],
         IS_INPUT + "|" + NOT_STORE, [copy("v2.db", "v2.db.png")]),
        ("plot_no_folder", ["--plot", "nofolder/h.html"], NO_FOLDER),
        ("plot_directory", ["--plot", "adir.html"], DIRECTORY, [mkdir("adir.html")]),
    ])

    # ---- resume: the run store
    cases += _store_cases("resume", ["resume", "--db", "{DB}"], ok=False)

    # ---- sim serve: a bad model is refused (subprocess: an accepted one would serve)
    for name in ("nan", "huge", "bool_min", "non_utf8", "neg_payload"):
        cases.append(Case("sim", f"model:{name}",
                          ["sim", "serve", "--no-pty", "--no-rtde", "--model", f"x_{name}.yaml"],
                          2, MODEL[name][1], [write(f"x_{name}.yaml", model_v[name])],
                          mode="subprocess", slow=True))
    for name in ("syntax", "zero_axis", "binary"):
        fname = f"c_{name}.yaml"
        cases.append(Case("sim", f"cell:{name}",
                          ["sim", "serve", "--no-pty", "--no-rtde", "--cell", fname], 2,
                          CELL[name], [write(fname, I.cell_variants()[name])],
                          mode="subprocess", slow=True))
    cases += _number_cases("sim", ["sim", "serve", "--no-pty", "--no-rtde"], [
        ("--tracker-at", ["nan,0,0", "1,2"]), ("--tracker-warmup-s", ["-1", "nan"]),
        ("--time-scale", ["nan", "-1"]), ("--seed", ["-1"]), ("--hidden", ["bogus"]),
        ("--thermal", ["hot"]), ("--six-dof", ["nan,0,0", "1,2"])])
    for c in cases:
        if (c.command == "sim" and c.name.startswith("num:")) or "100000000" in c.argv:
            c.mode, c.slow = "subprocess", True

    cases += _seam_cases(good_cap)
    cases += _log_cases(good_cap)

    # ---- process-level: stdout without a reader, a store only readable
    cases.append(Case("runs", "broken_pipe", ["runs", "--db", "cell.db", "--json"], 0, "",
                      mode="subprocess", slow=True, stdout_closed=True))
    cases.append(Case("compensate", "broken_pipe",
                      ["compensate", "targets.csv", "--params", "params.json"], 0, "",
                      mode="subprocess", slow=True, stdout_closed=True))
    for cmd, argv in (("runs", ["runs", "--db", "ro/cell.db"]),
                      ("export", ["export", "--db", "ro/cell.db", "--out", "-"]),
                      ("runs", ["runs", "--db", "ro/v2.db"])):
        cases.append(Case(cmd, f"store:ok_unprivileged_{Path(argv[2]).stem}", argv, 0, "",
                          [mkdir("ro"), copy("cell.db", "ro/cell.db"), copy("v2.db", "ro/v2.db"),
                           chmod_ro("ro/cell.db"), chmod_ro("ro/v2.db"),
                           lambda ws: (ws / "ro").chmod(0o555)],
                          mode="subprocess", slow=True, unprivileged=True))
    from .program_cases import program_cases  # it imports this module's helpers

    return cases + program_cases()


def _contradicting_joints(ws: Path) -> str:
    """targets.csv with its second target's x moved 500 mm (its joints left as they were)."""
    head, first, second, *rest = (ws / "targets.csv").read_text().splitlines()
    f = second.split(",")
    f[1] = repr(float(f[1]) + 500.0)
    return "\n".join([head, first, ",".join(f), *rest]) + "\n"


def _seam_cases(good_cap: list[str]) -> list[Case]:
    """Issue 29's seams: a plan made blind, an SMR inside the wrist, the documented minimum
    of a range, a NaN in a list option, a run that ends with most points missing, targets
    whose joints contradict their point."""
    sim = ["--robot", "sim://robot?model=ur10e", "--tracker", "sim://tracker", "--db", "new.db"]
    ur10e = ["--model", "ur10e", "--tool-mm", "0,0,60", "--tracker-at", "2500,0,500", *sim]
    blind = [a for a in ur10e if a not in ("--tracker-at", "2500,0,500")]
    out = [
        Case("capture", "seam:blind_plan", good_cap[:-2], 2,
             r"tracker's position is unknown.*--tracker-at.*frame run.*--cell.*--no-visibility"),
        Case("capture", "seam:smr_at_flange",
             ["capture", "poses", "--count", "5", "--model", "ur10e", "--tracker-at",
              "2500,0,500", *sim, "--dry-run"], 3, r"inside the wrist.*--tool-mm"),
        Case("capture", "seam:circle_below_minimum",
             ["capture", "frame", *ur10e, "--circle-span-deg", "29.9"], 2,
             r"--circle-span-deg.*minimum 30"),
        Case("capture", "seam:circle_minimum_ok",
             ["capture", "frame", *ur10e, "--circle-span-deg", "30", "--dry-run"], 0, ""),
        Case("capture", "seam:mostly_skipped",
             ["capture", "poses", "--count", "4", "--seed", "3", *blind, "--no-visibility",
              "--measure-s", "0.01"], 3, r"incomplete.*4 of 4 planned points missing",
             creates=("new.db", "new.db.run1.log"), stores=True),
        Case("resume", "seam:meteo_nan", ["resume", "--db", "cell.db", "--meteo", "20,nan,45"],
             2, r"--meteo.*finite"),
        Case("compensate", "seam:joints_contradict_target",
             ["compensate", "bad_joints.csv", "--params", "params.json"], 2,
             r"bad_joints\.csv.*line 3 \(pose_id t2\): \d+\.\d mm.*--joints-tolerance-mm",
             [write("bad_joints.csv", _contradicting_joints)]),
    ]
    lists = [("frame", "--start-deg", "0,-60,{v},-120,-90,0"),
             ("steps", "--start-xyz", "600,{v},500"), ("steps", "--start-deg", "0,-60,{v},0,0,0"),
             ("zero20", "--target-xyz", "600,200,{v}"), ("zero20", "--seed-deg", "{v},0,0,0,0,0"),
             ("iso9283", "--centre-xyz", "{v},0,500"), ("poses", "--keepout-mm", "0,0,0,1,1,{v}"),
             ("poses", "--meteo", "20,{v},45"), ("poses", "--tool-mm", "0,{v},60")]
    for routine, flag, value in lists:
        for v in ("nan", "inf"):
            argv = ["capture", routine, "--model", "ur10e", "--tracker-at", "2500,0,500", *sim,
                    flag, value.format(v=v)]
            out.append(Case("capture", f"seam:{routine}{flag}={v}", argv, 2,
                            f"{re.escape(flag)}.*finite"))
    out += _number_cases("compensate", ["compensate", "targets.csv", "--params", "params.json"],
                         [("--joints-tolerance-mm", ["0", "-1", "nan", "inf", "x"])])
    return out


def _log_cases(good_cap: list[str]) -> list[Case]:
    """The logging flags every command takes: a bad level, a log file that is an input, a
    store, a folder or in no folder (refused before the command runs: nothing written)."""
    out = [Case(cmd, f"log:level={v}", [*argv, "--log-level", v], 2,
                r"--log-level.*not a log level.*DEBUG, INFO, WARNING, ERROR, CRITICAL")
           for cmd, argv in (("runs", ["runs", "--db", "cell.db"]), ("models", ["models"]),
                             ("capture", good_cap))
           for v in ("LOUD", "", "10", "warn")]
    out.append(Case("models", "log:level_before_command", ["--log-level", "x", "models"], 2,
                    r"--log-level.*not a log level"))
    not_a_log = r"--log-file.*not a cellcal log"
    for name, target, msg, setup in (
            ("is_data", "good.csv", not_a_log, []), ("is_store", "cell.db", not_a_log, []),
            ("is_params", "params.json", not_a_log, []),
            ("directory", "adir", r"--log-file.*directory", [mkdir("adir")]),
            ("no_folder", "nofolder/x.log", r"--log-file.*no such folder", [])):
        out.append(Case("calibrate", f"log:file_{name}",
                        ["calibrate", "good.csv", "--model", "ur5", "--log-file", target], 2,
                        msg, setup))
    out.append(Case("capture", "log:file_is_store", [*good_cap, "--log-file", "cell.db"], 2,
                    not_a_log))
    out.append(Case("models", "log:file_ok", ["models", "-v", "--log-file", "m.log"], 0, "",
                    creates=("m.log",)))
    return out
def narrowed_params(ws: Path) -> str:
    """The workspace's params.json with joint 2's calibrated range cut to [0, 0.1] deg:
    every target (and program target) lies beyond it."""
    doc = json.loads((ws / "params.json").read_text())
    doc["envelope"]["joints_deg"][1] = [0.0, 0.1]
    return json.dumps(doc)


def _envelope_cases() -> list[Case]:
    """Issue 34: targets beyond the calibrated envelope (warned; refused with
    --strict-range, exit 3), a params.json without the envelope or with a bad one, check's
    poses beyond it, a table's knot range in its name."""
    def params(change):
        def make(ws):
            d = json.loads((ws / "params.json").read_text())
            change(d)
            return json.dumps(d)
        return make

    def env(**kw):
        return lambda d: d["envelope"].update(kw)

    argv = ["compensate", "targets.csv", "--params", "p.json", "--out", "comp.csv"]
    narrow = write("p.json", narrowed_params)
    cases = [
        Case("compensate", "envelope:outside_warned", argv, 0,
             r"warning: \d+ of \d+ targets lie beyond the calibrated envelope \(q2",
             [narrow], creates=("comp.csv",)),
        Case("compensate", "envelope:strict_outside", [*argv, "--strict-range"], 3,
             r"beyond the calibrated envelope.*q2.*--strict-range", [narrow]),
        Case("compensate", "envelope:strict_without_record", [*argv, "--strict-range"], 2,
             r"records no calibrated envelope",
             [write("p.json", params(lambda d: d.pop("envelope")))]),
    ]
    bad = {
        "not_object": (lambda d: d.update(envelope="wide"), r"envelope: not an object"),
        "newer": (env(version=99), r"envelope\.version"),
        "reversed": (env(joints_deg=[[1, 0]] * 6), r"envelope\.joints_deg\.0"),
        "short": (env(joints_deg=[[0, 1]] * 5), r"envelope\.joints_deg.*6 ranges"),
        "nan": (env(t_s=[0, float("nan")]), r"envelope\.t_s"),
        "no_joints": (lambda d: d["envelope"].pop("joints_deg"), r"joints_deg missing"),
    }
    cases += [Case("compensate", f"envelope:{name}", argv, 2, msg,
                   [write("p.json", params(change))])
              for name, (change, msg) in bad.items()]
    # check: the poses beyond the envelope named, a file without one said, a bad one refused
    check = ["check", "good.csv", "--params", "p.json", "--model", "ur5"]
    cases += [
        Case("check", "envelope:outside_named", check, 0,
             r"outside +\d+ of \d+ poses lie beyond the envelope \(.*q2: \d+", [narrow]),
        Case("check", "envelope:without_record", check, 0,
             r"records no calibrated envelope.*the poses are not checked",
             [write("p.json", params(lambda d: d.pop("envelope")))]),
        Case("check", "envelope:reversed", check, 2, r"envelope\.joints_deg\.0",
             [write("p.json", params(env(joints_deg=[[1, 0]] * 6)))]),
    ]
    cal = ["calibrate", "good.csv", "--model", "ur5", "--effects"]
    for name, effect, msg in (("not_knots", "table5:2@-3..40", r"multiples of 5"),
                              ("reversed", "table:2@40..-30", r"LO < HI"),
                              ("too_short", "table:2@0..10", r"at least 20"),
                              ("formula", "compliance:2@0..10", r"takes no range"),
                              ("text", "table:2@a..b", r"@LO\.\.HI")):
        cases.append(Case("calibrate", f"effects:table_range_{name}",
                          [*cal, f"geometric,base,tool,{effect}"], 2, msg))
    return cases


def _thermal_compensate_cases() -> list[Case]:
    """compensate and the thermal state: bad joint_temp1..N / t_s columns of the targets, a
    bad ``thermal`` record of params.json, a drift model without a recorded warm state."""
    def targets(extra_head, extra):
        def make(ws):
            lines = (ws / "targets.csv").read_text().splitlines()
            return "\n".join([lines[0] + extra_head] + [r + extra for r in lines[1:]]) + "\n"
        return make

    def params(change):
        def make(ws):
            d = json.loads((ws / "params.json").read_text())
            change(d)
            return json.dumps(d)
        return make

    def drift_model(d):  # thermal growth calibrated before the thermal record existed
        d["effects"].append("thermal_growth")
        d["parameters"].append({"name": "thermal_growth.k", "value": 1e-5, "std": None,
                                "unit": "1/K", "identifiable": True, "weak": None})

    temps = ",".join(f"joint_temp{j}" for j in range(1, 7))
    argv = ["compensate", "t.csv", "--params", "p.json", "--out", "comp.csv"]
    bad_targets = {
        "joint_temp_partial": (",joint_temp1", ",30", r"joint temp"),
        "joint_temp_implausible": ("," + temps, ",30,30,30,30,30,900", r"joint_temp6"),
        "joint_temp_nan": ("," + temps, ",30,30,nan,30,30,30", r"joint_temp3"),
        "joint_temp7": ("," + temps + ",joint_temp7", ",30,30,30,30,30,30,30",
                        r"joint_temp7"),
        "t_s_text": (",t_s", ",soon", r"t_s"),
    }
    cases = [Case("compensate", f"thermal:{name}", argv, 2, msg,
                  [write("t.csv", targets(head, row)), copy("params.json", "p.json")])
             for name, (head, row, msg) in bad_targets.items()]
    bad_records = {
        "record_not_object": (lambda d: d.update(thermal="warm"), r"thermal"),
        "record_window_reversed": (lambda d: d.update(thermal={"time_window_s": [9, 1]}),
                                   r"thermal.time_window_s"),
        "record_newer": (lambda d: d.update(thermal={"version": 99}), r"thermal.version"),
        "record_temps_short": (lambda d: d.update(thermal={"warm_state": {
            "joint_temp_c": [30]}}), r"joint_temp_c"),
        "record_missing": (drift_model, r"needs joint_temp1..N"),
    }
    cases += [Case("compensate", f"thermal:{name}", argv, 2, msg,
                   [copy("targets.csv", "t.csv"), write("p.json", params(change))])
              for name, (change, msg) in bad_records.items()]
    return cases


def _store_cases(command, argv, *, ok: bool, skip=(), creates=()) -> list[Case]:
    out = []
    for name in I.store_variants():
        if name in skip:
            continue
        rc, msg = STORE[name]
        fname = f"s_{name}.db"
        out.append(Case(command, f"store:{name}", [fname if a == "{DB}" else a for a in argv],
                        rc, f"(?=.*{re.escape(fname)})(?=.*(?:{msg}))", [store(fname, name)],
                        creates=creates))
    for name, path, setup in (("missing", "missing.db", []),
                              ("missing_folder", "nofolder/cell.db", []),
                              ("directory", "adir.db", [mkdir("adir.db")])):
        if name in skip:
            continue
        out.append(Case(command, f"store:{name}", [path if a == "{DB}" else a for a in argv], 2,
                        DIRECTORY if name == "directory" else MISSING, setup, creates=creates))
    if ok:
        for name, path, setup in (("ok_v2", "v2.db", []), ("ok_readonly", "cell.db",
                                                          [chmod_ro("cell.db")])):
            out.append(Case(command, f"store:{name}", [path if a == "{DB}" else a for a in argv],
                            0, "", setup, creates=creates))
    return out


def _effect_record_cases() -> list[Case]:
    """A params.json made with effect.py: --effect-file needed, with the recorded hash."""
    import json

    def make(ws):
        d = json.loads((ws / "params.json").read_text())
        d["effects"] = [*d["effects"], "myeffect:2"]
        d["parameters"].append({"name": "myeffect.j2.amp", "value": 0.001, "std": 0.0001,
                                "unit": "deg", "identifiable": True})
        text = (ws / "effect.py").read_text()
        d["effect_files"] = [{"name": "effect.py", "sha256": I._sha(text),
                              "families": ["myeffect"]}]
        return json.dumps(d, indent=1)

    argv = ["compensate", "targets.csv", "--params", "pe.json"]
    changed = write("effect.py", lambda ws: (ws / "effect.py").read_text() + "# edited\n")
    return [
        Case("compensate", "effect_record:not_given", argv, 2, r"--effect-file",
             [write("pe.json", make)]),
        Case("compensate", "effect_record:changed", [*argv, "--effect-file", "effect.py"], 2,
             r"sha256|changed|differs", [write("pe.json", make), changed]),
        Case("compensate", "effect_record:ok", [*argv, "--effect-file", "effect.py"], 0, "",
             [write("pe.json", make)]),
    ]


#: ``check`` evaluates the given model on any number of poses (no fit): data too few or too
#: alike to calibrate, or all marked valid, are checked; radians are still refused
CHECK_CSV = {**BAD_FILE_CSV, "one_pose": (0, ""), "five_poses": (0, ""),
             "eight_poses": (0, ""), "identical_100": (0, ""), "all_valid": (0, "")}


def _without_base(ws: Path) -> str:
    """params.json without its base effect (and its parameters): a calibration in the
    robot's own frame."""
    import json

    d = json.loads((ws / "params.json").read_text())
    d["effects"] = [e for e in d["effects"] if e != "base"]
    d["parameters"] = [p for p in d["parameters"] if not p["name"].startswith("base.")]
    return json.dumps(d, indent=1)


def _check_cases(csv_m, params_v, model_v) -> list[Case]:
    """``check``: the new poses' CSV, the params.json, the model, effect files, numbers,
    the run store of ``--db`` and the flags that need another."""
    argv = ["check", "{DATA}", "--params", "params.json", "--model", "ur5"]
    good = ["check", "good.csv", "--params", "params.json", "--model", "ur5"]
    cases = _file_cases("check", argv, "{DATA}", csv_m, CHECK_CSV, src="good.csv")
    cases += _path_cases("check", argv, "{DATA}", "good.csv")
    cases += _special_file_cases("check", argv, "{DATA}")
    pargv = ["check", "good.csv", "--model", "ur5", "--params", "{PARAMS}"]
    cases += _file_cases("check", pargv, "{PARAMS}", params_v, PARAMS, src="params.json")
    cases += _path_cases("check", pargv, "{PARAMS}", "params.json")[:3]
    margv = ["check", "good.csv", "--params", "params.json", "--model", "{MODEL}"]
    cases += _file_cases("check", margv, "{MODEL}", model_v, MODEL | {"seven_joints": (
        2, r"q7|joints")}, src="model.yaml")
    cases += _path_cases("check", margv, "{MODEL}", "model.yaml")[:3]
    for name, body in I.effect_file_variants().items():
        fname = f"e_{name}.py"
        cases.append(Case("check", f"effect_file:{name}", [*good, "--effect-file", fname], 2,
                          EFFECT_FILE[name], [write(fname, body)]))
    cases += _number_cases("check", good, [
        ("--sigma", ["nan", "-1", "0", "inf", "abc"]),
        ("--tolerance-mm", ["0", "-1", "nan", "inf", "abc"])])
    cases += _store_cases("check", [*good, "--db", "{DB}", "--robot-id", "R1"], ok=False,
                          skip=("missing", "empty"))
    cases += [
        Case("check", "robot_id_without_db", [*good, "--robot-id", "R1"], 2,
             r"--robot-id needs --db"),
        Case("check", "db_without_robot", [*good, "--db", "new.db"], 2,
             r"good\.csv.*name no robot.*--robot-id"),
        Case("check", "no_params", ["check", "good.csv", "--model", "ur5"], 2, r"--params"),
        Case("check", "refit_base_without_base",
             ["check", "good.csv", "--params", "nobase.json", "--refit-base"], 2,
             r"--refit-base.*nobase\.json.*no base effect", [write("nobase.json", _without_base)]),
        Case("check", "refit_base_one_pose", ["check", "x_one_pose.csv", "--params",
                                              "params.json", "--model", "ur5", "--refit-base"],
             3, r"x_one_pose\.csv.*at least three points",
             [write("x_one_pose.csv", csv_m["one_pose"])]),
        Case("check", "ok_tolerance_met", [*good, "--tolerance-mm", "1000"], 0, ""),
        Case("check", "tolerance_exceeded", [*good, "--tolerance-mm", "0.001"], 1,
             r"BEYOND"),
        Case("check", "ok_recorded", [*good, "--db", "new.db", "--robot-id", "R1"], 0, "",
             creates=("new.db",)),
    ]
    return cases


def _one_joint_with_temps(ws: Path) -> str:
    """good.csv with only joint 1 moving (a rank-deficient design) and the joints'
    temperatures of a controller that reports them (``joint_temp1..6``)."""
    lines = (ws / "good.csv").read_text().splitlines()
    meta = [ln for ln in lines if ln.startswith("#")]
    head, *rows = [ln for ln in lines if not ln.startswith("#")]
    cols = head.split(",")
    first = rows[0].split(",")
    out = [head + "," + ",".join(f"joint_temp{j}" for j in range(1, 7))]
    for row in rows:
        f = row.split(",")
        for c in ("q2", "q3", "q4", "q5", "q6"):
            f[cols.index(c)] = first[cols.index(c)]
        out.append(",".join(f) + ",20.5,21,21.5,22,22.5,23")
    return "\n".join(meta + out) + "\n"


def _issue36_cases() -> list[Case]:
    """Issue 36's seams: a rank-deficient capture with joint temperatures (its data check
    was skipped), a params.json naming the model of data that name none, a compensated
    program given to validate (program_cases)."""
    return [
        Case("calibrate", "seam:rank_deficient_with_joint_temps",
             ["calibrate", "rank.csv", "--model", "ur5"], 3, r"rank\.csv.*rank-deficient design",
             [write("rank.csv", _one_joint_with_temps)]),
        Case("diagnose", "seam:rank_deficient_with_joint_temps",
             ["diagnose", "rank.csv", "--model", "ur5"], 3, r"rank\.csv.*rank-deficient design",
             [write("rank.csv", _one_joint_with_temps)]),
        Case("calibrate", "seam:params_name_the_model",
             ["calibrate", "good.csv", "--params", "params.json"], 0, ""),
        Case("diagnose", "seam:params_name_the_model",
             ["diagnose", "good.csv", "--params", "params.json", "--top", "3"], 0, "",
             slow=True),
        Case("check", "seam:params_name_the_model", ["check", "good.csv", "--params",
                                                     "params.json"], 0, ""),
    ]


# --------------------------------------------------------------------------- running
def snapshot(ws: Path) -> dict[str, str]:
    """sha256 of every regular file under ``ws`` (relative path -> digest)."""
    out = {}
    for p in sorted(ws.rglob("*")):
        try:
            if p.is_symlink() or not p.is_file():
                continue
            out[str(p.relative_to(ws))] = hashlib.sha256(p.read_bytes()).hexdigest()
        except OSError:
            continue
    return out


def _restore_permissions(ws: Path) -> None:
    for p in [ws, *ws.rglob("*")]:
        with contextlib.suppress(OSError):
            if p.is_dir() and not p.is_symlink():
                p.chmod(0o755)
            elif p.is_file():
                p.chmod(0o644)


def run_inproc(case: Case, ws: Path) -> Outcome:
    from calibration import effects
    from cellcal.cli import main

    registry = dict(effects.REGISTRY)
    modules = set(sys.modules)
    out, err = io.StringIO(), io.StringIO()
    cwd = os.getcwd()
    os.chdir(ws)
    try:
        with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
            try:
                rc = main(list(case.argv))
            except SystemExit as e:
                rc = e.code if isinstance(e.code, int) else (0 if e.code is None else 2)
            except BaseException as e:  # noqa: BLE001 - the corpus counts what escapes
                return Outcome(None, out.getvalue(), err.getvalue(),
                               f"{type(e).__name__}: {e}"[:300])
    finally:
        os.chdir(cwd)
        effects.REGISTRY.clear()
        effects.REGISTRY.update(registry)
        for m in set(sys.modules) - modules:
            if m.startswith("cellcal_user_effect"):
                del sys.modules[m]
    return Outcome(int(rc), out.getvalue(), err.getvalue())


def _without_permission_override() -> None:
    """In the child, before exec: give up root's right to ignore file permissions
    (CAP_DAC_OVERRIDE, CAP_DAC_READ_SEARCH, CAP_FOWNER), so a read-only file or folder
    is read-only to it as to any user. Without root there is nothing to give up."""
    if os.geteuid() != 0:
        return
    import ctypes

    libc = ctypes.CDLL(None, use_errno=True)
    for cap in (1, 2, 3):
        libc.prctl(24, cap, 0, 0, 0)  # PR_CAPBSET_DROP: gone after the exec


def run_subprocess(case: Case, ws: Path, timeout: float = 120.0) -> Outcome:
    env = dict(os.environ)
    # the checkout under test first (``PYTHONPATH``, as the tally's docstring says), this
    # one after it
    env["PYTHONPATH"] = os.pathsep.join(filter(None, [os.environ.get("PYTHONPATH"), str(ROOT)]))
    env.setdefault("MPLBACKEND", "Agg")
    env["MPLCONFIGDIR"] = str(ws / ".mpl")

    def limits():
        import resource

        resource.setrlimit(resource.RLIMIT_AS, (4 << 30, 4 << 30))
        if case.unprivileged:
            _without_permission_override()

    cmd = [sys.executable, "-m", "cellcal", *case.argv]
    if case.stdout_closed:
        proc = subprocess.Popen(cmd, cwd=ws, env=env, stdout=subprocess.PIPE,
                                stderr=subprocess.PIPE, stdin=subprocess.DEVNULL,
                                preexec_fn=limits)
        proc.stdout.close()  # no reader from the start: the child's first write breaks
        try:
            _, err = proc.communicate(timeout=timeout)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.communicate()
            return Outcome(None, "", "", hung=True)
        return Outcome(proc.returncode, "", err.decode(errors="replace"))
    try:
        p = subprocess.run(cmd, cwd=ws, env=env, capture_output=True, timeout=timeout,
                           stdin=subprocess.DEVNULL, preexec_fn=limits)
    except subprocess.TimeoutExpired:
        return Outcome(None, "", "", hung=True)
    return Outcome(p.returncode, p.stdout.decode(errors="replace"),
                   p.stderr.decode(errors="replace"))


def prepare(case: Case, ws: Path) -> dict[str, str]:
    """Run the case's setup in ``ws``; the snapshot of every file before the command."""
    for s in case.setup:
        s(ws)
    return snapshot(ws)


def run_case(case: Case, ws: Path) -> tuple[Outcome, dict[str, str]]:
    """Set up ``ws``, run the case; (outcome, snapshot before)."""
    before = prepare(case, ws)
    run = run_subprocess if case.mode == "subprocess" else run_inproc
    outcome = run(case, ws)
    _restore_permissions(ws)
    return outcome, before


def judge(case: Case, outcome: Outcome, before: dict[str, str], ws: Path) -> list[str]:
    """What went wrong: a list of (kind: detail) strings, empty when the case passed."""
    problems = []
    text = outcome.out + outcome.err
    if outcome.hung:
        problems.append("traceback: hung (timeout)")
    elif outcome.exception or "Traceback (most recent call last)" in text \
            or "internal error" in text:
        problems.append(f"traceback: {outcome.exception or text.strip().splitlines()[-1]}")
    after = snapshot(ws)
    changed = [k for k in before if before[k] != after.get(k)]
    if changed:
        problems.append(f"loss: changed or removed {changed[:4]}")
    new = [k for k in after if k not in before and k not in case.creates
           and not k.startswith(".mpl")]
    refused = case.rc != 0 and not case.stores
    if refused and (new or any(k in after for k in case.creates if k not in before)):
        problems.append(f"loss: files left by a refused command {(new or list(case.creates))[:4]}")
    elif new and not refused:
        unexpected = [k for k in new if not k.endswith(("-wal", "-shm"))]
        if unexpected:
            problems.append(f"loss: unexpected files {unexpected[:4]}")
    for f in case.forbid:
        if (ws / f).exists():
            problems.append(f"loss: {f} exists (code from a data file ran)")
    if outcome.rc is not None and not any(p.startswith("traceback") for p in problems):
        if outcome.rc != case.rc:
            if case.rc in (2, 3) and outcome.rc in (0, 1):
                problems.append(f"accepted: exit {outcome.rc}, expected {case.rc}")
            else:
                problems.append(f"code: exit {outcome.rc}, expected {case.rc}: "
                                f"{outcome.err.strip()[-200:]}")
        elif case.msg and not re.search(case.msg, text, re.IGNORECASE | re.DOTALL):
            problems.append(f"message: {outcome.err.strip()[-300:]!r} does not match "
                            f"{case.msg!r}")
    return problems


def classify(problems: list[str]) -> str:
    """The one category a case counts under in the tally (worst first)."""
    for kind in ("traceback", "loss", "accepted", "code", "message"):
        if any(p.startswith(kind) for p in problems):
            return kind
    return "ok"
