"""The corpus's cases for robot programs: ``compensate --program`` and ``validate`` over bad
programs, frames files, numbers and outputs (refused before anything is written or moved).

The workspace's ur5 calibration (params.json) compensates a short URScript program that
each case writes (:data:`PROGRAM`); ``validate`` is refused before any device is opened.
"""

from __future__ import annotations

from .cases import (
    DIRECTORY,
    IS_INPUT,
    IS_STORE,
    MISSING,
    NO_FOLDER,
    NOT_NUMBER,
    Case,
    _number_cases,
    mkdir,
    narrowed_params,
    write,
)

#: a good program for the ur5 of the workspace: the TCP, a joint and two pose targets
PROGRAM = """def prog():
  set_tcp(p[0, 0, 0.05, 0, 0, 0])
  movej([0, -1.5708, 1.5708, -1.5708, -1.5708, 0])
  movel(p[0.4, -0.1, 0.3, 0, 3.1416, 0], a=1.2, v=0.25)
  movel(pose_add(p[0.4, -0.1, 0.3, 0, 3.1416, 0], p[0, 0, 0.05, 0, 0, 0]))
end
"""
PROGRAMS = {
    "unbalanced": (PROGRAM.replace("0, 3.1416, 0], a", "0, 3.1416, 0, a"), r"line \d"),
    "unterminated_string": (PROGRAM.replace("end\n", 'textmsg("oops)\nend\n'), r"line \d"),
    "binary": (b"\x00\x01\x02def", r"binary"),
    "compensated_already": (PROGRAM.replace("v=0.25)", "v=0.25)  # cellcal: was x"),
                            r"compensated already"),
}
#: the same for an ABB RAPID module: the TCP at the flange, a joint and a pose target
RAPID = """MODULE Prog
  PERS tooldata tPen:=[TRUE,[[0,0,0],[1,0,0,0]],[0.3,[0,0,20],[1,0,0,0],0,0,0]];
  CONST jointtarget jHome:=[[0,-90,90,-90,-90,0],[9E+09,9E+09,9E+09,9E+09,9E+09,9E+09]];
  CONST robtarget pDown:=[[400,-100,300],[0,0,1,0],[0,0,-1,1],
                         [9E+09,9E+09,9E+09,9E+09,9E+09,9E+09]];
  PROC main()
    MoveAbsJ jHome, v500, z10, tPen;
    MoveL pDown, v200, fine, tPen;
  ENDPROC
ENDMODULE
"""
RAPIDS = {
    "rapid_unbalanced": (RAPID.replace("[0,0,-1,1],", "[0,0,-1,1,"), r"line 4"),
    "rapid_unterminated_string": (RAPID.replace("  ENDPROC", '    TPWrite "oops;\n  ENDPROC'),
                                  r"line 9: unterminated string"),
    "rapid_compensated_already": (RAPID.replace("tPen;\n  ENDPROC",
                                                "tPen;  ! cellcal: was x\n  ENDPROC"),
                                  r"compensated already"),
    "rapid_binary": (b"MODULE \x00\x01", r"binary"),
}
FRAMES = {
    "not_yaml": ("tools: [1, 2\n", r"frames.*yaml"),
    "list": ("- 1\n- 2\n", r"frames.*mapping"),
    "unknown_key": ("toolz: {1: [0, 0, 0, 0, 0, 0]}\n", r"frames.*tools"),
    "short_frame": ("tools: {1: [0, 0, 100]}\n", r"tools\[1\].*6"),
    "nan_frame": ("tools: {1: [0, 0, .nan, 0, 0, 0]}\n", r"tools\[1\]"),
    "bad_number": ("bases: {x: [0, 0, 0, 0, 0, 0]}\n", r"bases.*frame number"),
}


def program_cases() -> list[Case]:
    """The cases of ``compensate --program`` and ``validate``."""
    prog = write("prog.script", PROGRAM)
    made = ("out.script",)
    comp = ["compensate", "--params", "params.json", "--program", "prog.script",
            "--out", "out.script"]
    cases = [Case("compensate", "program:ok", comp, 0, "", [prog], creates=made)]
    for name, (body, msg) in PROGRAMS.items():
        cases.append(Case("compensate", f"program:{name}", comp, 2, msg,
                          [write("prog.script", body)], creates=made))
    rapid = [*comp[:4], "prog.mod", "--out", "out.mod"]
    cases.append(Case("compensate", "program:rapid_ok", rapid, 0, "", [write("prog.mod", RAPID)],
                      creates=("out.mod",)))
    for name, (body, msg) in RAPIDS.items():
        cases.append(Case("compensate", f"program:{name}", rapid, 2, msg,
                          [write("prog.mod", body)], creates=("out.mod",)))
    for suffix, msg in ((".pgf", r"program file \(\.pgf\).*each module"),
                        (".prg", r"S4 RAPID program \(\.prg\)")):
        cases.append(Case("compensate", f"program:rapid{suffix}",
                          [*comp[:4], f"prog{suffix}", "--out", "out.mod"], 2, msg,
                          [write(f"prog{suffix}", RAPID)], creates=("out.mod",)))
    cases += [
        Case("compensate", "program:missing", comp, 2, MISSING, creates=made),
        Case("compensate", "program:directory", comp, 2, DIRECTORY, [mkdir("prog.script")],
             creates=made),
        Case("compensate", "program:urp", [*comp[:4], "prog.urp", *comp[5:]], 2,
             r"polyscope|\.script", [copy_program("prog.urp")], creates=made),
        Case("compensate", "program:unknown_suffix", [*comp[:4], "prog.py", *comp[5:]], 2,
             r"language", [copy_program("prog.py")], creates=made),
        Case("compensate", "program:no_out", comp[:-2], 2, r"--out", [prog]),
        Case("compensate", "program:with_targets", [*comp, "targets.csv"], 2,
             r"does not go with", [prog], creates=made),
        Case("compensate", "program:with_export", [*comp, "--export-model", "m.yaml"], 2,
             r"does not go with", [prog], creates=(*made, "m.yaml")),
        Case("compensate", "program:flag_without_program",
             ["compensate", "targets.csv", "--params", "params.json", "--temp-c", "20"], 2,
             r"--temp-c.*only with --program"),
        Case("compensate", "program:bad_language", [*comp, "--language", "karel"], 2,
             r"language", [prog], creates=made),
        Case("compensate", "program:strict_outside",
             [*comp[:2], "narrow.json", *comp[3:], "--strict-range"], 3,
             r"beyond the calibrated envelope.*q2", [prog, write("narrow.json",
                                                               narrowed_params)],
             creates=made),
        Case("compensate", "program:outside_warned", [*comp[:2], "narrow.json", *comp[3:]], 0,
             r"warning: \d+ of \d+ targets lie beyond the calibrated envelope",
             [prog, write("narrow.json", narrowed_params)], creates=made),
        Case("compensate", "program:thermal_without_temp", [*comp[:2], "thermal.json",
                                                           *comp[3:]], 2, r"--temp-c",
             [prog, write("thermal.json", _thermal_params)], creates=made),
        # issue 36: a program gives no joint temperatures: the calibration's warm state
        Case("compensate", "seam:program_at_the_warm_state", [*comp[:2], "warm.json",
                                                              *comp[3:]], 0,
             r"thermal: joints 24\.0–27\.5 °C: the calibration's warm state",
             [prog, write("warm.json", _warm_params)], creates=made),
    ]
    cases += _number_cases("compensate", comp, [
        ("--temp-c", ["nan", "inf"]), ("--payload-kg", ["nan", "-1"]),
        ("--start", ["nan,0,0,0,0,0", "1,2,3"])], creates=made)
    for c in cases[-6:]:
        c.setup.insert(0, prog)
    for name, (body, msg) in FRAMES.items():
        cases.append(Case("compensate", f"frames:{name}", [*comp, "--frames", "f.yaml"], 2, msg,
                          [prog, write("f.yaml", body)], creates=made))
    cases.append(Case("compensate", "frames:missing", [*comp, "--frames", "nof.yaml"], 2,
                      MISSING, [prog], creates=made))
    for name, out, msg, setup in (
            ("is_program", "prog.script", IS_INPUT, []),
            ("is_params", "params.json", IS_INPUT, []),
            ("is_store", "cell.db", IS_STORE, []),
            ("directory", "adir", DIRECTORY, [mkdir("adir")]),
            ("no_folder", "nofolder/o.script", NO_FOLDER, [])):
        cases.append(Case("compensate", f"program_out:{name}", [*comp[:-1], out], 2, msg,
                          [prog, *setup]))
    return cases + validate_cases(prog)


def copy_program(name: str):
    """Setup: the good program under another name."""
    return write(name, PROGRAM)


def _thermal_params(ws) -> str:
    """params.json of a calibration with thermal growth (the workspace's, one effect more)."""
    import json

    doc = json.loads((ws / "params.json").read_text())
    doc["effects"] = [*doc["effects"], "thermal"]
    doc["parameters"].append({"name": "thermal.k", "value": 1e-5, "std": 1e-6,
                              "unit": "1/K", "identifiable": True, "weak": None})
    return json.dumps(doc)


def _warm_params(ws) -> str:
    """params.json with thermal growth over the joints' temperatures and the warm state it
    was fitted against (the workspace's, one effect and the ``thermal`` record more)."""
    import json

    doc = json.loads((ws / "params.json").read_text())
    doc["effects"] = [*doc["effects"], "thermal_growth"]
    doc["parameters"].append({"name": "thermal_growth.k", "value": 1.5e-5, "std": 1e-6,
                              "unit": "1/K", "identifiable": True, "weak": None})
    doc["thermal"] = {"version": 1, "temp_ref_c": 20.0,
                      "warm_state": {"joint_temp_c": [26.0, 27.5, 27.0, 25.0, 24.5, 24.0]}}
    return json.dumps(doc)


def validate_cases(prog) -> list[Case]:
    """``validate``: refused before any device is opened (no robot moves in the corpus)."""
    devices = ["--robot", "socket://127.0.0.1:9", "--tracker", "tracker+tcp://127.0.0.1:9"]
    val = ["validate", "--params", "params.json", "--program", "prog.script", "--db",
           "cell.db", *devices]
    new = [a if a != "cell.db" else "new.db" for a in val]
    cases = [
        Case("validate", "no_frame_run", new, 2, r"no measurement frame.*capture frame", [prog]),
        Case("validate", "neither_program_nor_targets",
             [a for a in new if a not in ("--program", "prog.script")], 2, r"one of them"),
        Case("validate", "program_and_targets", [*new, "targets.csv"], 2, r"one of them",
             [prog]),
        Case("validate", "params:missing", [*new[:2], "nop.json", *new[3:]], 2, MISSING,
             [prog]),
        Case("validate", "url:unknown_scheme", [*new[:-3], "ftp://127.0.0.1:9", *new[-2:]], 2,
             r"scheme|url", [prog]),
        Case("validate", "cycles:zero", [*new, "--cycles", "0"], 2, r"--cycles", [prog]),
        Case("validate", "strict_outside", [*val[:2], "narrow.json", *val[3:],
                                            "--strict-range"], 3,
             r"waypoints lie beyond the calibrated envelope.*q2",
             [prog, write("narrow.json", narrowed_params)]),
        Case("validate", "variants:bogus", [*new, "--variants", "compensated,bogus"], 2,
             r"--variants", [prog]),
        Case("validate", "variants:twice", [*new, "--variants", "compensated,compensated"], 2,
             r"--variants", [prog]),
    ]
    for name, (body, msg) in PROGRAMS.items():  # a compensated one too (issue 36: its
        cases.append(Case("validate", f"program:{name}", val, 2, msg,  # "compensated" variant
                          [write("prog.script", body)]))  # would be compensated twice)
    cases += _number_cases("validate", val, [("--temp-c", ["nan"])])
    cases[-1].setup.insert(0, prog)
    return cases


__all__ = ["NOT_NUMBER", "program_cases"]
