"""Forward kinematics against published numbers and an independent formulation."""

import numpy as np
import pytest
import scipy.linalg
import yaml

from calibration import builtin_models, forward, load_model
from calibration.model.gravity import gravity_torques, potential_energy
from calibration.model.kinematics import run_chain
from tests.shared_data import shared_file


def _ur10_reference_model():
    """UR10 with alpha = 1.570796327, as UR's simulator computed the check values."""
    m = load_model("ur10")
    rows = [j.model_dump() for j in m.joints]
    for r in rows:
        if abs(r["alpha"]) == 90:
            r["alpha"] = np.sign(r["alpha"]) * np.degrees(1.570796327)
    return m.with_changes(joints=rows)


def test_fk_matches_universal_robots_check_values():
    ref = yaml.safe_load(shared_file("ur_reference_values.yaml").read_text())
    checks = [c for c in ref["fk_checks_ur10_nominal"] if "position" in c]
    assert len(checks) == 2
    m = _ur10_reference_model()
    for c in checks:
        p = forward(m, np.array(c["q"]))[0, -1, :3, 3]
        np.testing.assert_allclose(p, np.array(c["position"]) * 1000.0, rtol=0, atol=1e-9)


def test_fk_matches_universal_robots_formulas():
    m = load_model("ur10")
    t = m.dh_table()
    d1, d4, d5, d6 = t[0, 1], t[3, 1], t[4, 1], t[5, 1]
    a2, a3 = t[1, 2], t[2, 2]
    p0 = forward(m, np.zeros(6))[0, -1, :3, 3]
    np.testing.assert_allclose(p0, [a2 + a3, -(d4 + d6), d1 - d5], atol=1e-9)
    q = [np.pi / 2, -np.pi / 4, np.pi / 2, -np.pi / 4, 0, 0]
    p1 = forward(m, np.array(q))[0, -1, :3, 3]
    s = np.sqrt(2)
    np.testing.assert_allclose(p1, [d4 + d6, a2 / s + a3 / s, d1 - a2 / s + a3 / s - d5],
                               atol=1e-9)


def _textbook_link(convention, theta, d, a, alpha, beta):
    """One link as an explicit 4x4 product of elementary matrices."""

    def rot(axis, t):
        c, s = np.cos(t), np.sin(t)
        R = {"x": [[1, 0, 0], [0, c, -s], [0, s, c]],
             "y": [[c, 0, s], [0, 1, 0], [-s, 0, c]],
             "z": [[c, -s, 0], [s, c, 0], [0, 0, 1]]}[axis]
        T = np.eye(4)
        T[:3, :3] = R
        return T

    def trans(axis, v):
        T = np.eye(4)
        T["xyz".index(axis), 3] = v
        return T

    if convention == "dh":
        return rot("z", theta) @ trans("z", d) @ trans("x", a) @ rot("x", alpha) @ rot("y", beta)
    return rot("x", alpha) @ trans("x", a) @ rot("y", beta) @ rot("z", theta) @ trans("z", d)


def _poe_points(convention, table, tool, q):
    """Product of exponentials: screw axes from the zero configuration, then exp(xi q)."""
    N = table.shape[0]
    T = np.eye(4)
    screws = []
    for j in range(N):
        th, d, a, al, be = table[j]
        # joint j's axis is the z axis of the frame where Rz(theta) acts
        if convention == "dh":
            frame = T
            T = T @ _textbook_link("dh", th, d, a, al, be)
        else:
            frame = T @ _textbook_link("mdh", 0.0, 0.0, a, al, be)
            T = T @ _textbook_link("mdh", th, d, a, al, be)
        w = frame[:3, 2]
        v = -np.cross(w, frame[:3, 3])
        screws.append((w, v))
    M = T @ np.array([[1, 0, 0, tool[0]], [0, 1, 0, tool[1]], [0, 0, 1, tool[2]], [0, 0, 0, 1]])
    out = []
    for qi in q:
        G = np.eye(4)
        for (w, v), t in zip(screws, qi, strict=True):
            X = np.zeros((4, 4))
            X[:3, :3] = [[0, -w[2], w[1]], [w[2], 0, -w[0]], [-w[1], w[0], 0]]
            X[:3, 3] = v
            G = G @ scipy.linalg.expm(X * t)
        out.append((G @ M)[:3, 3])
    return np.array(out)


@pytest.mark.parametrize("name", builtin_models())
def test_fk_matches_product_of_exponentials(name):
    m = load_model(name)
    rng = np.random.default_rng(7)
    table = m.dh_table()
    # a perturbed table, with a Hayati tilt on every parallel row, exercises every term
    table = table + rng.normal(0, 1e-3, table.shape) * [1, 1, 1, 1, 0]
    for r in m.parallel_rows():
        table[r, 4] = 2e-3
    tool = np.array([12.0, -7.0, 55.0])
    q = rng.uniform(-np.pi, np.pi, (20, m.n_joints))
    ours = run_chain(m.convention, table, q, tool, jacobian=False).base_p_tcp
    ref = _poe_points(m.convention, table, tool, q)
    np.testing.assert_allclose(ours, ref, rtol=0, atol=1e-9)


def test_forward_returns_every_frame_vectorised():
    m = load_model("ur5e")
    q = np.random.default_rng(0).uniform(-3, 3, (1000, 6))
    T = forward(m, q)
    assert T.shape == (1000, 7, 4, 4)
    np.testing.assert_allclose(T[:, 0], np.broadcast_to(np.eye(4), (1000, 4, 4)))
    single = np.array([forward(m, qi)[0] for qi in q[:3]])
    np.testing.assert_allclose(T[:3], single, atol=1e-12)
    np.testing.assert_allclose(forward(m, np.degrees(q[:3]), degrees=True), T[:3], atol=1e-12)


@pytest.mark.parametrize("payload", [None, 5.0])
def test_gravity_torques_are_minus_gradient_of_potential(payload):
    m = load_model("ur10e").with_changes(payload={"mass_kg": 3.0, "com": [10.0, 20.0, 50.0]})
    rng = np.random.default_rng(1)
    q = rng.uniform(-3, 3, (30, 6))
    pk = None if payload is None else np.full(30, payload)

    def chain(qq):
        return run_chain(m.convention, m.dh_table(), qq, m.tool_mm(), jacobian=False)

    tau = gravity_torques(m, chain(q), pk)
    h = 1e-6
    for j in range(6):
        dq = np.zeros(6)
        dq[j] = h
        num = -(potential_energy(m, chain(q + dq), pk) - potential_energy(m, chain(q - dq), pk))
        np.testing.assert_allclose(tau[:, j], num / (2 * h), atol=1e-6)
    # joint 1 axis is vertical: gravity exerts no torque about it
    np.testing.assert_allclose(tau[:, 0], 0.0, atol=1e-9)
    # joint 2 of a UR10e carries tens of N·m
    assert 30 < np.abs(tau[:, 1]).max() < 300
