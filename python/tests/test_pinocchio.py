"""Cross-check against Pinocchio (PyPI `pin`): idexp's rigid-body regressor
(inertial columns) times Pinocchio's parameters, mapped to idexp's order with
`Robot.from_pinocchio`, equals `pinocchio.rnea` on random states, for the
shipped UR5 and Panda URDFs (the Panda's fixed hand and TCP are merged into
link 7 by both)."""

import numpy as np
import pytest

import idexp
from conftest import ROBOTS

pin = pytest.importorskip("pinocchio")


@pytest.mark.parametrize("name", ["ur5", "panda"])
def test_regressor_times_pinocchio_params_is_pinocchio_rnea(name):
    path = ROBOTS / f"{name}.urdf"
    robot = idexp.Robot.load(path)
    model = pin.buildModelFromUrdf(str(path))
    data = model.createData()
    assert model.nv == robot.dof
    assert list(model.names)[1:] == robot.joint_names
    pi = np.concatenate([model.inertias[i].toDynamicParameters() for i in range(1, model.njoints)])
    # the same inertial parameters from the same file
    np.testing.assert_allclose(robot.to_pinocchio(), pi, rtol=1e-12, atol=1e-12)
    theta = robot.from_pinocchio(pi)
    mask = np.array(robot.inertial_mask)
    np.testing.assert_allclose(model.gravity.linear, robot.gravity)
    g = np.random.default_rng(42)
    lo, hi = robot.limits["lower"], robot.limits["upper"]
    worst = 0.0
    for _ in range(50):
        q = g.uniform(np.maximum(lo, -3), np.minimum(hi, 3))
        v = g.uniform(-2, 2, robot.dof)
        a = g.uniform(-5, 5, robot.dof)
        y = robot.regressor(q, v, a)[:, mask]
        tau_pin = pin.rnea(model, data, q, v, a)
        tau = y @ theta[mask]
        np.testing.assert_allclose(tau, tau_pin, rtol=0, atol=1e-9)
        worst = max(worst, np.abs(tau - tau_pin).max())
        # and Pinocchio's own regressor with the parameters mapped back
        yp = pin.computeJointTorqueRegressor(model, data, q, v, a)
        np.testing.assert_allclose(yp @ robot.to_pinocchio(theta), tau_pin, atol=1e-9)
    print(f"{name}: max |Y θ − pinocchio.rnea| = {worst:.2e} N·m")


def test_mapping_permutes_each_body():
    """A distinct value per parameter: the mapping is a per-body permutation."""
    robot = idexp.Robot.load(ROBOTS / "panda.urdf")
    theta = np.arange(robot.n_params, dtype=float)
    pi = robot.to_pinocchio(theta)
    for i in range(robot.dof):
        body = pi[10 * i:10 * i + 10]
        body = body - body.min()  # the link's first inertial parameter (XX) sits at its offset in the layout
        np.testing.assert_array_equal(body, [9, 6, 7, 8, 0, 1, 3, 2, 4, 5])


@pytest.mark.parametrize("name", ["ur5", "panda"])
def test_id_derivatives_are_pinocchio_rnea_derivatives(name):
    """idexp's recursive RNEA derivatives with Pinocchio's inertial parameters
    (friction and rotor inertia set to zero) equal
    `pinocchio.computeRNEADerivatives` (∂τ/∂q, ∂τ/∂v) at random states,
    and the mass matrix equals Pinocchio's (∂τ/∂a, upper triangle mirrored)."""
    path = ROBOTS / f"{name}.urdf"
    robot = idexp.Robot.load(path)
    model = pin.buildModelFromUrdf(str(path))
    data = model.createData()
    pi = np.concatenate([model.inertias[i].toDynamicParameters() for i in range(1, model.njoints)])
    mask = np.array(robot.inertial_mask)
    theta = np.zeros(robot.n_params)
    theta[mask] = robot.from_pinocchio(pi)[mask]
    g = np.random.default_rng(7)
    lo, hi = robot.limits["lower"], robot.limits["upper"]
    for _ in range(50):
        q = g.uniform(np.maximum(lo, -3), np.minimum(hi, 3))
        v = g.uniform(-2, 2, robot.dof)
        a = g.uniform(-5, 5, robot.dof)
        dq, dv = robot.id_derivatives(q, v, a, theta=theta)
        pq, pv, pa = (np.array(x) for x in pin.computeRNEADerivatives(model, data, q, v, a))
        scale = max(1.0, np.abs(pq).max(), np.abs(pv).max())
        np.testing.assert_allclose(dq, pq, rtol=0, atol=1e-10 * scale)
        np.testing.assert_allclose(dv, pv, rtol=0, atol=1e-10 * scale)
        # a test that can fail: the derivatives are not zero
        assert np.abs(pq).max() > 1e-3 and np.abs(pv).max() > 1e-3
    # and the ten-parameter CRBA against Pinocchio's crba (nominal parameters
    # of the URDF = Pinocchio's; no rotor inertia in these files)
    for _ in range(20):
        q = g.uniform(np.maximum(lo, -3), np.minimum(hi, 3))
        mp = pin.crba(model, data, q)
        mp = np.triu(mp) + np.triu(mp, 1).T
        np.testing.assert_allclose(robot.mass_matrix(q), mp, rtol=0, atol=1e-12 * np.abs(mp).max())
