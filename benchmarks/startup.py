"""Start-up time of every ``cellcal`` command: ``--help`` and an argument error, against
``python -c 'import numpy'`` measured in the same run (the machine's pace).

Each command runs as a fresh ``python -m cellcal ...`` process; the table gives the median
wall time over ``--runs`` runs. The target: ``--help`` and argument errors well under
0.3 s, i.e. less than importing numpy (building the parser imports no numpy, scipy,
matplotlib or pydantic; see :mod:`cellcal.cli`).

    python benchmarks/startup.py                 # this checkout
    python benchmarks/startup.py --root DIR      # another checkout (e.g. an older commit)
"""

from __future__ import annotations

import argparse
import os
import statistics
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]

#: (label, arguments after ``python -m cellcal``, expected exit code)
CASES = [
    ("cellcal --help", ["--help"], 0),
    ("cellcal (bare)", [], 0),
    ("cellcal --version", ["--version"], 0),
    ("demo --help", ["demo", "--help"], 0),
    ("capture poses --help", ["capture", "poses", "--help"], 0),
    ("capture poses (bad arg)", ["capture", "poses", "--count", "x"], 2),
    ("runs --help", ["runs", "--help"], 0),
    ("resume --help", ["resume", "--help"], 0),
    ("export --help", ["export", "--help"], 0),
    ("calibrate --help", ["calibrate", "--help"], 0),
    ("calibrate (no args)", ["calibrate"], 2),
    ("diagnose --help", ["diagnose", "--help"], 0),
    ("models --help", ["models", "--help"], 0),
    ("sim serve --help", ["sim", "serve", "--help"], 0),
    ("simulate --help", ["simulate", "--help"], 0),
    ("zero --help", ["zero", "--help"], 0),
    ("report --help", ["report", "--help"], 0),
    ("compensate --help", ["compensate", "--help"], 0),
    ("compensate (no args)", ["compensate"], 2),
]


def wall(cmd: list[str], env: dict, expect: int | None) -> float:
    t = time.perf_counter()
    out = subprocess.run(cmd, env=env, cwd=env["PYTHONPATH"], stdout=subprocess.DEVNULL,
                         stderr=subprocess.PIPE, timeout=120)
    dt = time.perf_counter() - t
    if expect is not None and out.returncode != expect:
        raise SystemExit(f"{' '.join(cmd)}: exit {out.returncode}, expected {expect}\n"
                         f"{out.stderr.decode()[-500:]}")
    return dt


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--root", default=str(ROOT), help="the checkout to time (default: this)")
    ap.add_argument("--runs", type=int, default=7, help="runs per case (default 7)")
    a = ap.parse_args()
    env = {**os.environ, "PYTHONPATH": a.root}
    py = sys.executable
    ref = [("python -c pass", [py, "-c", "pass"]),
           ("python -c 'import numpy'", [py, "-c", "import numpy"])]
    rows = []
    for label, cmd in ref:
        rows.append((label, statistics.median(wall(cmd, env, 0) for _ in range(a.runs)), None))
    numpy_s = rows[1][1]
    this = Path(a.root).resolve() == ROOT  # exit codes are checked for this checkout only
    for label, args, code in CASES:
        cmd = [py, "-m", "cellcal", *args]
        rows.append((label, statistics.median(wall(cmd, env, code if this else None)
                                              for _ in range(a.runs)), code))
    print(f"start-up of {a.root}: median of {a.runs} runs; 'x numpy' = time / "
          "time of python -c 'import numpy' (same run)")
    print(f"{'command':<28} {'median s':>9} {'x numpy':>8}")
    print("-" * 47)
    for label, t, _ in rows:
        print(f"{label:<28} {t:>9.3f} {t / numpy_s:>8.2f}")
    worst = max(t for label, t, _ in rows[2:])
    print(f"slowest cellcal case: {worst:.3f} s ({worst / numpy_s:.2f} x import numpy)")


if __name__ == "__main__":
    main()
