"""``report``: one self-contained HTML page showing where the model fails and what fixed
it, with its provenance.

:class:`ReportRequest` is what the command was asked; :func:`write_report` fits the
stages, renders the page (:func:`presentation.html_report.build_report`) and writes it;
it returns a :class:`WrittenReport`.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

from pydantic import Field

from presentation.html_report import Report, ReportError, build_report
from presentation.provenance import Provenance

from ..errors import UsageError
from .inputs import CurrentModelInputs, DataInputs, check_data, current_model, load_inputs
from .outputs import check_outputs, existing_paths

#: ``--max-steps`` when not given
DEFAULT_MAX_STEPS = 12


class ReportRequest(DataInputs, CurrentModelInputs):
    """The flags of ``cellcal report`` (defaults as the parser's; ``--max-steps`` and
    ``--budget-s`` are checked by :meth:`check`, with their own messages)."""

    auto: bool = Field(False, alias="--auto")
    max_steps: int = Field(DEFAULT_MAX_STEPS, alias="--max-steps")
    budget_s: float | None = Field(None, alias="--budget-s")
    title: str | None = Field(None, alias="--title")
    out: str = Field("report.html", alias="--out")

    def check(self) -> None:
        """Refuse ``--auto``'s flags without it, a bad step count or budget (UsageError)."""
        if not self.auto and (self.max_steps != DEFAULT_MAX_STEPS or self.budget_s is not None):
            raise UsageError("--max-steps and --budget-s need --auto")
        if self.max_steps < 1:
            raise UsageError("--max-steps must be at least 1")
        if self.budget_s is not None and not (self.budget_s > 0
                                              and math.isfinite(self.budget_s)):
            raise UsageError("--budget-s must be a positive number of seconds")


@dataclass
class WrittenReport:
    """The page :func:`write_report` wrote: ``report`` (its fits, diagnosis, figures,
    timings), ``out`` and its ``size`` in bytes, its ``provenance``, the ``notes``."""

    report: Report
    out: Path
    size: int
    provenance: Provenance
    notes: list[str] = field(default_factory=list)


def _as_usage_error(fn, *errors: type[Exception]):
    """fn(); the given errors become a UsageError with their own message (exit 2)."""
    try:
        return fn()
    except errors as e:
        raise UsageError(str(e)) from None


def write_report(request: ReportRequest,
                 on_note: Callable[[str], None] | None = None) -> WrittenReport:
    """Fit, diagnose, render and write the page ``request`` asks for.

    ``on_note`` is called with each remark as soon as it is known (before the fits).

    Raises
    ------
    UsageError, calibration.errors.InputError
        Bad input (exit 2); InsufficientData: data too poor for the model (exit 3).
    """
    request.check()
    out = Path(request.out)
    check_outputs({"--out": request.out},
                  existing_paths(request.data, request.params, request.model,
                                 request.effect_file))
    model, data = load_inputs(request)
    em, _, notes = current_model(request, model)
    notes += check_data(em, data, "report", "auto" if request.auto else "diagnose")
    for n in notes if on_note is not None else ():
        on_note(n)
    prov = _as_usage_error(lambda: Provenance.of(model.name, request.data, data,
                                                 request.params), OSError)
    rep = _as_usage_error(lambda: build_report(
        data, model, request.effects, request.params, solver=request.solver,
        title=request.title, auto=request.auto, max_steps=request.max_steps,
        budget_s=request.budget_s, provenance=prov), ReportError)
    rep.write(out)
    return WrittenReport(rep, out, out.stat().st_size, prov, notes)
