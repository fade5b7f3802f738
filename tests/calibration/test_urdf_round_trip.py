"""Identification round trips for models read from URDF files (UR-style, the 7-axis arm,
a prismatic track + UR10e), as for the built-in models in test_identify.py."""

import numpy as np
import pytest

from calibration import identify, load_model

from .test_identify import SEEDS, _dataset
from .test_urdf_model import rows_of, track_model
from .urdf_writers import dh_chain_urdf, ur_style_urdf


def urdf_spec(tmp_path, which: str) -> str:
    if which == "ur10e-style":
        return f"{ur_style_urdf(tmp_path / 'ur.urdf', load_model('ur10e'))}#base_link:tool0"
    if which == "panda-urdf":
        ref = load_model("panda")
        return str(dh_chain_urdf(tmp_path / "panda.urdf", "mdh", rows_of(ref), tool=ref.tool,
                                 rng=np.random.default_rng(5), split_fixed=True))
    return str(track_model(tmp_path)[0])


@pytest.mark.parametrize("which", ["ur10e-style", "panda-urdf", "track"])
def test_urdf_model_round_trip_reaches_noise_floor(tmp_path, which):
    spec = urdf_spec(tmp_path, which)
    # the panda from a URDF is the built-in panda: same seed as there (see test_identify)
    em, x_true, data = _dataset(spec, seed=SEEDS["panda"] if which == "panda-urdf" else 5)
    fit = identify(em, data)
    assert fit.converged, fit.reason
    free = fit.free
    z = (fit.values[free] - x_true[free]) / fit.std[free]
    names = [n for n, f in zip(em.names, free, strict=True) if f]
    worst = int(np.argmax(np.abs(z)))
    assert np.abs(z).max() < 3.0, f"{names[worst]} off by {z[worst]:.1f} sigma"
    np.testing.assert_allclose(fit.values[~free], x_true[~free], atol=1e-12)
    assert fit.valid["rms_mm"] == pytest.approx(data.noise_floor_mm(), rel=0.05)
    assert 0.6 < np.std(z) < 1.4
