"""The demo's and the cold-start demo's HTML reports, as a reader gets them: what the
blunder section says agrees with its table, and a real browser opens both pages.

The browser is Chromium, driven by Playwright through the system's Chromium
(``apt-get install chromium``; Playwright's own browser download is not needed): no
console error, every figure loaded with a non-zero size, no horizontal overflow at 1280 px,
the sections present. The full-page screenshots are kept in ``tests/artifacts/`` (ignored
by git; the test prints where). Without Chromium or Playwright the browser test is skipped,
saying so, except in CI (``.ci/run`` installs both and sets ``CELLCAL_REQUIRE_BROWSER=1``:
there it fails).
"""

from __future__ import annotations

import html
import json
import os
import re
import shutil
from pathlib import Path

import pytest

from cellcal.cli import main

pytestmark = pytest.mark.slow

ARTIFACTS = Path(__file__).resolve().parents[1] / "artifacts"
#: the sections every report has (its h2 headings start so), and a report with the
#: automatic diagnosis' story besides
SECTIONS = ("Measurements left out (blunders)", "Where the ", "Candidate effects",
            "Parameters")
STORY = ("What each step fixed",)


@pytest.fixture(scope="module")
def demo_reports(tmp_path_factory):
    """{"demo": folder, "cold-start": folder}: each demo run once, at seed 1 (the
    cold-start one with its documented pose counts: the report of issue 36)."""
    root = tmp_path_factory.mktemp("demos")
    out = {"demo": root / "demo", "cold-start": root / "cold"}
    assert main(["demo", "--seed", "1", "--poses", "150", "--valid", "60", "--quiet",
                 "--out", str(out["demo"])]) == 0
    assert main(["demo", "--cold-start", "--seed", "1", "--quiet", "--out",
                 str(out["cold-start"])]) == 0
    return out


def _section(page: str, title: str) -> str:
    start = page.index(f"<h2>{title}</h2>")
    end = page.find("<h2>", start + 4)
    return page[start:end if end >= 0 else None]


def test_cold_start_blunder_sentence_and_table_agree(demo_reports, capsys):
    """Issue 36: the cold-start demo's report said "No measurement is out of line" above a
    table listing the drift check ``drift1.1``. Drift-check readings measure the drift: the
    blunder test leaves them to the drift checks' own bound, every fit keeps them, and the
    sentence says so."""
    capsys.readouterr()
    folder = demo_reports["cold-start"]
    page = (folder / "report.html").read_text()
    part = _section(page, "Measurements left out (blunders)")
    text = " ".join(html.unescape(re.sub(r"<[^>]+>", " ", part)).split())
    listed = re.findall(r"<tr><td><code>([^<]+)</code>", part)
    assert not [p for p in listed if p.startswith("drift")]
    if "No measurement is out of line" in text:  # then no table, or one the text explains
        assert not listed or "The table also lists" in text
    assert "drift-check readings are not tested: each measures the drift itself" in text
    csv = (folder / "capture.csv").read_text().splitlines()
    n_drift = sum(line.endswith(",drift") for line in csv)
    n_calib = sum(line.endswith(",calib") for line in csv)
    assert n_drift >= 10
    params = json.loads((folder / "params.json").read_text())
    assert params["stats"]["calib"]["n"] == n_calib + n_drift - len(params["outliers"])
    assert not [o for o in params["outliers"] if o["pose_id"].startswith("drift")]


def _chromium() -> str | None:
    for name in (os.environ.get("CELLCAL_CHROMIUM"), "chromium", "chromium-browser",
                 "google-chrome"):
        if name and shutil.which(name):
            return shutil.which(name)
    return None


@pytest.fixture
def browser():
    """A headless Chromium (the system's) under Playwright, one per test (its driver's
    threads and processes end with it); skipped when either is missing, except where
    ``CELLCAL_REQUIRE_BROWSER=1`` (CI)."""
    required = os.environ.get("CELLCAL_REQUIRE_BROWSER") == "1"
    exe = _chromium()
    try:
        from playwright.sync_api import sync_playwright
    except ImportError:
        sync_playwright = None
    missing = ("Playwright (pip install playwright)" if sync_playwright is None else
               "Chromium (apt-get install chromium)" if exe is None else None)
    if missing:
        if required:
            pytest.fail(f"CELLCAL_REQUIRE_BROWSER=1 but {missing} is not installed")
        pytest.skip(f"needs {missing}")
    with sync_playwright() as p:
        b = p.chromium.launch(executable_path=exe, args=["--no-sandbox"])
        try:
            yield b
        finally:
            b.close()


_LAYOUT = """() => ({
  scrollWidth: document.documentElement.scrollWidth,
  viewport: window.innerWidth,
  wide: Array.from(document.body.querySelectorAll('*'))
    .filter(e => e.getBoundingClientRect().right > window.innerWidth + 0.5
                 && !e.closest('.scroll'))
    .map(e => e.tagName + (e.id ? '#' + e.id : '')).slice(0, 10),
  images: Array.from(document.images).map(i => ({
    alt: i.alt, complete: i.complete, w: i.naturalWidth, h: i.naturalHeight,
    shown: i.getBoundingClientRect().width})),
  headings: Array.from(document.querySelectorAll('h2')).map(h => h.textContent.trim()),
})"""


@pytest.mark.parametrize("which", ["demo", "cold-start"])
def test_report_in_a_real_browser(demo_reports, browser, which, capsys):
    report = demo_reports[which] / "report.html"
    page = browser.new_page(viewport={"width": 1280, "height": 900})
    errors = []
    page.on("console", lambda m: errors.append(f"console {m.type}: {m.text}")
            if m.type in ("error", "assert") else None)
    page.on("pageerror", lambda e: errors.append(f"page error: {e}"))
    page.on("requestfailed", lambda r: errors.append(f"request failed: {r.url[:80]}"))
    try:
        page.goto(report.as_uri(), wait_until="load")
        info = page.evaluate(_LAYOUT)
        ARTIFACTS.mkdir(exist_ok=True)
        shot = ARTIFACTS / f"report-{which}.png"
        page.screenshot(path=str(shot), full_page=True)
    finally:
        page.close()
    with capsys.disabled():
        print(f"\n{which} report screenshot: {shot}")
    assert errors == []
    images = info["images"]
    assert len(images) >= 5
    bad = [i for i in images if not (i["complete"] and i["w"] > 0 and i["h"] > 0
                                     and i["shown"] > 0)]
    assert bad == [], bad
    assert info["scrollWidth"] <= info["viewport"], info["wide"]
    expected = SECTIONS + (STORY if 'id="fig-steps"' in report.read_text() else ())
    for title in expected:
        assert any(h.startswith(title) for h in info["headings"]), (title, info["headings"])
    assert shot.stat().st_size > 10_000
