"""The report tells the story: the automatic diagnosis step by step, what each step fixed,
the blunders left out, masked joint views, medians that break over empty bins."""

import base64
import re
import struct
from dataclasses import replace

import numpy as np
import pytest

from calibration import DEFAULT_EFFECTS, ErrorModel, identify, load_model
from calibration.fit.simulate import add_blunders, random_joints, realistic_truth, simulate
from calibration.workflow import joint_view
from presentation.figures import fig_steps
from presentation.html_report import build_report
from presentation.joint_figures import fig_joints, masked_note
from presentation.plot_base import FIG_WIDTH, binned_median
from presentation.residual_points import LEVER_ARM_MIN_MM, points_of

from .test_report import assert_self_contained

HIDDEN = "compliance:3,harmonic2:4,backlash:2"


@pytest.fixture(scope="module")
def model():
    return load_model("ur5e")


@pytest.fixture(scope="module")
def story(model):
    """250 calibration + 150 validation poses of a UR5e with three hidden effects and
    blunders in the calibration rows (approach directions recorded)."""
    em = ErrorModel(model, DEFAULT_EFFECTS + "," + HIDDEN)
    rng = np.random.default_rng(2)
    x = realistic_truth(em, rng)
    n = 400
    q = random_joints(model, n, rng)
    dirs = np.zeros((n, 6), int)
    dirs[1:] = np.sign(np.diff(q, axis=0))
    data = simulate(em, x, q, 0.015, rng, is_valid=np.arange(n) >= 250, dirs=dirs)
    data, truth = add_blunders(data, 0.02, np.random.default_rng(2), rows=~data.is_valid)
    assert len(truth.pose_id) >= 3
    return data, truth, build_report(data, model, auto=True)


def _block(page: str, fig_id: str) -> str:
    return re.search(rf'<figure id="{fig_id}">(.*?)</figure>', page, re.S)[1]


def _png_size(src: str) -> tuple[int, int]:
    png = base64.b64decode(src.split(",", 1)[1])
    return struct.unpack(">II", png[16:24])


def test_steps_come_first_and_each_step_has_its_before_after(story):
    _, _, rep = story
    page = rep.html
    assert_self_contained(page)
    added = [s.effect for s in rep.story.added]
    assert set(added) == set(HIDDEN.split(","))  # the hidden effects, nothing else
    ids = [f for f, _ in rep.figures]
    k = len(added)
    assert ids == (["fig-steps"] + [f"fig-step-{i}" for i in range(1, k + 1)]
                   + ["fig-hist", "fig-workspace", "fig-joints", "fig-torque", "fig-time",
                      "fig-periodogram"])
    assert page.count("<img") == len(ids)
    # the first figure of the page is the RMS at every step
    assert page.index("<figure") == page.index('<figure id="fig-steps">')
    assert f"each of the {k} steps" in _block(page, "fig-steps")
    steps = re.search(r'<table id="tab-steps">(.*?)</table>', page, re.S)[1]
    assert len(re.findall(r"<tr><td", steps)) == k + 1  # the start and every step
    for i, effect in enumerate(added, 1):
        assert f"+ <code>{effect}</code>" in _block(page, f"fig-step-{i}")
    # each step lowers the held-out error; the story ends near the noise floor
    held = [s.heldout_rms_mm for s in rep.story.steps]
    assert all(b < a for a, b in zip(held, held[1:], strict=False))
    assert held[-1] < 1.15 * rep.diagnosis.noise_floor_mm
    # every figure is drawn at most 800 px wide: read at its natural size in an 800 px window
    for src in re.findall(r'src="([^"]+)"', page):
        assert _png_size(src)[0] <= FIG_WIDTH * 100


def test_captions_say_what_each_effect_looks_like(story):
    _, _, rep = story
    page = rep.html
    by_effect = {s.effect: i for i, s in enumerate(rep.story.added, 1)}
    backlash = _block(page, f"fig-step-{by_effect['backlash:2']}")
    assert "two bands" in backlash and "approach direction" in backlash
    assert "step at 0" not in page
    harmonic = _block(page, f"fig-step-{by_effect['harmonic2:4']}")
    assert "sinusoid of order 2" in harmonic
    compliance = _block(page, f"fig-step-{by_effect['compliance:3']}")
    assert "straight line through zero against the gravity torque on joint 3" in compliance
    # the fitted size is that step's fit's, in the caption's units
    step = rep.story.added[by_effect["compliance:3"] - 1]
    c = step.fit.param("compliance.j3.c")[0] * 1e6
    assert f"c = {c:.3g} µrad/(N·m)" in compliance


def test_step_fit_recovers_the_hidden_effects(story, model):
    """What the story's steps fitted is the simulated truth (within its uncertainty)."""
    data, _, rep = story
    final = rep.story.final.fit
    em = ErrorModel(model, DEFAULT_EFFECTS + "," + HIDDEN)
    rng = np.random.default_rng(2)
    x = realistic_truth(em, rng)
    for name in ("compliance.j3.c", "backlash.j2.b"):
        value, std = final.param(name)
        assert abs(value - x[em.index(name)]) < 5 * std + 0.05 * abs(x[em.index(name)]), name


def test_blunders_are_tabulated_and_marked(story):
    _, truth, rep = story
    page = rep.html
    table = re.search(r'<table id="tab-blunders">(.*?)</table>', page, re.S)[1]
    listed = re.findall(r"<tr><td><code>([^<]+)</code>", table)
    assert set(listed) == set(truth.pose_id)
    for pid, along in zip(truth.pose_id, truth.along_beam, strict=True):
        row = re.search(rf"<tr><td><code>{pid}</code>(.*?)</tr>", table, re.S)[1]
        assert ("along the beam" if along else "across the beam") in row
    for fig_id in ("fig-workspace", "fig-joints", "fig-time"):
        assert "Orange crosses" in _block(page, fig_id)


def test_lever_arm_is_how_far_the_target_moves_per_radian(story):
    """``joint_view``'s lever arm against finite differences of the fitted model, and the
    joint-equivalent residual is the residual's least-squares joint correction. (The
    difference quotient also carries the fitted effects' own dependence on the angle,
    harmonic and compliance: a few 1e-4 of it.)"""
    data, _, rep = story
    fit = rep.story.final.fit
    rows = fit.data.subset(np.arange(20))
    view = joint_view(fit, rows)
    h = 1e-6
    for j in range(6):
        q = rows.q.copy()
        q[:, j] += h
        moved = replace(rows, q=q)
        dP = (fit.predict(moved) - fit.predict(rows)) / h
        np.testing.assert_allclose(view.lever_arm_mm[:, j], np.linalg.norm(dP, axis=1),
                                   rtol=1e-3, atol=1e-3)
        ls = np.einsum("ni,ni->n", dP, view.residuals) / np.einsum("ni,ni->n", dP, dP)
        np.testing.assert_allclose(view.joint_residual_rad[:, j], ls, rtol=1e-2,
                                   atol=1e-9)


def test_joint_views_are_masked_where_the_lever_arm_is_short(story):
    """UR5e with its SMR near the flange axis: joint 6 barely moves the target, so its
    equivalent residual is masked at every pose and the page says so."""
    _, _, rep = story
    fit = rep.diagnosis.fit
    cloud = points_of(fit, fit.data)
    assert (cloud.lever_mm[:, 5] < LEVER_ARM_MIN_MM).all()
    assert cloud.shown(1).mean() > 0.9
    note = masked_note(cloud)
    assert f"joint 6: {cloud.n} of {cloud.n}" in note
    assert f"joint 6: {cloud.n} of {cloud.n}" in _block(rep.html, "fig-joints")
    # the panel of a masked joint draws no point
    fig = fig_joints(cloud)
    ax6 = fig.axes[5]
    assert not ax6.collections and "not shown" in ax6.texts[0].get_text()


def test_each_step_overlay_is_on_the_cloud_basis(story):
    """Before-cloud minus the overlay is exactly the after-residual, projected the same way:
    the orange points are what the step removed from that cloud."""
    _, _, rep = story
    before, after = rep.story.steps[0].fit, rep.story.steps[1].fit
    rows = before.data
    view = joint_view(before, rows)
    r_after = rows.tracker_p_smr - after.predict(rows)
    overlay = view.project(after.predict(rows) - before.predict(rows))
    np.testing.assert_allclose(view.joint_residual_rad - overlay, view.project(r_after),
                               atol=1e-12)


def test_binned_median_breaks_over_empty_bins():
    rng = np.random.default_rng(0)
    x = np.concatenate([rng.uniform(-180, -60, 300), rng.uniform(60, 180, 300)])
    y = np.sin(np.radians(x)) + rng.normal(0, 0.1, x.size)
    cx, cy = binned_median(x, y, bins=12)
    gap = (cx > -50) & (cx < 50)
    assert gap.any() and np.isnan(cy[gap]).all()
    assert np.isfinite(cy[~gap]).all()


def test_joint_panels_never_draw_a_median_across_empty_bins(model):
    """Joint 2 only ever below -60 deg or above 60 deg: its median line has a hole."""
    em = ErrorModel(model, DEFAULT_EFFECTS)
    rng = np.random.default_rng(4)
    x = realistic_truth(em, rng)
    q = random_joints(model, 240, rng)
    q[:, 1] = np.where(q[:, 1] < 0, -np.radians(rng.uniform(60, 170, 240)),
                       np.radians(rng.uniform(60, 170, 240)))
    data = simulate(em, x, q, 0.015, rng)
    fit = identify(em, data)
    fig = fig_joints(points_of(fit, fit.data))
    line = fig.axes[1].lines[0]  # the binned median of joint 2
    xs, ys = np.asarray(line.get_xdata()), np.asarray(line.get_ydata())
    half = 0.5 * (xs[1] - xs[0])
    inside = np.abs(xs) < 60 - half  # bins wholly inside the gap
    assert inside.any() and np.isnan(ys[inside]).all()
    assert np.isfinite(ys[~inside]).sum() >= 6


def test_steps_figure_has_one_point_per_step():
    fig = fig_steps(["uncalibrated", "start", "+ a", "+ b"], [0.6, 0.2, 0.05, 0.03],
                    [0.62, 0.21, None, 0.031], 0.026)
    ax = fig.axes[0]
    calib, held, floor = ax.lines[:3]
    assert len(calib.get_xdata()) == len(held.get_xdata()) == 4
    assert np.isnan(held.get_ydata()[2])  # no held-out number: no point, no line through it
    assert floor.get_ydata()[0] == pytest.approx(0.026)
    assert [t.get_text() for t in ax.get_xticklabels()] == ["uncalibrated", "start", "+ a",
                                                             "+ b"]


def test_candidates_are_listed_in_ranking_order(story):
    _, _, rep = story
    diag = rep.diagnosis
    table = re.search(r'<table id="tab-candidates">(.*?)</table>', rep.html, re.S)[1]
    listed = re.findall(r"<tr[^>]*><td><code>([^<]+)</code>", table)
    assert listed == [c.effect for c in diag.candidates[: len(listed)]]
    assert "Ranked by the diagnosis" in table and "BIC gain" in table
    # the order the caption states: confirmed by held-out RMS, then by BIC gain
    cands = diag.candidates[: len(listed)]
    confirmed = [c for c in cands if c.significant and c.confirmed]
    assert cands[: len(confirmed)] == confirmed
    held = [c.heldout_after_mm for c in confirmed]
    assert held == sorted(held)
    rest = cands[len(confirmed):]
    for group in ([c for c in rest if c.significant], [c for c in rest if not c.significant]):
        scores = [c.score for c in group]
        assert scores == sorted(scores, reverse=True)


def test_backlash_joint_is_split_by_approach_direction(story):
    """Before the backlash step, joint 2's residual is two bands: coloured by direction,
    one median per band, about 2b apart (a little less: the model without backlash absorbs
    part of it in its other parameters, since the approach direction correlates with the
    angle)."""
    _, _, rep = story
    k = [s.effect for s in rep.story.added].index("backlash:2")
    before, after = rep.story.steps[k].fit, rep.story.steps[k + 1].fit
    cloud = points_of(before, before.data)
    fig = fig_joints(cloud, by_direction=1)
    medians = [ln for ln in fig.axes[1].lines if len(ln.get_xdata()) > 2]
    assert len(medians) == 2
    b = after.param("backlash.j2.b")[0] * 1e6
    levels = sorted(float(np.nanmedian(ln.get_ydata())) for ln in medians)
    gap = levels[1] - levels[0]
    assert 0.7 * 2 * abs(b) < gap < 1.1 * 2 * abs(b)
