"""The store's checked pieces: the schema's upgrade registry (complete, and refusing a gap
or a duplicate), the interruption kinds every fault maps to, and the run summary written
back exactly as it was read."""

from __future__ import annotations

import json

import pytest

from daq.errors import CaptureError
from daq.executor import fault_kind
from daq.store import STATUSES, InterruptionKind, RunStatus, RunSummary
from daq.store.schema import SCHEMA_VERSION, UPGRADES, Upgrade, checked_upgrades


def _noop(con) -> None:
    pass


def test_the_upgrade_registry_is_complete():
    assert list(UPGRADES) == list(range(1, SCHEMA_VERSION))
    for v, up in UPGRADES.items():
        assert up.version == v
        assert up.description.strip() and "\n" not in up.description


@pytest.mark.parametrize("versions, message", [
    ((1, 2, 2), "two upgrades from schema version 2"),
    ((1, 3), "no upgrade from schema version 2"),
    ((2, 3), "no upgrade from schema version 1"),
])
def test_a_gap_or_a_duplicate_is_refused(versions, message):
    with pytest.raises(ValueError, match=message):
        checked_upgrades([Upgrade(v, f"step {v}", _noop) for v in versions])


def test_an_upgrade_needs_a_one_line_description():
    for text in ("", "two\nlines"):
        with pytest.raises(ValueError, match="one-line description"):
            checked_upgrades([Upgrade(1, text, _noop)])


def test_statuses_are_stored_as_before():
    assert STATUSES == ("running", "paused", "stopped", "completed", "failed", "incomplete")
    assert tuple(RunStatus) == STATUSES


def _subclasses(cls):
    for sub in cls.__subclasses__():
        yield sub
        yield from _subclasses(sub)


def test_every_capture_error_has_an_interruption_kind():
    import daq.motion_guard  # noqa: F401 - defines CaptureErrors

    for cls in (CaptureError, *_subclasses(CaptureError)):
        assert cls.kind in set(InterruptionKind), cls
        e = cls.__new__(cls)
        assert fault_kind(e) == cls.kind


def test_a_summary_is_written_back_as_it_was_read():
    text = ('{"later": 1, "capture_s": 3, "remeasure": {"judged": 2, "refit_s": 1, '
            '"new_count": [1]}, "iso9283": {"P1": {"n": 3, "RP_mm": 0.01}}, "odd": NaN}')
    s = RunSummary.from_json(text)
    assert s.dumps() == json.dumps(json.loads(text))
    assert s.capture_s == 3 and isinstance(s.capture_s, int)
    assert s.remeasure.judged == 2 and s.iso9283["P1"].RP_mm == 0.01
    s.beam_breaks = 0
    s.capture_s = 4.5
    assert list(s.to_json()) == ["later", "capture_s", "remeasure", "iso9283", "odd",
                                 "beam_breaks"]
