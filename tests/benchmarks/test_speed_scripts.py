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
