"""A run's summary (``runs.summary_json``) as a typed record: :class:`RunSummary`.

The executor, the routines' ``finalize`` and the re-measure policy each add their keys;
``cellcal runs`` and ``capture`` read them back. The keys known today are typed
attributes (None: not in this run's summary); keys this cellcal does not know (an older
or a newer one wrote them) are kept as they were. A summary is written back as it was
read, byte for byte: the same keys in the same order (a key set for the first time comes
last, as in a dict), numbers as stored (an integer stays an integer), so the stored JSON
and ``cellcal runs --json`` do not change.

Keys
    the executor: ``beam_breaks``, ``skipped_points``, ``spares_measured``, ``capture_s``;
    the re-measure policy: ``remeasure`` (:class:`RemeasureSummary`);
    ``frame``: ``circle_rms_mm``, ``line_rms_mm``, ``orthogonality_deg``;
    ``iso9283``: ``iso9283`` (RP and AP per cube point, :class:`Iso9283Point`);
    ``validate``: ``validation`` (per variant, :class:`ValidationVariant`) and
    ``validation_frame`` (the frame the errors are measured in);
    ``zero20``: ``tip_spread_max_mm``, ``tip_spread_rms_mm``, and, while capturing,
    ``zero_target_tracker_mm`` and ``zero_tracker_R_base``;
    ``warmup``: ``warmup`` (:class:`WarmupSummary`).

Units: mm, degrees, s.
"""

from __future__ import annotations

import json
from typing import Any

from pydantic import (
    BaseModel,
    ConfigDict,
    ModelWrapValidatorHandler,
    PrivateAttr,
    model_validator,
)

#: a JSON number kept as stored (an integer stays one: the summary is written back as read)
Number = float | int


class StoredRecord(BaseModel):
    """A JSON object read from the store: known keys typed, unknown ones kept, every key
    written back in the order it was read or first set (:meth:`to_json`)."""

    model_config = ConfigDict(extra="allow")

    _order: list[str] = PrivateAttr(default_factory=list)

    @model_validator(mode="wrap")
    @classmethod
    def _keep_order(cls, data: Any, handler: ModelWrapValidatorHandler[Any]) -> Any:
        record = handler(data)
        if isinstance(data, dict):
            record._order = list(data)
        return record

    def __setattr__(self, name: str, value: Any) -> None:
        super().__setattr__(name, value)
        if not name.startswith("_") and name not in self._order:
            self._order.append(name)

    def to_json(self) -> dict:
        """The JSON-ready dict: the keys given, in their order, values as given."""
        return {k: _plain(getattr(self, k)) for k in self._order}

    def __getitem__(self, key: str) -> Any:
        """The value of ``key`` as stored (JSON: a nested record as a dict); KeyError when
        the key is not in this record. Code reads the attributes; this is the stored
        document's view (what ``cellcal runs --json`` shows)."""
        if key not in self._order:
            raise KeyError(key)
        return _plain(getattr(self, key))

    def __eq__(self, other: object) -> bool:
        """Equal to a record of the same class, or to a dict, with the same JSON."""
        if isinstance(other, dict):
            return self.to_json() == other
        if type(other) is type(self):
            return self.to_json() == other.to_json()
        return NotImplemented

    __hash__ = None  # type: ignore[assignment]  # mutable: not hashable


def _plain(v: Any) -> Any:
    if isinstance(v, StoredRecord):
        return v.to_json()
    if isinstance(v, dict):
        return {k: _plain(x) for k, x in v.items()}
    if isinstance(v, list):
        return [_plain(x) for x in v]
    return v


class RemeasureSummary(StoredRecord):
    """What the re-measure policy did in a run (:mod:`daq.remeasure`): the counts of
    :meth:`daq.store.RunStore.remeasure_counts`, then the policy's limit, the running
    model's warm-up and its refits over every session."""

    judged: int | None = None
    warmup: int | None = None
    suspects: int | None = None
    remeasurements: int | None = None
    rejected: int | None = None
    model_disagrees: int | None = None
    unresolved: int | None = None
    max_remeasures: int | None = None
    warmup_points: int | None = None
    refits: int | None = None
    refit_s: Number | None = None
    largest_refit_rows: int | None = None


class Iso9283Point(StoredRecord):
    """ISO 9283 at one cube point: ``n`` repetitions, the positional repeatability RP
    and, when the frame is known, the accuracy AP (mm)."""

    n: int | None = None
    RP_mm: Number | None = None  # noqa: N815 - the standard's name
    AP_mm: Number | None = None  # noqa: N815 - the standard's name


class WarmupSummary(StoredRecord):
    """How a warm-up ended (:mod:`daq.routines.warmup`): ``settled`` (the reference's drift
    over the last ``window_min`` fell below ``threshold_mm``) or not (the time bound or the
    plan's last cycle came first), after ``minutes`` and ``cycles``; ``drift_mm`` that last
    window's drift; the drift curve of the reference (``t_min``, ``curve_mm`` from its first
    reading) and the joints' temperatures at its last reading (``joint_temp_c``, °C; None
    when the robot reports none)."""

    settled: bool | None = None
    reason: str | None = None
    minutes: Number | None = None
    cycles: int | None = None
    drift_mm: Number | None = None
    threshold_mm: Number | None = None
    window_min: Number | None = None
    t_min: list[Number] | None = None
    curve_mm: list[Number] | None = None
    joint_temp_c: list[Number] | None = None
class ValidationVariant(StoredRecord):
    """One variant of a validation run (``validate``: the program as written, compensated,
    geometric only): the position error of every visit against its target, ``n`` visits
    (RMS, mean, max, mm), and ISO 9283 per waypoint (``waypoints``: label -> AP, and RP
    where the waypoint was visited more than once); ``ap_max_mm``, ``rp_max_mm`` the
    worst."""

    n: int | None = None
    rms_mm: Number | None = None
    mean_mm: Number | None = None
    max_mm: Number | None = None
    ap_max_mm: Number | None = None
    rp_max_mm: Number | None = None
    waypoints: dict[str, Iso9283Point] | None = None


class RunSummary(StoredRecord):
    """A run's summary (see the module docstring for who writes which key)."""

    beam_breaks: int | None = None
    skipped_points: list[int] | None = None
    spares_measured: int | None = None
    capture_s: Number | None = None
    remeasure: RemeasureSummary | None = None
    circle_rms_mm: Number | None = None
    line_rms_mm: Number | None = None
    orthogonality_deg: Number | None = None
    iso9283: dict[str, Iso9283Point] | None = None
    tip_spread_max_mm: Number | None = None
    tip_spread_rms_mm: Number | None = None
    zero_target_tracker_mm: list[Number] | None = None
    zero_tracker_R_base: list[list[Number]] | None = None  # noqa: N815 - a_R_b
    warmup: WarmupSummary | None = None
    validation: dict[str, ValidationVariant] | None = None
    validation_frame: str | None = None

    @classmethod
    def from_json(cls, text: str) -> RunSummary:
        """The summary stored as ``text`` (JSON)."""
        return cls.model_validate(json.loads(text))

    def dumps(self) -> str:
        """The JSON text stored (as ``json.dumps`` of the dict it was read from)."""
        return json.dumps(self.to_json())
