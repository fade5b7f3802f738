"""Compensate a robot program with a calibration: read, solve, write back, report.

:func:`compensate_program` is what ``cellcal compensate --program`` runs: it reads a
URScript (``.script``, ``.urscript``, ``.txt``), KRL ``.dat`` or RAPID (``.mod``,
``.modx``, ``.sys``, ``.sysx``) file, compensates every target it can
(:func:`calibration.compensation.pose_compensation.compensate_targets`: joint targets by
the full model, pose targets near their neighbouring joint targets with the active TCP),
writes the result atomically, and returns a :class:`ProgramReport` (what the command
prints, and its exit code: 1 when something could not be compensated, unless
``allow_partial``). A TCP at the calibration's tool (the SMR it measured) carries the
identified point; any other TCP rides on the calibration's view of the flange (the report
says which). :func:`solve` is shared with ``cellcal validate``. Units are converted here,
at the edge: URScript m and rad, KRL and RAPID mm and deg; the core works in mm and rad.
"""

from __future__ import annotations

from dataclasses import dataclass, field, fields, replace
from pathlib import Path

import numpy as np

from calibration.compensation.controller_joints import ControllerJoints, controller_joints
from calibration.compensation.pose_compensation import neighbour_seeds
from calibration.files import read_input, write_atomic
from calibration.fit.envelope import Envelope, outside_envelope, refuse_outside
from calibration.fit.thermal_state import target_state

from . import krl, rapid, urscript
from .poses import T_to_krl, T_to_rapid, T_to_ur, krl_to_T, rapid_to_T, ur_to_T
from .program_report import ProgramReport, target_row
from .targets import Correction, Program, ProgramError, Refusal, Target

#: a 6-axis arm's usual working configuration (deg), the seed when a program has no joints
DEFAULT_SEED_DEG = {"urscript": (0.0, -90.0, 90.0, -90.0, -90.0, 0.0),
                    "krl": (0.0, -90.0, 90.0, 0.0, 45.0, 0.0),
                    "rapid": (0.0, 0.0, 0.0, 0.0, 30.0, 0.0)}


@dataclass(frozen=True)
class Dialect:
    """A language's reader, writer and units; ``check`` (target, nominal joints,
    compensated joints) -> why the compensation is not the configuration the target asks
    for, or None; ``seeds`` (targets, seed joints rad) -> the seeds the targets'
    configuration data make, tried for those the neighbours' seeds leave in another
    configuration."""

    name: str
    parse: object
    rewrite: object
    to_T: object
    from_T: object
    joint_unit: float  # rad per unit of a joint value
    seeds: object = None
    check: object = None


DIALECTS = {
    "urscript": Dialect("urscript", urscript.parse_program, urscript.rewrite, ur_to_T, T_to_ur,
                        1.0),
    "krl": Dialect("krl", krl.parse_program, krl.rewrite, krl_to_T, T_to_krl, np.pi / 180.0),
    "rapid": Dialect("rapid", rapid.parse_program, rapid.rewrite, rapid_to_T, T_to_rapid,
                     np.pi / 180.0, rapid.seeds, rapid.configuration),
}
SUFFIXES = {".script": "urscript", ".urscript": "urscript", ".txt": "urscript", ".dat": "krl",
            ".mod": "rapid", ".modx": "rapid", ".sys": "rapid", ".sysx": "rapid"}
#: files that are no program text of a known language, and what to do instead
NOT_TEXT = {
    ".urp": "a PolyScope program (.urp) is not URScript text; save it as a .script file "
            "(PolyScope writes one beside it)",
    ".pgf": "a RAPID program file (.pgf) lists the program's modules: compensate each "
            "module (.mod, .modx)",
    ".prg": "an S4 RAPID program (.prg): save its modules as .mod files (RobotStudio, or "
            "the controller's Save Module)",
}


@dataclass
class Options:
    """What a program does not say: the configuration seed (rad), the thermal state and
    payload (when the model has them), KRL's tools and bases by number (X, Y, Z, A, B, C)."""

    seed: np.ndarray | None = None
    temp_c: float | None = None
    payload_kg: float | None = None
    tools: dict[int, tuple] = field(default_factory=dict)
    bases: dict[int, tuple] = field(default_factory=dict)
    #: the calibration's thermal record (params.json ``thermal``): a program gives no joint
    #: temperatures nor times, so a drift effect is compensated at its warm state
    thermal: dict | None = None


def language_of(path: str | Path, language: str | None = None) -> Dialect:
    if language:
        return DIALECTS[language]
    suffix = Path(path).suffix.lower()
    if suffix in NOT_TEXT:
        raise ProgramError(f"{path}: {NOT_TEXT[suffix]}")
    if suffix not in SUFFIXES:
        raise ProgramError(f"{path}: cannot tell the program's language from {suffix!r}; "
                           f"known: {', '.join(sorted(SUFFIXES))}")
    return DIALECTS[SUFFIXES[suffix]]


def read_program(path: str | Path, dialect: Dialect) -> Program:
    """A program file, parsed. Bytes that are not UTF-8 (a KRL file in Windows-1252) pass
    through unchanged (surrogate escapes), as does a byte-order mark."""
    raw = read_input(path, ProgramError, "program", 50 << 20)
    if b"\x00" in raw[:4096]:
        raise ProgramError(f"{path}: a binary file, not a program")
    return dialect.parse(raw.decode("utf-8", "surrogateescape"), str(path))


def _frames(program: Program, dialect: Dialect, options: Options):
    """Per target: the TCP (4x4, flange frame) and the base (4x4, robot base frame), or the
    reason they are unknown."""
    out = []
    for t in program.targets:
        tool = base = None
        if dialect.name == "krl":
            tool = options.tools.get(t.extra.get("tool_no"))
            base = options.bases.get(t.extra.get("base_no", 0), None)
            if t.kind == "pose" and t.extra.get("base_no", 0) and base is None:
                out.append(f"BASE_DATA[{t.extra['base_no']}] is not given")
                continue
            if "tool_no" in t.extra and tool is None:
                out.append(f"TOOL_DATA[{t.extra['tool_no']}] is not given")
                continue
        else:
            tool, base = t.tcp, t.extra.get("base")
        out.append((np.eye(4) if tool is None else dialect.to_T(tool),
                    np.eye(4) if base is None else dialect.to_T(base)))
    return out


#: a TCP this close (mm) to the calibration's tool is the point the calibration measured
MEASURED_TOL_MM = 1e-3


@dataclass
class Solved:
    """A program's targets solved (:func:`solve`): the targets used (program order), their
    bases (n, 4, 4), TCPs (n, 4, 4), which TCPs are the calibration's measured point, the
    joints of each controller variant
    (:class:`~calibration.compensation.controller_joints.ControllerJoints`)
    and the targets refused."""

    targets: list[Target]
    base: np.ndarray
    tcp: np.ndarray
    measured: np.ndarray
    joints: ControllerJoints | None
    refusals: list[Refusal]
    #: the thermal state compensated for (:func:`calibration.fit.thermal_state.target_state`),
    #: None for a model without drift effects
    thermal: dict | None = None


def solve(program: Program, dialect: Dialect, error_model, x, options: Options, *,
          geometric: bool = False) -> Solved:
    """The joints each controller uses for a parsed program's targets (``geometric``: the
    geometric-only controller's too); targets that cannot be solved are refused."""
    model = error_model.model
    N = model.n_joints
    refusals, use = [], []
    frames = _frames(program, dialect, options)
    for t, f in zip(program.targets, frames, strict=True):
        if isinstance(f, str):
            refusals.append(Refusal(t.line, t.context, f))
        elif t.kind == "joints" and len(t.values) != N:
            refusals.append(Refusal(t.line, t.context, f"{len(t.values)} joint values, the "
                                    f"model {model.name} has {N} joints"))
        else:
            use.append(t)
    if not use:
        empty = np.zeros((0, 4, 4))
        return Solved([], empty, empty, np.zeros(0, bool), None, refusals)
    n = len(use)
    is_pose = np.array([t.kind == "pose" for t in use])
    joints = np.zeros((n, N))
    joints[~is_pose] = np.reshape([np.asarray(t.values) * dialect.joint_unit for t in use
                                   if t.kind == "joints"], (-1, N))  # none: (0, N)
    default = (options.seed if options.seed is not None else
               np.radians(DEFAULT_SEED_DEG[dialect.name][:N] + (0.0,) * max(0, N - 6)))
    joints = neighbour_seeds(is_pose, joints, default)
    tcp = np.stack([frames[t.index][0] for t in use])
    base = np.stack([frames[t.index][1] for t in use])
    measured = np.linalg.norm(tcp[:, :3, 3] - model.tool_mm(), axis=1) < MEASURED_TOL_MM
    pose = np.broadcast_to(np.eye(4), (n, 4, 4)).copy()
    pose[is_pose] = [base[i] @ dialect.to_T(t.values) for i, t in enumerate(use) if is_pose[i]]
    columns = {}
    if options.temp_c is not None:
        columns["temp_c"] = np.full(n, float(options.temp_c))
    payload = [t.payload_kg if t.payload_kg is not None else options.payload_kg for t in use]
    if any(p is not None for p in payload):
        columns["payload_kg"] = np.array([0.0 if p is None else p for p in payload])
    # a drift effect's joint temperatures and time: the calibration's warm state (a program
    # runs on a robot that has warmed up), as for a targets CSV without them
    columns, thermal = target_state(error_model, options.thermal, columns, n)

    def run(seeds: np.ndarray) -> ControllerJoints:
        return controller_joints(error_model, x, seeds, pose=pose, is_pose=is_pose,
                                 flange_T_tcp=tcp, measured=measured, columns=columns,
                                 geometric=geometric)

    cj = run(joints)
    if dialect.seeds is not None:  # the configuration the program asks for, if not found
        retry = [i for i in np.flatnonzero(is_pose) if _off(dialect, use[i], cj, i)]
        if retry:
            again = run(dialect.seeds(use, joints))
            cj = _take_rows(cj, again, [i for i in retry if not _off(dialect, use[i], again, i)])
    return Solved(use, base, tcp, measured, cj, refusals, thermal)


def _off(dialect: Dialect, t: Target, cj: ControllerJoints, i: int) -> bool:
    """Target i not reached, or not in the configuration it asks for."""
    c = cj.compensation
    return not c.success[i] or bool(dialect.check(t, c.q_nominal[i], c.q[i]))


def _take_rows(a: ControllerJoints, b: ControllerJoints, rows: list[int]) -> ControllerJoints:
    """``a`` with the given target rows taken from ``b`` (same targets, other seeds)."""
    if not rows:
        return a
    n = len(a.compensation.q)

    def mix(u, v):
        if isinstance(v, np.ndarray) and v.shape[:1] == (n,):
            u = u.copy()
            u[rows] = v[rows]
        return u

    comp = replace(a.compensation, **{f.name: mix(getattr(a.compensation, f.name),
                                                  getattr(b.compensation, f.name))
                                      for f in fields(a.compensation)})
    return ControllerJoints(comp, {k: mix(v, b.joints[k]) for k, v in a.joints.items()},
                            {k: mix(v, b.success[k]) for k, v in a.success.items()})


def tcp_notes(solved: Solved, model) -> list[str]:
    """What the report says about the TCPs: the measured point's identified position is
    used; any other TCP rides on the calibration's view of the flange."""
    notes, seen = [], set()
    for t, m, T in zip(solved.targets, solved.measured, solved.tcp, strict=True):
        key = (bool(m), tuple(np.round(T[:3, 3], 3)))
        if key in seen:
            continue
        seen.add(key)
        xyz = ", ".join(f"{v:g}" for v in np.round(T[:3, 3], 3))
        if m:
            notes.append(f"line {t.line}: the TCP ({xyz} mm) is the point the calibration "
                         "measured: its identified position is used")
        else:
            notes.append(f"line {t.line}: the TCP ({xyz} mm) is not the point the "
                         f"calibration measured ({', '.join(f'{v:g}' for v in model.tool_mm())}"
                         " mm): it is compensated as well as the calibration knows the "
                         "flange (docs/programs.md)")
    return notes


def solved_outside(solved: Solved, envelope: Envelope | None, options: Options
                   ) -> list[list[str]]:
    """Per solved target, the quantities beyond the calibrated envelope: the joints the
    robot is sent and the air temperature the program is compensated for (``--temp-c``)."""
    if solved.joints is None:
        return []
    q = solved.joints.compensation.q
    columns = {} if options.temp_c is None else {"temp_c": np.full(len(q), options.temp_c)}
    return outside_envelope(envelope, q, columns)


def corrections(solved: Solved, dialect: Dialect, outside: list[list[str]] | None = None
                ) -> tuple[dict[int, Correction], list[dict], list[Refusal]]:
    """The new values of a solved program's targets; (corrections, report rows, refusals:
    the solved ones' and those the calibrated robot cannot reach). ``outside``: per solved
    target, what lies beyond the calibrated envelope (in the rows)."""
    refusals = list(solved.refusals)
    out, rows = {}, []
    if solved.joints is None:
        return out, rows, refusals
    c = solved.joints.compensation
    for i, t in enumerate(solved.targets):
        if not c.success[i]:
            refusals.append(Refusal(t.line, t.context, "the calibrated robot cannot reach it "
                                    "(out of reach or at a singularity)"))
            continue
        why = dialect.check and dialect.check(t, c.q_nominal[i], c.q[i])
        if why:
            refusals.append(Refusal(t.line, t.context, why))
            continue
        if t.kind == "pose":
            values = dialect.from_T(np.linalg.inv(solved.base[i]) @ c.cmd[i], near=t.values)
        else:
            values = tuple(float(v) for v in c.q[i] / dialect.joint_unit)
        out[t.index] = Correction(values, float(c.correction_mm[i]))
        rows.append(target_row(t, c, i, outside[i] if outside else None))
    return out, rows, refusals


def compensate_program(path: str | Path, error_model, x, out: str | Path, *,
                       allow_partial: bool = False, language: str | None = None,
                       options: Options | None = None, envelope: Envelope | None = None,
                       strict_range: bool = False) -> ProgramReport:
    """Read the program at ``path``, compensate it with the calibration ``(error_model,
    x)`` (e.g. :func:`calibration.exports.params_io.read_params`), write it to ``out`` atomically
    and report. Nothing is written when a target cannot be compensated, unless
    ``allow_partial`` (those targets stay as they were and are listed); a program a
    previous compensation wrote is refused (it would be compensated twice). Targets
    beyond the calibration's ``envelope`` are named in the report (``outside_range``);
    with ``strict_range`` they are refused (OutsideEnvelope, exit 3; nothing written)."""
    dialect = language_of(path, language)
    program = read_program(path, dialect)
    if program.compensated_at is not None:
        raise ProgramError(f"{path}: line {program.compensated_at}: this program was "
                           "compensated already (a 'cellcal:' comment); compensate the "
                           "original")
    options = options or Options()
    solved = solve(program, dialect, error_model, x, options)
    outside = solved_outside(solved, envelope, options)
    if strict_range:
        refuse_outside(outside, [f"line {t.line}" for t in solved.targets], "targets",
                       str(path))
    new, rows, refused = corrections(solved, dialect, outside)
    refusals = sorted(program.refusals + refused, key=lambda r: r.line)
    notes = program.notes + tcp_notes(solved, error_model.model)
    if solved.thermal is not None:
        from presentation.thermal_text import state_line

        notes.append(f"thermal: {state_line(solved.thermal)}")
    report = ProgramReport(str(path), str(out), dialect.name, len(program.targets), rows,
                           refusals, notes)
    if not refusals or allow_partial:
        text = dialect.rewrite(program, new)
        write_atomic(out, text.encode("utf-8", "surrogateescape"))
        report.written = True
    return report
