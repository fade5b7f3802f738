"""What compensating a program did, as the command prints it and as JSON."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .targets import Refusal


def target_row(t, c, i: int) -> dict:
    """One compensated target for the report: where it is and what changed."""
    return {"line": t.line, "kind": t.kind, "context": t.context,
            "correction_mm": float(c.correction_mm[i]),
            "correction_deg": float(c.correction_deg[i]),
            "predicted_miss_mm": float(c.predicted_mm[i]),
            "predicted_miss_deg": float(c.predicted_deg[i])}


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
    def exit_code(self) -> int:
        """0 all compensated; 1 something was not (written or not, see ``written``)."""
        return 1 if self.refusals else 0

    def _stats(self, key: str) -> tuple[float, float]:
        v = np.array([r[key] for r in self.rows])
        return (float(np.sqrt(np.mean(v**2))), float(v.max())) if v.size else (0.0, 0.0)

    def lines(self) -> list[str]:
        """The report in words, as the command prints it."""
        out = [f"{self.source}: {self.language}, {self.n_targets} targets found, "
               f"{len(self.rows)} compensated"]
        if self.rows:
            rms, worst = self._stats("predicted_miss_mm")
            out.append(f"  predicted miss without compensation: RMS {rms:.3f} mm, "
                       f"worst {worst:.3f} mm")
            rms, worst = self._stats("correction_mm")
            out.append(f"  correction: RMS {rms:.3f} mm, worst {worst:.3f} mm")
        if self.refusals:
            out.append(f"  not compensated ({len(self.refusals)}):")
            out += [f"    {r}" for r in self.refusals]
        out += [f"  note: {n}" for n in self.notes]
        if self.written:
            out.append(f"  wrote {self.out}" + (" (partly compensated)" if self.refusals
                                                else ""))
        elif self.refusals:
            out.append(f"  nothing written: {len(self.refusals)} construct(s) cannot be "
                       "compensated (--allow-partial writes the rest)")
        return out

    def to_json(self) -> dict:
        return {"source": self.source, "out": self.out if self.written else None,
                "language": self.language, "n_targets": self.n_targets,
                "n_compensated": len(self.rows), "targets": self.rows,
                "refused": [{"line": r.line, "construct": r.construct, "reason": r.reason}
                            for r in self.refusals],
                "notes": self.notes, "written": self.written}
