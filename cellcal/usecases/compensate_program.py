"""``compensate --program``: a robot program rewritten so that the real robot reaches what
the nominal program meant (:mod:`cellcal.programs`).

:class:`ProgramRequest` is what the command was asked; :func:`compensate_program` checks
the output (never an input, never a run store), reads the calibration, the program and its
frames, and writes the compensated program atomically; it returns the
:class:`~cellcal.programs.program_report.ProgramReport` (its ``exit_code``: 1 when
something could not be compensated; nothing is written then, unless ``--allow-partial``).
"""

from __future__ import annotations

from pydantic import Field

from calibration.effects import load_effect_file
from calibration.exports.params_io import read_params

from ..errors import UsageError
from ..programs import compensate as program_filter
from ..programs.program_report import ProgramReport
from ..request import Request
from .outputs import check_outputs, existing_paths
from .program_inputs import program_options
from .target_checks import no_envelope_note

#: the flags of ``compensate`` that do not go with ``--program``
_OTHER_FLAGS = {"targets": "TARGETS.csv", "position_only": "--position-only",
                "export_model": "--export-model", "export_ur": "--export-ur",
                "export_urdf": "--export-urdf", "export_ur_yaml": "--export-ur-yaml",
                "export_dh": "--export-dh"}


class ProgramRequest(Request):
    """The flags of ``cellcal compensate --program`` (defaults as the parser's)."""

    program: str = Field(alias="--program")
    params: str = Field(alias="--params")
    out: str | None = Field(None, alias="--out")
    effect_file: tuple[str, ...] = Field((), alias="--effect-file")
    language: str | None = Field(None, alias="--language")
    allow_partial: bool = Field(False, alias="--allow-partial")
    frames: str | None = Field(None, alias="--frames")
    start: str | None = Field(None, alias="--start")
    temp_c: float | None = Field(None, alias="--temp-c")
    payload_kg: float | None = Field(None, alias="--payload-kg")
    strict_range: bool = Field(False, alias="--strict-range")


def refuse_other_flags(args) -> None:
    """``--program`` goes with none of the CSV path's inputs and exports (UsageError)."""
    given = [flag for attr, flag in _OTHER_FLAGS.items() if getattr(args, attr, None)]
    if given:
        raise UsageError(f"--program does not go with {', '.join(given)}: compensate a "
                         "program, or targets and exports, in separate runs")


def compensate_program(request: ProgramRequest) -> ProgramReport:
    """Compensate ``request.program`` with ``request.params`` into ``request.out``.

    Raises
    ------
    UsageError, calibration.errors.CalibrationError
        Bad input (exit 2): no ``--out``, an output that is an input or a run store, a
        program that does not parse (:class:`~cellcal.programs.targets.ProgramError`
        names the line), a bad frames file, a thermal calibration without ``--temp-c``;
        with ``--strict-range`` a target beyond the calibrated envelope
        (:class:`~calibration.errors.OutsideEnvelope`, exit 3).
    """
    if request.out is None:
        raise UsageError("--program needs --out FILE: where the compensated program goes")
    check_outputs({"--out": request.out},
                  existing_paths(request.program, request.params, request.frames,
                                 request.effect_file))
    dialect = program_filter.language_of(request.program, request.language)
    for f in request.effect_file:
        load_effect_file(f)
    loaded = read_params(request.params)
    em, x = loaded.error_model, loaded.values
    if request.strict_range and loaded.envelope is None:
        raise UsageError(f"--strict-range: {no_envelope_note(request.params)}")
    options = program_options(em, frames=request.frames, start_deg=request.start,
                              temp_c=request.temp_c, payload_kg=request.payload_kg,
                              thermal=loaded.thermal)
    report = program_filter.compensate_program(
        request.program, em, x, request.out, allow_partial=request.allow_partial,
        language=dialect.name, options=options, envelope=loaded.envelope,
        strict_range=request.strict_range)
    if loaded.envelope is None:
        report.notes.append(no_envelope_note(request.params))
    return report
