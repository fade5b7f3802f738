"""The HTML report: self-contained, every plot present, numbers that match the fits."""

import base64
import html
import re

import numpy as np
import pytest

from calibration import DEFAULT_EFFECTS, ErrorModel, identify, load_model
from calibration.diagnosis.diagnosis import diagnose
from calibration.fit.simulate import random_joints, realistic_truth, simulate
from presentation.figures import MAX_POINTS, Stage, _subsample
from presentation.html_report import _value_std, build_report, render_report

FIGURES = ["fig-story", "fig-hist", "fig-workspace", "fig-joints", "fig-torque", "fig-time",
           "fig-periodogram"]


def _data(model, hidden: str, n_calib: int, n_valid: int, seed: int, **columns):
    """The recipe of ``cellcal simulate``: realistic hidden errors, 0.015 mm tracker noise."""
    em = ErrorModel(model, DEFAULT_EFFECTS + ("," + hidden if hidden else ""))
    rng = np.random.default_rng(seed)
    x = realistic_truth(em, rng)
    n = n_calib + n_valid
    q = random_joints(model, n, rng)
    return simulate(em, x, q, 0.015, rng, is_valid=np.arange(n) >= n_calib, **columns)


@pytest.fixture(scope="module")
def model():
    return load_model("ur5e")


@pytest.fixture(scope="module")
def compliance_report(model):
    data = _data(model, "compliance:3", 300, 300, seed=1)
    return data, build_report(data, model)


def _images(page: str) -> list[str]:
    return re.findall(r"<img\b[^>]*\bsrc=\"([^\"]*)\"", page)


def assert_self_contained(page: str) -> None:
    assert "http://" not in page and "https://" not in page
    assert "<link" not in page and "<script" not in page and "@import" not in page
    srcs = _images(page)
    assert srcs and len(srcs) == page.count("<img")
    for src in srcs:
        assert src.startswith("data:image/png;base64,")
        assert base64.b64decode(src.split(",", 1)[1])[:8] == b"\x89PNG\r\n\x1a\n"
    assert re.findall(r"\b(?:src|href)=\"(?!data:)", page) == []


def test_page_is_self_contained_with_every_plot(compliance_report):
    _, rep = compliance_report
    page = rep.html
    assert page.startswith("<!DOCTYPE html>") and page.rstrip().endswith("</html>")
    assert_self_contained(page)
    assert [f for f, _ in rep.figures] == FIGURES
    assert len(_images(page)) == len(FIGURES)
    for fig_id in FIGURES:
        block = re.search(rf'<figure id="{fig_id}">(.*?)</figure>', page, re.S)
        assert block and "<figcaption>" in block[1], fig_id
    for table_id in ("tab-stats", "tab-candidates", "tab-params"):
        assert f'id="{table_id}"' in page
    assert len(page) < 3e6


def _stats_rows(page: str) -> dict[str, list[str]]:
    table = re.search(r'<table class="stats" id="tab-stats">(.*?)</table>', page, re.S)[1]
    rows = {}
    for tr in re.findall(r"<tr>(.*?)</tr>", table, re.S):
        cells = [re.sub(r"<[^>]+>", "", c) for c in re.findall(r"<td[^>]*>(.*?)</td>", tr, re.S)]
        if cells:
            rows[html.unescape(cells[0])] = cells
    return rows


def test_before_after_numbers_match_independent_fits(compliance_report, model):
    data, rep = compliance_report
    rows = _stats_rows(rep.html)
    expected = {
        "uncalibrated": identify(ErrorModel(model, "base,tool"), data),
        "current model": identify(ErrorModel(model, DEFAULT_EFFECTS), data),
        "current model + compliance:3": identify(
            ErrorModel(model, DEFAULT_EFFECTS + ",compliance:3"), data),
    }
    assert list(rows) == list(expected)
    for label, fit in expected.items():
        cells = rows[label]
        # model, effects, params, then n rms mean p95 max for calibration and validation
        assert cells[3:8] == [str(fit.calib["n"])] + [
            f"{fit.calib[k]:.4f}" for k in ("rms_mm", "mean_mm", "p95_mm", "max_mm")]
        assert cells[8:13] == [str(fit.valid["n"])] + [
            f"{fit.valid[k]:.4f}" for k in ("rms_mm", "mean_mm", "p95_mm", "max_mm")]
    floor = data.noise_floor_mm()
    assert f"{floor:.4f}" in rep.html
    assert expected["current model + compliance:3"].valid["rms_mm"] < \
        expected["current model"].valid["rms_mm"]


def test_recommended_effect_is_the_hidden_one(compliance_report):
    _, rep = compliance_report
    diag = rep.diagnosis
    assert diag.best is not None and diag.best.effect == "compliance:3"
    page = rep.html
    assert html.escape(diag.recommendation()) in page
    assert "--effects geometric,base,tool,compliance:3" in page
    assert re.search(r'<tr class="best"><td><code>compliance:3</code>', page)
    # the refitted compliance parameter is tabulated, highlighted
    assert re.search(r'<tr class="best"><td><code>compliance\.j3\.c</code>', page)
    # its fitted correction is drawn against the joint-3 torque
    assert "Orange" in re.search(r'<figure id="fig-torque">(.*?)</figure>', page, re.S)[1]
    assert [s.label for s in rep.stages][-1] == "current model + compliance:3"


def test_render_from_computed_fits_is_deterministic_and_optional_panels(model):
    """The demo's path: fits and a diagnosis computed elsewhere; no validation rows; time
    and temperature columns; no missing effect (at the noise floor)."""
    n = 80
    t = np.arange(n) * 30.0
    data = _data(model, "", n, 0, seed=5, t_s=t, temp_c=20.0 + t / 1000.0)
    base = identify(ErrorModel(model, "base"), data)
    cur = identify(ErrorModel(model, DEFAULT_EFFECTS), data)
    diag = diagnose(cur, data, confirm=1, folds=2)
    assert diag.best is None
    a = render_report(diag, [("uncalibrated", base), ("current", cur)], title="x<y", dpi=40)
    b = render_report(diag, [Stage("uncalibrated", base), Stage("current", cur)],
                      title="x<y", dpi=40)
    assert a.html == b.html
    assert_self_contained(a.html)
    assert "<h1>x&lt;y</h1>" in a.html
    assert "Next:" not in a.html and "validation poses" in a.html
    ids = [f for f, _ in a.figures]
    assert ids == FIGURES
    caption = re.search(r'<figure id="fig-time">(.*?)</figure>', a.html, re.S)[1]
    assert "temperature" in caption and "time since the first pose" in caption
    import matplotlib.pyplot as plt

    assert plt.get_fignums() == []  # nothing registered with pyplot, nothing leaked


def test_helpers():
    idx = _subsample(10_000)
    assert len(idx) == MAX_POINTS and np.all(np.diff(idx) > 0)
    assert np.array_equal(_subsample(10), np.arange(10))
    assert _value_std(0.0995362, 0.000918) == ("0.09954", "0.00092")
    assert _value_std(2512.3456, 0.0123) == ("2512.346", "0.012")
    assert _value_std(3.2e-6, 4.1e-8) == ("3.200e-06", "4.10e-08")
    assert _value_std(1.5, None) == ("1.5", "")


def test_the_blunder_sentence_agrees_with_the_table():
    """The verdict is the last fit's; a pose only an earlier fit left out is listed in the
    table and the sentence says so (issue 36: "No measurement is out of line" above a table
    of one)."""
    from calibration.fit.outliers import Blunder, BlunderScreen
    from presentation.html_tables import blunders_section

    blunder = Blunder("drift1.1", 0, 16, 0.113, 1.02, False, 74.0)
    earlier = BlunderScreen([blunder], 318, 1, 1.0, 0.015, 0.072, True, mode="exclude")
    clean = BlunderScreen([], 319, 0, 1.0, 0.015, 0.072, True, mode="exclude")
    text = blunders_section([("geometric,base,tool", earlier), ("+ thermal_zero:1", clean)])
    plain = re.sub(r"<[^>]+>", " ", html.unescape(text))
    assert "No measurement is out of line (threshold 0.072 mm)." in plain
    assert ("The table also lists drift1.1: only the fit of geometric,base,tool left it out "
            "(out of line with a model that still lacked an effect); the last fit keeps it."
            in plain)
    assert 'id="tab-blunders"' in text and "<code>drift1.1</code>" in text
    # named by the last fit too: the verdict itself names it, nothing is added
    text = blunders_section([("geometric,base,tool", earlier), ("diagnosis", earlier)])
    assert "The table also lists" not in text and "1 measurement looks like a blunder" in text
    # named by no fit: the verdict alone, no table
    text = blunders_section([("geometric,base,tool", clean)])
    assert 'id="blunders-none"' in text and "tab-blunders" not in text
