"""The report shows the thermal state (issue 26): the error against the joints' mean
temperature, each joint's residual against its own temperature, and every drift effect's
step figure against what it depends on (joint temperature, mean temperature, time)."""

import re

import numpy as np
import pytest

from calibration import ErrorModel, identify, load_model
from calibration.fit.simulate import random_joints, realistic_truth, simulate, warmup_temperatures
from presentation.figures import time_axes
from presentation.html_report import render_report
from presentation.joint_figures import _step_x, _what
from presentation.plot_base import Stage
from presentation.residual_points import points_of

UR = load_model("ur10e")
N, DT_S = 120, 20.0  # a 40-minute cold start
DRIFT = ("thermal_zero:2", "thermal_growth", "time_growth", "base_drift")


@pytest.fixture(scope="module")
def cold():
    """A UR10e warming up while it is captured (its joint 2 zero and its links drift)."""
    em = ErrorModel(UR, "geometric,base,tool,thermal_zero:2,thermal_growth")
    rng = np.random.default_rng(3)
    x = realistic_truth(em, rng)
    t = np.arange(N) * DT_S
    data = simulate(em, x, random_joints(UR, N, rng), 0.015, rng, t_s=t,
                    joint_temp=warmup_temperatures(t, 6))
    start = identify(ErrorModel(UR, "geometric,base,tool"), data)
    return data, start


def test_the_report_plots_the_error_against_the_joint_temperatures(cold):
    data, start = cold
    from calibration.diagnosis.diagnosis import diagnose

    page = render_report(diagnose(start, data), [Stage("current model", start)],
                         data=data, dpi=30).html
    ids = re.findall(r'<figure id="([^"]+)"', page)
    assert ids.index("fig-joint-temps") == ids.index("fig-time") + 1
    assert "the joints' mean temperature" in page
    assert "thermal_zero:J" in page


def test_the_mean_temperature_panel_only_where_the_joints_warm(cold):
    data, start = cold
    from dataclasses import replace

    def panels(rows):
        return [name for name, _, _ in time_axes(points_of(start, rows))]

    assert panels(data) == ["time", "joint temperature"]
    assert panels(replace(data, joint_temp=None)) == ["time"]
    steady = replace(data, joint_temp=np.full(data.q.shape, 30.0))
    assert panels(steady) == ["time"]


@pytest.mark.parametrize("effect", DRIFT)
def test_each_drift_step_is_plotted_against_what_it_depends_on(cold, effect):
    data, start = cold
    after = identify(ErrorModel(UR, "geometric,base,tool," + effect), data)
    em = after.error_model
    eff = em.effects[-1]
    x, label = _step_x(eff, data, start)
    expected = {"thermal_zero:2": (data.joint_temp[:, 1], "joint 2 temperature, °C"),
                "thermal_growth": (data.joint_temp.mean(axis=1),
                                   "joints' mean temperature, °C"),
                "time_growth": ((data.t_s - data.t_s[0]) / 60, "time since the first pose, min"),
                "base_drift": ((data.t_s - data.t_s[0]) / 60, "time since the first pose, min")}
    np.testing.assert_allclose(x, expected[effect][0])
    assert label == expected[effect][1]
    what = _what(eff, after.values[em.slices[-1]], data, start)
    assert {"thermal_zero:2": "µrad/K", "thermal_growth": "ppm/K", "time_growth": "ppm",
            "base_drift": "µm"}[effect] in what
