"""Memory linear in the poses: `cellcal calibrate` of 20 000 poses under an address-space
limit that any n x n intermediate would break, and a limit too small for the data refused
before the work starts (exit 3, naming the size that would fit), never an internal error.

No timing: the limits are on memory (``resource.setrlimit`` in the child)."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

resource = pytest.importorskip("resource")

ROOT = Path(__file__).resolve().parents[2]
N_POSES = 20_000
#: an n x n float64 array of 20 000 poses is 3.0 GiB (the 3n x 3n of a position fit
#: 27 GiB); the fit itself needs a few hundred MiB: 1.5 GiB tells them apart
LIMIT_BYTES = 1536 << 20

pytestmark = pytest.mark.skipif(not sys.platform.startswith("linux"),
                                reason="address-space limits and /proc are Linux's")


def _env() -> dict:
    return {**os.environ, "PYTHONPATH": str(ROOT), "OPENBLAS_NUM_THREADS": "1",
            "OMP_NUM_THREADS": "1"}


def _run(args: list[str], limit: int | None = None, code: str | None = None):
    def limited() -> None:
        if limit is not None:
            resource.setrlimit(resource.RLIMIT_AS, (limit, limit))

    argv = [sys.executable, "-c", code] if code else [sys.executable, "-m", "cellcal", *args]
    return subprocess.run(argv, capture_output=True, text=True, timeout=600, env=_env(),
                          cwd=ROOT, preexec_fn=limited)


@pytest.fixture(scope="module")
def poses(tmp_path_factory) -> Path:
    path = tmp_path_factory.mktemp("memory") / "poses.csv"
    out = _run(["simulate", "--model", "ur10e", "--poses", str(N_POSES), "--valid", "0",
                "--seed", "3", "--out", str(path)])
    assert out.returncode == 0, out.stderr
    return path


def test_calibrate_of_20000_poses_fits_in_a_limit_no_n_by_n_array_would(poses):
    out = _run(["calibrate", "--model", "ur10e", str(poses), "--json"], limit=LIMIT_BYTES)
    assert out.returncode == 0, out.stderr
    doc = json.loads(out.stdout)
    assert doc["calib"]["n"] == N_POSES and doc["converged"]


def test_data_too_large_for_the_memory_left_are_refused_before_the_work(poses):
    # the address space calibrate holds before it fits (interpreter, libraries, data)
    started = _run([], code=(
        "import sys; sys.argv = ['cellcal', 'calibrate', '--model', 'ur10e', "
        f"{str(poses)!r}]\n"
        "import cellcal.usecases.inputs as i\n"
        "def stop(*a, **k):\n"
        "    print([l.split()[1] for l in open('/proc/self/status') if l.startswith('VmSize')]"
        "[0]); raise SystemExit(0)\n"
        "i.check_data = stop\n"
        "import cellcal.usecases.calibrate as c; c.check_data = stop\n"
        "from cellcal.cli import main; main()"))
    assert started.returncode == 0, started.stderr
    held = int(started.stdout.split()[-1]) * 1024
    out = _run(["calibrate", "--model", "ur10e", str(poses)], limit=held + (100 << 20))
    assert out.returncode == 3, out.stderr
    assert "internal error" not in out.stderr and "Traceback" not in out.stderr
    assert "of memory" in out.stderr and "poses fit" in out.stderr
    assert out.stdout == ""  # nothing was fitted
