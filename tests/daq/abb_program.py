"""The ABB tests' cell and program: the built-in IRB 2600-12/1.65 with hidden errors (the
simulated IRC5 moves it), and a RAPID module of taught targets as a teach pendant would
save it: where the nominal controller puts the tool at given joints, as ``robtarget``s
(position, quaternion, the robconf of those joints) moved to with ``MoveL ... fine`` and
the SMR's ``tooldata``. docs/abb.md's example (examples/abb_taught.mod) was made with
:func:`taught_module`."""

from __future__ import annotations

import numpy as np

from calibration import load_model
from calibration.compensation.pose_compensation import NominalTcpFK
from cellcal.programs.poses import T_to_rapid
from sim_drivers.model_truth import ModelTruth

MODEL = "irb2600_12_165"
TOOL_MM = (0.0, 0.0, 60.0)  # the SMR on its holder


def controller_model():
    """The nominal IRB 2600 as the simulated controller knows it (SMR on a 60 mm holder)."""
    return load_model(MODEL).with_changes(tool=TOOL_MM)


def irb2600_truth(seed: int, hidden: str | None) -> ModelTruth:
    """``truth_factory`` of the simulated cell: the IRB 2600 with hidden errors."""
    return ModelTruth.from_spec(MODEL, hidden, seed, tool_mm=TOOL_MM)


def robconf(q_rad: np.ndarray) -> list[int]:
    """cf1, cf4, cf6 (the quadrants of axes 1, 4 and 6: floor(angle / 90 deg)) and cfx
    (its lowest bit: axis 5 negative), as the controller records a taught target."""
    deg = np.degrees(q_rad)
    return [int(np.floor(deg[0] / 90.0)), int(np.floor(deg[3] / 90.0)),
            int(np.floor(deg[5] / 90.0)), int(deg[4] < 0)]


def taught_module(model, q_rad: np.ndarray, name: str = "AbbTaught",
                  title: str = "taught targets") -> str:
    """The module's text: one ``CONST robtarget`` per row of ``q_rad`` (n, 6), the tool
    the model's (``tSmr``), moved to in order, fine."""
    tool = model.tool_mm()
    fk = NominalTcpFK(model, tool).chain(np.asarray(q_rad, float))
    lines = [f"MODULE {name}", f"  ! {title}: the SMR on its holder (tSmr), base frame wobj0",
             f"  PERS tooldata tSmr:=[TRUE,[[{tool[0]:g},{tool[1]:g},{tool[2]:g}],[1,0,0,0]],"
             "[0.5,[0,0,20],[1,0,0,0],0,0,0]];"]
    for k, q in enumerate(np.asarray(q_rad, float)):
        T = np.eye(4)
        T[:3, :3], T[:3, 3] = fk.base_R_flange[k], fk.base_p_tcp[k]
        x, y, z, *quat = T_to_rapid(T)
        cf = ",".join(str(c) for c in robconf(q))
        lines.append(f"  CONST robtarget p{k + 1}:=[[{x:.2f},{y:.2f},{z:.2f}],"
                     f"[{','.join(f'{v:.7f}' for v in quat)}],[{cf}],"
                     "[9E+09,9E+09,9E+09,9E+09,9E+09,9E+09]];")
    lines += ["", "  PROC main()"]
    lines += [f"    MoveL p{k + 1}, v200, fine, tSmr;" for k in range(len(q_rad))]
    lines += ["  ENDPROC", "ENDMODULE", ""]
    return "\n".join(lines)
