"""The speed benchmarks run (on tiny sizes, one run each), so that they cannot rot: their
figures are measured by hand (docs/speed.md), but the scripts are kept working."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]


@pytest.mark.parametrize("script", ["identify.py", "diagnose.py", "speed.py"])
def test_benchmark_runs_on_a_tiny_size(script):
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    out = subprocess.run([sys.executable, str(ROOT / "benchmarks" / script), "--quick"],
                         capture_output=True, text=True, timeout=600, env=env, cwd=ROOT)
    assert out.returncode == 0, out.stderr
    assert "reference" in out.stdout or script == "identify.py"


@pytest.mark.slow
def test_the_scaling_benchmark_runs_on_small_sizes(tmp_path):
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    out = subprocess.run([sys.executable, str(ROOT / "benchmarks" / "scaling.py"), "--sizes",
                          "150,1000", "--quick", "--workdir", str(tmp_path)],
                         capture_output=True, text=True, timeout=1200, env=env, cwd=ROOT)
    assert out.returncode == 0, out.stderr
    for row in ("calibrate", "diagnose --auto", "report", "compensate", "export", "history",
                "solve, in process", "500 real-shaped poses", "first solve"):
        assert row in out.stdout, row
    assert "fails" not in out.stdout
