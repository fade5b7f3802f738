"""What compensating a program did, as the command prints it and as JSON."""

from __future__ import annotations

from dataclasses import dataclass, field

from presentation.program_text import program_lines, program_summary

from .targets import Refusal


def target_row(t, c, i: int, outside: list[str] | None = None) -> dict:
    """One compensated target for the report: where it is, what changed, and what lies
    beyond the calibrated envelope (``outside_range``: ``["q2"]``, empty inside)."""
    return {"line": t.line, "kind": t.kind, "context": t.context,
            "correction_mm": float(c.correction_mm[i]),
            "correction_deg": float(c.correction_deg[i]),
            "predicted_miss_mm": float(c.predicted_mm[i]),
            "predicted_miss_deg": float(c.predicted_deg[i]),
            "outside_range": list(outside or [])}


@dataclass
class ProgramReport:
    """The result of :func:`~cellcal.programs.compensate.compensate_program`.

    Attributes
    ----------
    source, out : the program read and the file written
    language : ``urscript`` or ``krl``
    n_targets : targets found
    rows : one dict per compensated target (:func:`target_row`)
    refusals : what was not compensated, with lines
    notes : what the reader wants the user to know (a run-time TCP, a shared variable)
    written : the output file was written
    """

    source: str
    out: str
    language: str
    n_targets: int
    rows: list[dict]
    refusals: list[Refusal]
    notes: list[str] = field(default_factory=list)
    written: bool = False

    @property
    def outside(self) -> list[list[str]]:
        """Per compensated target, the quantities beyond the calibrated envelope."""
        return [r.get("outside_range", []) for r in self.rows]

    @property
    def exit_code(self) -> int:
        """0 all compensated; 1 something was not (written or not, see ``written``)."""
        return 1 if self.refusals else 0

    def lines(self) -> list[str]:
        """The report in words, as the command prints it (:mod:`presentation.program_text`)."""
        return program_lines(self)

    def to_json(self) -> dict:
        return program_summary(self)
