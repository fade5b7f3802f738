"""The calibrated tool frame in the exports (issue 27): a full-pose fit's ``tool_rotation``
goes to the model YAML as ``tool_rpy_deg`` and to the URDF's tcp_joint rpy, each checked
by its parity check on the tool frame's orientation; an old model YAML (no
``tool_rpy_deg``) loads and hashes as before; UR's exports say where UR keeps its TCP."""

from __future__ import annotations

import numpy as np
import pytest

from calibration import load_model
from calibration.exports.model_export import calibrated_model, write_model_yaml
from calibration.exports.parity import model_file_parity
from calibration.exports.urdf_export import write_urdf
from calibration.fit.error_model import ErrorModel
from calibration.model.transforms import rotvec_to_matrix
from tests.calibration.test_full_pose import FULL, POSITION, _truth


@pytest.fixture(scope="module")
def full_pose():
    model = load_model("ur10e")
    em, x, _ = _truth(model)
    return model, em, x


def test_the_model_yaml_carries_the_tool_rotation(full_pose, tmp_path):
    _, em, x = full_pose
    m, notes = calibrated_model(em, x)
    assert np.allclose(m.tool_R(), rotvec_to_matrix(x[em.slices[3]]), atol=1e-12)
    path = tmp_path / "cal.yaml"
    write_model_yaml(m, path, notes)
    assert "tool_rpy_deg" in path.read_text()
    back = load_model(path)
    assert np.allclose(back.tool_rpy_deg, m.tool_rpy_deg)
    parity = model_file_parity(path, m)
    assert parity.max_mm < 1e-6 and parity.max_rad < 1e-9
    assert any("tool_rpy_deg" in n and "installation" in n for n in notes)


def test_the_urdf_turns_its_tcp_by_the_tool_rotation(full_pose, tmp_path):
    _, em, x = full_pose
    m, notes = calibrated_model(em, x)
    parity = write_urdf(m, tmp_path / "cal.urdf", notes)
    assert parity.max_mm < 1e-6 and parity.max_rad < 1e-9
    # a URDF without the turn would miss the tool frame by the tool rotation's angle
    flat = m.with_changes(tool_rpy_deg=None)
    write_urdf(flat, tmp_path / "flat.urdf")
    from calibration.exports.urdf_export import urdf_parity

    assert urdf_parity(tmp_path / "flat.urdf", m, n=20).max_rad > np.radians(1.0)


def test_position_only_models_keep_the_old_format(full_pose, tmp_path):
    model, _, _ = full_pose
    em = ErrorModel(model, POSITION)
    m, _ = calibrated_model(em, np.zeros(em.n_params))
    assert m.tool_rpy_deg is None and "tool_rpy_deg" not in m.to_yaml()
    assert model.definition_hash() == load_model("ur10e").definition_hash()
    assert ErrorModel(model, FULL).n_params > em.n_params
