"""Analytic Jacobians of the measured point against finite differences."""

import numpy as np
import pytest

from calibration import Dataset, ErrorModel, builtin_models, load_model
from calibration.fit.simulate import random_joints, realistic_truth


@pytest.mark.parametrize("name", builtin_models())
def test_default_model_jacobian_matches_finite_differences(name):
    m = load_model(name)
    em = ErrorModel(m)
    rng = np.random.default_rng(11)
    q = random_joints(m, 40, rng)
    bound = em.bind(Dataset(q=q, tracker_p_smr=np.zeros((40, 3))))
    # far from nominal: big geometric errors, a base in an arbitrary orientation
    x = realistic_truth(em, rng, length_mm=2.0, angle_deg=0.5)
    _, J = em.evaluate(x, bound)
    # step 1e-4: with the base turned ~3 rad (panda) the 1e-3 step's truncation error alone
    # reached 1.3e-6
    Jn = em.numeric_jacobian(x, bound, rel=1e-4)
    scale = np.abs(J).max(axis=(0, 1)) + 1.0
    err = np.abs(J - Jn).max(axis=(0, 1)) / scale
    worst = int(np.argmax(err))
    assert err.max() < 1e-6, f"{em.names[worst]}: relative error {err.max():.2e}"


def test_base_jacobian_near_half_turn():
    m = load_model("ur10e")
    em = ErrorModel(m)
    rng = np.random.default_rng(2)
    bound = em.bind(Dataset(q=random_joints(m, 10, rng), tracker_p_smr=np.zeros((10, 3))))
    x = realistic_truth(em, rng)
    k = em.index("base.rx")
    x[k : k + 3] = np.array([1.0, 2.0, 2.0]) / 3.0 * (np.pi - 1e-3)
    _, J = em.evaluate(x, bound)
    Jn = em.numeric_jacobian(x, bound)
    np.testing.assert_allclose(J[:, :, k : k + 3], Jn[:, :, k : k + 3], atol=1e-5 * np.abs(J).max())
