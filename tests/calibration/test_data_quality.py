"""Data too poor to identify a model are refused (not fitted), with the reason and what to
capture; parameters the data hardly determine are marked weak."""

from __future__ import annotations

import numpy as np
import pytest

from calibration import ErrorModel, identify, load_model
from calibration.fit.data_quality import InsufficientData, check_for_fit, distinct_poses
from calibration.fit.simulate import random_joints, realistic_truth, simulate

UR5 = load_model("ur5")


def _data(n, seed=0, q=None, **columns):
    em = ErrorModel(UR5)
    rng = np.random.default_rng(seed)
    x = realistic_truth(em, rng)
    q = random_joints(UR5, n, rng) if q is None else q
    return em, simulate(em, x, q, 0.015, rng, **columns)


def test_a_well_spread_data_set_passes():
    em, data = _data(60)
    v = check_for_fit(em, data)
    assert v.n_distinct == 60 and 20 <= v.n_identifiable <= 30 and not v.notes


@pytest.mark.parametrize("n", [1, 5, 8])
def test_fewer_observations_than_parameters_are_refused(n):
    em, data = _data(n)
    with pytest.raises(InsufficientData, match=r"observations for \d+ identifiable .*capture "
                                               r"at least \d+ distinct poses"):
        check_for_fit(em, data)


def test_a_hundred_repeats_of_one_pose_are_one_pose():
    rng = np.random.default_rng(3)
    q = np.repeat(random_joints(UR5, 1, rng), 100, axis=0) + rng.normal(0, 1e-5, (100, 6))
    em, data = _data(100, q=q)
    assert distinct_poses(data.q) <= 2
    with pytest.raises(InsufficientData, match="100 poses, but only [12] distinct"):
        check_for_fit(em, data)


def test_joints_in_radians_are_named():
    em, data = _data(60)
    data.q = np.radians(data.q)  # degrees columns holding radians, as read
    with pytest.raises(InsufficientData, match="look like radians"):
        check_for_fit(em, data)


def test_no_calibration_rows():
    em, data = _data(30, is_valid=np.ones(30, bool))
    with pytest.raises(InsufficientData, match="all 30 rows are set=valid"):
        check_for_fit(em, data)


def test_a_rank_deficient_design_is_refused():
    """Joints 2 and 3 moving only together (q3 = -q2) cannot separate their errors."""
    rng = np.random.default_rng(4)
    q = random_joints(UR5, 80, rng)
    q[:, 2] = -q[:, 1]
    em, data = _data(80, q=q)
    with pytest.raises(InsufficientData, match="rank-deficient design"):
        check_for_fit(em, data)


def test_weakly_identified_parameters_are_marked():
    em, data = _data(60, seed=7)
    fit = identify(em, data)
    weak = fit.weakly_identified()
    rows = {r["name"]: r for r in fit.parameter_rows()}
    assert weak and all(rows[n]["weak"] == why for n, why in weak.items())
    free = list(np.flatnonzero(fit.free))
    R = np.abs(fit.correlation())
    np.fill_diagonal(R, 0.0)
    for n in weak:
        k = em.index(n)
        assert fit.std[k] >= abs(fit.values[k]) or R[free.index(k)].max() >= 0.999
    for n, r in rows.items():
        if r["identifiable"] and n not in weak:
            assert r["std"] < abs(r["value"])
