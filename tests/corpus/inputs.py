"""The bad inputs of the corpus: each a function that writes one file (or folder) into a
case's workspace copy, made from the workspace's good files (:mod:`tests.corpus.workspace`).

Families: CSV tables (measurement, targets, postures), params.json, model YAML, run stores,
register maps and effect files. Names are ``family:variant``; :data:`INPUTS` maps a name to
``(file name written, writer)``.
"""

from __future__ import annotations

import hashlib
import json
import math
import os
import random
import sqlite3
from collections.abc import Callable
from pathlib import Path

# --------------------------------------------------------------------------- CSV


class Table:
    """A CSV file as metadata lines, a header and rows of text fields."""

    def __init__(self, text: str) -> None:
        lines = [ln for ln in text.splitlines() if ln.strip()]
        self.meta = [ln for ln in lines if ln.startswith("#")]
        body = [ln.split(",") for ln in lines if not ln.startswith("#")]
        self.header, self.rows = body[0], body[1:]

    def col(self, name: str) -> int:
        return self.header.index(name)

    def set(self, row: int, name: str, value: str) -> Table:
        self.rows[row][self.col(name)] = value
        return self

    def drop(self, name: str) -> Table:
        k = self.col(name)
        self.header = self.header[:k] + self.header[k + 1:]
        self.rows = [r[:k] + r[k + 1:] for r in self.rows]
        return self

    def add(self, name: str, values) -> Table:
        self.header = [*self.header, name]
        self.rows = [[*r, str(v)] for r, v in zip(self.rows, values, strict=False)]
        return self

    def text(self, sep: str = ",", eol: str = "\n") -> str:
        lines = self.meta + [sep.join(self.header)] + [sep.join(r) for r in self.rows]
        return eol.join(lines) + eol


def _table(ws: Path, src: str) -> Table:
    return Table((ws / src).read_text())


def _write(ws: Path, name: str, data: str | bytes) -> None:
    p = ws / name
    p.parent.mkdir(parents=True, exist_ok=True)
    if isinstance(data, bytes):
        p.write_bytes(data)
    else:
        p.write_bytes(data.encode("utf-8"))


def _rand_bytes(n: int, seed: int = 0) -> bytes:
    return random.Random(seed).randbytes(n)


def csv_variants(src: str, measurement: bool, cols: tuple[str, str, str] = ("x", "y", "z")
                 ) -> dict[str, Callable[[Path], str | bytes]]:
    """Bad (and a few tolerable) variants of the CSV ``src``: name -> content maker.

    ``cols``: three numeric columns of the file the variants damage."""
    first_num, c2, c3 = cols

    def t(ws):
        return _table(ws, src)

    v: dict[str, Callable] = {
        "empty": lambda ws: b"",
        "blank": lambda ws: "\n  \n\n",
        "comments_only": lambda ws: "# tracker_sigma_mm: 0.015\n# note: nothing else\n",
        "header_only": lambda ws: ",".join(t(ws).header) + "\n",
        "no_x": lambda ws: t(ws).drop(first_num).text(),
        "no_q3": lambda ws: t(ws).drop("q3").text(),
        "dup_col": lambda ws: (lambda tb: (tb.header.__setitem__(tb.col(c2), first_num),
                                           tb.text())[1])(t(ws)),
        "nan": lambda ws: t(ws).set(2, first_num, "nan").text(),
        "inf": lambda ws: t(ws).set(2, first_num, "inf").text(),
        "neg_inf": lambda ws: t(ws).set(2, "q2", "-inf").text(),
        "overflow": lambda ws: t(ws).set(2, first_num, "1e999").text(),
        "text_value": lambda ws: t(ws).set(3, "q1", "abc").text(),
        "empty_value": lambda ws: t(ws).set(3, c3, "").text(),
        "hex_value": lambda ws: t(ws).set(3, c3, "0x1F").text(),
        "short_row": lambda ws: (lambda tb: (tb.rows[1].pop(), tb.text())[1])(t(ws)),
        "long_row": lambda ws: (lambda tb: (tb.rows[1].append("7"), tb.text())[1])(t(ws)),
        "semicolons": lambda ws: t(ws).text(sep=";"),
        "tabs": lambda ws: t(ws).text(sep="\t"),
        "binary": lambda ws: _rand_bytes(4096, 1),
        "latin1": lambda ws: t(ws).set(0, "pose_id", "caf\xe9").text().encode("latin-1"),
        "nul": lambda ws: t(ws).set(0, "pose_id", "a\x00b").text(),
        "huge_field": lambda ws: t(ws).set(0, "pose_id", "p" * 200_000).text(),
        "dup_id": lambda ws: (lambda tb: (tb.set(1, "pose_id", tb.rows[0][tb.col("pose_id")]),
                                          tb.text())[1])(t(ws)),
        "utf16": lambda ws: t(ws).text().encode("utf-16"),
        "huge_xyz": lambda ws: t(ws).set(2, c2, "1e300").text(),
        # tolerable: must be read as the good file
        "ok_bom": lambda ws: b"\xef\xbb\xbf" + t(ws).text().encode(),
        "ok_crlf": lambda ws: t(ws).text(eol="\r\n"),
    }
    if measurement:
        def rows(ws, k):
            tb = t(ws)
            tb.rows = tb.rows[:k]
            return tb

        def radians(ws):
            tb = t(ws)
            for r in tb.rows:
                for j in range(6):
                    k = tb.col(f"q{j + 1}")
                    r[k] = repr(math.radians(float(r[k])))
            return tb.text()

        def identical(ws):
            tb = t(ws)
            r0 = tb.rows[0]
            tb.rows = []
            for i in range(100):
                r = list(r0)
                r[tb.col("pose_id")] = f"p{i}"
                r[tb.col("x")] = repr(float(r0[tb.col("x")]) + 0.01 * math.sin(i))
                if "set" in tb.header:
                    r[tb.col("set")] = "calib"
                tb.rows.append(r)
            return tb.text()

        def all_valid(ws):
            tb = t(ws)
            k = tb.col("set")
            for r in tb.rows:
                r[k] = "valid"
            return tb.text()

        def calib_rows(ws, k):
            tb = t(ws)
            tb.rows = [r for r in tb.rows if r[tb.col("set")] == "calib"][:k]
            return tb.text()

        v.update({
            "one_pose": lambda ws: calib_rows(ws, 1),
            "five_poses": lambda ws: calib_rows(ws, 5),
            "eight_poses": lambda ws: calib_rows(ws, 8),
            "identical_100": identical,
            "radians": radians,
            "all_valid": all_valid,
            "out_of_limits": lambda ws: t(ws).set(4, "q2", "400").text(),
            "bad_set": lambda ws: t(ws).set(4, "set", "train").text(),
            "sigma_neg": lambda ws: t(ws).add("sigma_mm", ["-0.01"] * 200).text(),
            "sigma_nan": lambda ws: t(ws).add("sigma_mm", ["nan"] * 200).text(),
            "payload_neg": lambda ws: t(ws).add("payload_kg", ["-5"] * 200).text(),
            "temp_absurd": lambda ws: t(ws).add("temp_c", ["1e6"] * 200).text(),
            "meta_sigma_text": lambda ws: "# tracker_sigma_mm: fifteen\n" + t(ws).text(),
            "meta_sigma_neg": lambda ws: "# tracker_sigma_mm: -1\n" + t(ws).text(),
            "bad_dir": lambda ws: (lambda tb: [tb.add(f"dir{j}", ["1"] * 200)
                                               for j in range(1, 7)][-1].set(2, "dir3", "2")
                                   .text())(t(ws)),
            "half_dirs": lambda ws: t(ws).add("dir1", ["1"] * 200).text(),
            "cmd_partial": lambda ws: t(ws).add("cmd_x", ["1"] * 200).text(),
            "ok_extra_col": lambda ws: t(ws).add("reflector", ["RRR1.5"] * 200).text(),
        })
        del rows
    return v


# -------------------------------------------------------------------- params.json


def _params(ws: Path, name: str = "params.json") -> dict:
    return json.loads((ws / name).read_text())


def _dump(d) -> str:
    return json.dumps(d, indent=1)


def _mut(fn):
    def make(ws):
        d = _params(ws)
        fn(d)
        return _dump(d)
    return make


EVIL_PY = """from pathlib import Path
Path(__file__).with_name("PWNED").write_text("code from a data file ran")
"""


def _sha(text: str) -> str:
    return hashlib.sha256(text.encode()).hexdigest()


def _row(d, name_part="geometric.j2.a"):
    return next(r for r in d["parameters"] if r["name"] == name_part)


def params_variants() -> dict[str, Callable[[Path], str | bytes]]:
    def evil(ws, entry):
        (ws / "evil.py").write_text(EVIL_PY)
        d = _params(ws)
        d["effect_files"] = [entry(ws)]
        return _dump(d)

    return {
        "empty": lambda ws: b"",
        "not_json": lambda ws: "model: ur5\n",
        "truncated": lambda ws: (ws / "params.json").read_text()[:500],
        "array": lambda ws: "[1, 2, 3]\n",
        "wrong_format": _mut(lambda d: d.__setitem__("format", "something-else")),
        "future_version": _mut(lambda d: d.__setitem__("version", 99)),
        "nan_value": lambda ws: (ws / "params.json").read_text().replace(
            f'"value": {_row(_params(ws))["value"]!r}', '"value": NaN', 1),
        "inf_value": lambda ws: (ws / "params.json").read_text().replace(
            f'"value": {_row(_params(ws))["value"]!r}', '"value": Infinity', 1),
        "huge_value": _mut(lambda d: _row(d).__setitem__("value", 1e300)),
        "string_value": _mut(lambda d: _row(d).__setitem__("value", "0.1")),
        "null_value": _mut(lambda d: _row(d).__setitem__("value", None)),
        "bool_value": _mut(lambda d: _row(d).__setitem__("value", True)),
        "missing_value": _mut(lambda d: _row(d).pop("value")),
        "neg_std": _mut(lambda d: _row(d).__setitem__("std", -1.0)),
        "no_parameters": _mut(lambda d: d.pop("parameters")),
        "null_parameters": _mut(lambda d: d.__setitem__("parameters", None)),
        "no_model_definition": _mut(lambda d: d.pop("model_definition")),
        "no_effects": _mut(lambda d: d.pop("effects")),
        "unknown_effect": _mut(lambda d: d.__setitem__("effects", ["geometric", "base",
                                                                   "nosuch"])),
        "missing_row": _mut(lambda d: d["parameters"].pop(3)),
        "unknown_row": _mut(lambda d: d["parameters"].append(
            {"name": "geometric.j9.a", "value": 0.0, "std": 0.0, "unit": "mm",
             "identifiable": True})),
        "wrong_unit": _mut(lambda d: _row(d).__setitem__("unit", "in")),
        "model_nan": _mut(lambda d: d["model_definition"]["joints"][1].__setitem__(
            "a", float("nan"))),
        "model_tampered": _mut(lambda d: d["model_definition"]["joints"][1].__setitem__(
            "a", d["model_definition"]["joints"][1]["a"] + 5.0)),
        "other_model": lambda ws: (ws / "params_ur10e.json").read_text(),
        "binary": lambda ws: _rand_bytes(2048, 2),
        "latin1": lambda ws: (ws / "params.json").read_text().replace(
            '"solver": "lm"', '"solver": "lm", "note": "caf\xe9"').encode("latin-1"),
        # code in a data file: must never run (the case also checks no PWNED file appears)
        "evil_effect_path": lambda ws: evil(ws, lambda ws: "evil.py"),
        "evil_effect_abs": lambda ws: evil(ws, lambda ws: str((ws / "evil.py").resolve())),
        "evil_effect_record": lambda ws: evil(ws, lambda ws: {
            "name": "evil.py", "sha256": _sha(EVIL_PY), "families": ["evil"]}),
        # tolerable: a version-1 file (no version-2 keys) still loads
        "ok_v1": _mut(lambda d: [d.pop(k, None) for k in ("model_hash", "weak")]
                      and d.__setitem__("version", 1)),
    }


# --------------------------------------------------------------------- model YAML


def model_variants() -> dict[str, Callable[[Path], str | bytes]]:
    def edit(old, new):
        def make(ws):
            text = (ws / "model.yaml").read_text()
            assert old in text, old
            return text.replace(old, new, 1)
        return make

    good_first = "- {a: 0.0, alpha: 90.0, d: 89.159"
    return {
        "empty": lambda ws: b"",
        "list": lambda ws: "- 1\n- 2\n",
        "scalar": lambda ws: "ur5\n",
        "syntax": lambda ws: "name: [ur5\njoints: {\n",
        "nan": edit("a: -425.0", "a: .nan"),
        "inf": edit("a: -425.0", "a: .inf"),
        "huge": edit("a: -425.0", "a: 1e300"),
        "bool_min": edit("min: -360.0", "min: true"),
        "string_a": edit("a: -425.0", "a: long"),
        "min_gt_max": edit("min: -360.0", "min: 400.0"),
        "no_joints": lambda ws: "name: x\nconvention: dh\n",
        "zero_joints": lambda ws: "name: x\nconvention: dh\njoints: []\n",
        "unknown_field": edit("name: ur5", "name: ur5\ncolour: blue"),
        "bad_convention": edit("convention: dh", "convention: dhx"),
        "neg_payload": lambda ws: (ws / "model.yaml").read_text()
        + "payload: {mass_kg: -5.0, com: [0, 0, 50]}\n",
        "nan_tool": lambda ws: (ws / "model.yaml").read_text().replace(
            "tool: [0.0, 0.0, 0.0]", "tool: [0.0, .nan, 0.0]"),
        "huge_gravity": lambda ws: (ws / "model.yaml").read_text().replace(
            "gravity: [0.0, 0.0, -9.81]", "gravity: [0.0, 0.0, -9.81e9]"),
        "non_utf8": lambda ws: ((ws / "model.yaml").read_text().replace(
            "name: ur5", "name: ur5-caf\xe9")).encode("latin-1"),
        "binary": lambda ws: _rand_bytes(1024, 3),
        "dup_key": edit("name: ur5", "name: ur5\nname: ur10e"),
        "huge_name": edit("name: ur5", "name: " + "u" * 100_000),
        "seven_joints": lambda ws: (ws / "model.yaml").read_text().replace(
            "joints:\n", "joints:\n" + good_first + ", theta_offset: 0.0, beta: 0.0, "
            "min: -360.0, max: 360.0}\n", 1),
    }


# ----------------------------------------------------------------------- run stores


def _sqlite(ws: Path, name: str, script: str, user_version: int = 0) -> None:
    path = ws / name
    con = sqlite3.connect(path)
    con.executescript(script)
    con.execute(f"PRAGMA user_version={user_version}")
    con.commit()
    con.close()


def store_variants() -> dict[str, Callable[[Path], str | bytes | None]]:
    def foreign(ws, name):
        _sqlite(ws, name, "CREATE TABLE invoices (id INTEGER PRIMARY KEY, total REAL);"
                "INSERT INTO invoices VALUES (1, 99.5);")

    def newer(ws, name):
        data = (ws / "cell.db").read_bytes()
        (ws / name).write_bytes(data)
        con = sqlite3.connect(ws / name)
        con.execute("PRAGMA user_version=99")
        con.commit()
        con.close()

    def runs_no_version(ws, name):
        _sqlite(ws, name, "CREATE TABLE runs (id INTEGER PRIMARY KEY, note TEXT);")

    def versioned_foreign(ws, name):
        _sqlite(ws, name, "CREATE TABLE stuff (a);", user_version=3)

    def truncated(ws, name):
        data = (ws / "cell.db").read_bytes()
        (ws / name).write_bytes(data[: len(data) // 3])

    def zeroed_pages(ws, name):
        data = bytearray((ws / "cell.db").read_bytes())
        data[4096:16384] = bytes(12288)
        (ws / name).write_bytes(bytes(data))

    return {
        "text": lambda ws, name: _write(ws, name, "this is not a database\n"),
        "binary": lambda ws, name: _write(ws, name, _rand_bytes(8192, 4)),
        "empty": lambda ws, name: _write(ws, name, b""),
        "truncated": truncated,
        "zeroed": zeroed_pages,
        "header_only": lambda ws, name: _write(ws, name, (ws / "cell.db").read_bytes()[:100]),
        "foreign": foreign,
        "versioned_foreign": versioned_foreign,
        "runs_no_version": runs_no_version,
        "newer": newer,
        "csv": lambda ws, name: _write(ws, name, (ws / "good.csv").read_text()),
    }


# ------------------------------------------------------------------- register maps


def register_map_variants() -> dict[str, str | bytes]:
    return {
        "not_mapping": "- 1\n",
        "syntax": "command: [\n",
        "unknown_field": "comand: 0\n",
        "negative": "command: -1\n",
        "string": "speed: fast\n",
        "overlap": "command: 0\ncommand_seq: 0\n",
        "bits": "bits: {busy: 99}\n",
        "word_order": "word_order: middle\n",
        "binary": _rand_bytes(512, 5),
        "n_joints": "n_joints: 0\n",
    }


# ------------------------------------------------------------------------ cell YAML


def cell_variants() -> dict[str, str | bytes]:
    return {
        "empty_list": "- 1\n",
        "syntax": "tracker: [\n",
        "unknown_key": "trackre: {position: [2500, 0, 500]}\n",
        "zero_axis": "smr: {axis: [0, 0, 0]}\n",
        "unknown_reflector": "smr: {reflector: bogus}\n",
        "nan_position": "tracker: {position: [.nan, 0, 500]}\n",
        "two_shapes": ("fixtures:\n  - name: t\n    box: {centre: [0, 0, 0], size: [1, 1, 1]}\n"
                       "    cylinder: {start: [0, 0, 0], end: [0, 0, 1], radius: 1}\n"),
        "dup_key": "tracker: {position: [2500, 0, 500]}\ntracker: {position: [0, 0, 0]}\n",
        "binary": _rand_bytes(512, 7),
        "latin1": "smr: {reflector: 'r\u00e9flecteur'}\n".encode("latin-1"),
    }


# ---------------------------------------------------------------------- effect files


def effect_file_variants() -> dict[str, str | bytes]:
    return {
        "syntax": "def (:\n",
        "raises": "raise RuntimeError('boom')\n",
        "no_effect": "x = 1\n",
        "replaces_builtin": (
            "import numpy as np\nfrom calibration.effects.geometric import Tool\n\n"
            "class Evil(Tool):\n    family = 'geometric'\n"),
        "bad_family": (
            "from calibration.effects import JointEffect\n\n"
            "class Bad(JointEffect):\n    family = 'Bad-Name'\n"),
        "binary": _rand_bytes(256, 6),
    }


def fifo(ws: Path, name: str) -> None:
    os.mkfifo(ws / name)
