"""Calibration history: changes against the combined uncertainty of consecutive fits."""

from __future__ import annotations

import math

import numpy as np
import pytest

from calibration.diagnosis.history import CalibrationSummary, parameter_histories


def _doc(rows, effects=("geometric",), rms=0.02):
    return {"model": "m", "effects": list(effects), "stats": {"calib": {"rms_mm": rms}},
            "parameters": [{"name": n, "value": v, "std": s, "unit": u,
                            "identifiable": s is not None} for n, v, s, u in rows]}


def test_changes_are_judged_against_the_combined_sigma():
    s = 0.1
    docs = [_doc([("a", 1.0, s, "mm"), ("b", 5.0, None, "deg")]),
            _doc([("a", 1.0 + 2.99 * math.sqrt(2) * s, s, "mm"), ("b", 9.0, None, "deg")]),
            _doc([("a", 1.0 + 2.99 * math.sqrt(2) * s + 3.01 * math.hypot(s, 2 * s), 2 * s,
                   "mm")]),
            _doc([("b", 9.0, 0.001, "deg"), ("a", 0.0, 2 * s, "mm")])]
    a, b = parameter_histories(docs)
    assert a.name == "a" and a.unit == "mm" and a.index.tolist() == [0, 1, 2, 3]
    np.testing.assert_allclose(a.sigma, [math.hypot(s, s), math.hypot(s, 2 * s),
                                         math.hypot(2 * s, 2 * s)])
    np.testing.assert_allclose(a.z[:2], [2.99, 3.01])
    assert a.flagged.tolist() == [False, True, True]
    assert a.largest_step() == 2 and a.determined
    # b: absent from the third calibration, its uncertainty unknown at first: never flagged
    assert b.index.tolist() == [0, 1, 3] and b.change.tolist() == [4.0, 0.0]
    assert not b.flagged.any() and np.isnan(b.sigma).all() and b.largest_step() is None
    assert math.isclose(a.net_change, -1.0) and math.isclose(a.net_z, 1.0 / math.hypot(s, 2 * s))
    assert parameter_histories(docs, threshold=2.9)[0].flagged.tolist() == [True, True, True]
    with pytest.raises(ValueError):
        parameter_histories(docs, threshold=0)


def test_decimals_show_the_uncertainty_and_summaries_read_the_stats():
    (h,) = parameter_histories([_doc([("x", 2661.2, 0.00093, "mm")]),
                                _doc([("x", 2661.3, 0.0011, "mm")])])
    assert h.decimals() == 5  # 0.00093 -> two significant digits
    (fixed,) = parameter_histories([_doc([("y", 0.0, None, "mm")])])
    assert not fixed.determined and fixed.decimals() == 4 and math.isnan(fixed.net_change)
    s = CalibrationSummary.of(_doc([], effects=("geometric", "base"), rms=0.031))
    assert s == CalibrationSummary("m", ("geometric", "base"), 0.031, None)
