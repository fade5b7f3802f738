"""The report's orientation section on simulated 6-DoF data (issue 27): the orientation
residual per pose (angle and flange-axis parts) and each joint's share of it, present only
when the data have orientations."""

from __future__ import annotations

import re

import pytest

from calibration import load_model
from calibration.diagnosis.diagnosis import diagnose
from calibration.fit.error_model import ErrorModel
from calibration.fit.identify import identify
from presentation.html_report import render_report
from presentation.plot_base import Stage
from tests.calibration.test_full_pose import POSITION, _data


@pytest.fixture(scope="module")
def position_only():
    data = _data(load_model("ur10e"), n=50, n_valid=15)
    return data, identify(ErrorModel(load_model("ur10e"), POSITION), data)


def _figure_ids(data, fit):
    page = render_report(diagnose(fit, data), [Stage("current model", fit)], data=data,
                         dpi=30).html
    return page, re.findall(r'<figure id="([^"]+)"', page)


def test_the_report_shows_where_the_orientations_fail(position_only):
    data, fit = position_only
    page, ids = _figure_ids(data, fit)
    assert "fig-orientation" in ids and "Where the orientations fail" in page
    assert "predicted by this position-only model" in page and "joint 5 carries" in page


def test_no_orientation_section_without_orientations(position_only):
    from dataclasses import replace

    data, _ = position_only
    data = replace(data, quat=None, sigma_deg=None)
    fit = identify(ErrorModel(load_model("ur10e"), POSITION), data)
    page, ids = _figure_ids(data, fit)
    assert "fig-orientation" not in ids and "orientations fail" not in page
