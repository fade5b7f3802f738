"""Render a ``cellcal report`` page with headless Chromium and check every plot decoded.

    .venv/bin/python benchmarks/report_screenshot.py [REPORT.html] [--out shot.png]
                                                     [--width 800] [--plain]

Without REPORT.html, simulates a UR5e with three hidden effects (joint-3 compliance, a
twice-per-turn error of joint 4, joint-2 backlash; 300 + 300 poses, 1 % blunders in the
calibration rows), writes its report with the automatic diagnosis' story (``--plain``: the
three-stage report without it) to a temporary directory, prints a table of its size and
build times, and renders it. A small script is injected into a copy of the page: once
loaded, it sets ``document.title`` to ``IMAGES ok/total`` (an <img> counts as ok when it
decoded: ``complete`` and ``naturalWidth > 0``), which Chromium prints with
``--dump-dom``. The screenshot is written too (default report_screenshot.png, 800 px wide:
the narrowest window the report is made for) for a person to look at.

Exit codes: 0 every image decoded, 1 some did not (or Chromium failed), 2 no Chromium
(install it with ``apt-get install -y chromium``).
"""

from __future__ import annotations

import argparse
import re
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

CHECK = """<script>
window.addEventListener('load', function () {
  var imgs = Array.prototype.slice.call(document.images);
  var ok = imgs.filter(function (i) { return i.complete && i.naturalWidth > 0; }).length;
  var size = imgs.map(function (i) { return i.naturalWidth + 'x' + i.naturalHeight; });
  document.title = 'IMAGES ' + ok + '/' + imgs.length + ' ' + size.join(',');
});
</script>"""

FLAGS = ["--headless", "--no-sandbox", "--disable-gpu", "--disable-background-networking",
         "--disable-component-update", "--disable-sync", "--no-first-run",
         "--hide-scrollbars", "--virtual-time-budget=5000"]


def find_chromium() -> str | None:
    for name in ("chromium", "chromium-browser", "google-chrome", "google-chrome-stable"):
        path = shutil.which(name)
        if path:
            return path
    return "/usr/bin/chromium" if Path("/usr/bin/chromium").exists() else None


def make_report(workdir: Path, auto: bool = True) -> Path:
    import numpy as np

    from calibration import DEFAULT_EFFECTS, ErrorModel, load_model
    from calibration.fit.simulate import add_blunders, random_joints, realistic_truth, simulate
    from presentation.html_report import build_report
    from presentation.provenance import Provenance

    hidden = "compliance:3,harmonic2:4,backlash:2"
    model = load_model("ur5e")
    em = ErrorModel(model, DEFAULT_EFFECTS + "," + hidden)
    rng = np.random.default_rng(1)
    x = realistic_truth(em, rng)
    n = 600
    q = random_joints(model, n, rng)
    dirs = np.zeros((n, 6), int)
    dirs[1:] = np.sign(np.diff(q, axis=0))
    data = simulate(em, x, q, 0.015, rng, is_valid=np.arange(n) >= 300, dirs=dirs)
    data, _ = add_blunders(data, 0.01, np.random.default_rng(5), rows=~data.is_valid)
    data.source = f"simulated UR5e, hidden {hidden}"
    csv = workdir / "sim.csv"
    data.to_csv(csv)
    t0 = time.perf_counter()
    rep = build_report(data, model, auto=auto, provenance=Provenance.of(model.name, csv, data))
    path = rep.write(workdir / "report.html")
    total = time.perf_counter() - t0
    t = rep.timings
    print(f"{'poses':>6} {'figures':>7} {'MB':>5} {'fit s':>6} {'auto s':>6} "
          f"{'diag s':>6} {'render s':>8} {'total s':>7}")
    print(f"{n:>6} {len(rep.figures):>7} {path.stat().st_size / 1e6:>5.2f} "
          f"{t.get('fit_s', 0):>6.1f} {t.get('auto_s', 0):>6.1f} {t.get('diagnose_s', 0):>6.1f} "
          f"{t.get('render_s', 0):>8.1f} {total:>7.1f}")
    return path


def run_chromium(chromium: str, args: list[str], timeout: float = 120.0):
    with tempfile.TemporaryDirectory(prefix="cellcal-chromium-") as profile:
        return subprocess.run([chromium, *FLAGS, f"--user-data-dir={profile}", *args],
                              capture_output=True, text=True, timeout=timeout)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("report", nargs="?", help="report HTML (default: make one)")
    ap.add_argument("--out", default="report_screenshot.png", help="screenshot PNG")
    ap.add_argument("--width", type=int, default=800)
    ap.add_argument("--height", type=int, default=9000)
    ap.add_argument("--plain", action="store_true",
                    help="without REPORT.html: the report without the automatic diagnosis")
    args = ap.parse_args(argv)

    chromium = find_chromium()
    if chromium is None:
        print("report_screenshot: Chromium not found; install it with "
              "`apt-get update && apt-get install -y chromium`", file=sys.stderr)
        return 2
    with tempfile.TemporaryDirectory(prefix="cellcal-report-") as tmp:
        tmp = Path(tmp)
        page = (Path(args.report).resolve() if args.report
                else make_report(tmp, auto=not args.plain))
        text = page.read_text(encoding="utf-8")
        n_img = len(re.findall(r"<img\b", text))
        probe = tmp / "probe.html"
        probe.write_text(text.replace("</body>", CHECK + "</body>", 1), encoding="utf-8")

        res = run_chromium(chromium, ["--dump-dom", probe.as_uri()])
        m = re.search(r"<title>IMAGES (\d+)/(\d+) ?([^<]*)</title>", res.stdout)
        if m is None:
            print(f"report_screenshot: Chromium gave no result (exit {res.returncode}):\n"
                  f"{res.stderr[-2000:]}", file=sys.stderr)
            return 1
        ok, total = int(m[1]), int(m[2])
        print(f"images decoded: {ok}/{total} (page has {n_img} <img>); sizes {m[3]}")

        out = Path(args.out).resolve()
        res = run_chromium(chromium, [f"--screenshot={out}",
                                      f"--window-size={args.width},{args.height}",
                                      page.as_uri()])
        if not out.exists():
            print(f"report_screenshot: no screenshot (exit {res.returncode}):\n"
                  f"{res.stderr[-2000:]}", file=sys.stderr)
            return 1
        print(f"screenshot: {out}")
    return 0 if ok == total == n_img and total > 0 else 1


if __name__ == "__main__":
    sys.exit(main())
