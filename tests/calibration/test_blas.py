"""Small identification problems run on one BLAS thread (timings that do not depend on the
neighbours); large ones keep BLAS's threads."""

from __future__ import annotations

import contextlib
import sys

import numpy as np
from threadpoolctl import threadpool_info

from calibration import ErrorModel, identify, load_model
from calibration.fit.simulate import random_joints, realistic_truth, simulate
from calibration.numerics.blas import SMALL_ELEMENTS, blas_threads


def _blas_threads() -> set[int]:
    return {i["num_threads"] for i in threadpool_info() if i["user_api"] == "blas"}


def test_one_blas_thread_inside_for_a_small_problem_only():
    before = _blas_threads()
    with blas_threads(3 * 1000 * 35):
        assert _blas_threads() == {1}
    assert _blas_threads() == before
    with blas_threads(SMALL_ELEMENTS + 1):
        assert _blas_threads() == before


def test_identify_runs_in_the_limit(monkeypatch):
    seen = []

    @contextlib.contextmanager
    def spy(n, small=None):
        seen.append(n)
        with blas_threads(n, small):
            yield

    # the module (the package's ``identify`` is the function)
    monkeypatch.setattr(sys.modules["calibration.fit.identify"], "blas_threads", spy)
    m = load_model("ur5")
    em = ErrorModel(m)
    rng = np.random.default_rng(0)
    data = simulate(em, realistic_truth(em, rng), random_joints(m, 60, rng), 0.01, rng)
    fit = identify(em, data)
    assert fit.converged and seen == [3 * 60 * em.n_params]


def test_scipy_blas_loaded_after_the_first_limit_is_pinned_too():
    # the default calibrate never loads scipy; a diagnosis loads it (and its own BLAS)
    # after the first identification made the controller
    import subprocess

    code = ("import numpy\nfrom threadpoolctl import threadpool_info\n"
            "from calibration.numerics.blas import blas_threads\n"
            "with blas_threads(10):\n    pass\n"
            "import scipy.linalg\n"
            "with blas_threads(10):\n"
            "    print(sorted(i['num_threads'] for i in threadpool_info()"
            " if i['user_api'] == 'blas'))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True)
    assert out.stdout.strip() == "[1, 1]"
