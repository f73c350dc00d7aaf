"""Robot: shapes, dtypes, memory orders, physics cross-checks, bad input."""

import numpy as np
import pytest

import idexp
from conftest import ROBOTS


def states(robot, k, seed=0):
    g = np.random.default_rng(seed)
    n = robot.dof
    return g.uniform(-2, 2, (k, n)), g.uniform(-1.5, 1.5, (k, n)), g.uniform(-4, 4, (k, n))


def test_metadata(ur5):
    assert ur5.dof == 6
    assert len(ur5.joint_names) == 6 and ur5.joint_kinds == ["revolute"] * 6
    lim = ur5.limits
    assert set(lim) == {"lower", "upper", "velocity", "acceleration", "effort"}
    assert all(v.shape == (6,) and v.dtype == np.float64 for v in lim.values())
    assert np.all(lim["lower"] < lim["upper"])
    assert len(ur5.param_names) == ur5.n_params == ur5.nominal_params.shape[0]
    assert ur5.param_names[:10] == ["XX1", "XY1", "XZ1", "YY1", "YZ1", "ZZ1", "MX1", "MY1", "MZ1", "M1"]
    assert sum(ur5.inertial_mask) == 60
    assert "ur5" in repr(ur5).lower()


def test_shapes_and_dtypes(ur5):
    n, p = ur5.dof, ur5.n_params
    q, qd, qdd = states(ur5, 5)
    assert ur5.rnea(q[0], qd[0], qdd[0]).shape == (n,)
    assert ur5.rnea(q, qd, qdd).shape == (5, n)
    assert ur5.mass_matrix(q[0]).shape == (n, n)
    assert ur5.mass_matrix(q).shape == (5, n, n)
    assert ur5.regressor(q[0], qd[0], qdd[0]).shape == (n, p)
    assert ur5.regressor(q, qd, qdd).shape == (5 * n, p)
    nb = ur5.base_parameters().n_base
    assert ur5.regressor(q, qd, qdd, base=True).shape == (5 * n, nb)
    for a in (ur5.rnea(q, qd, qdd), ur5.mass_matrix(q), ur5.regressor(q, qd, qdd)):
        assert a.dtype == np.float64 and a.flags["C_CONTIGUOUS"]


def test_memory_orders_and_conversions(ur5):
    q, qd, qdd = states(ur5, 7)
    ref = ur5.regressor(q, qd, qdd)
    f = [np.asfortranarray(a) for a in (q, qd, qdd)]
    assert f[0].flags["F_CONTIGUOUS"] and not f[0].flags["C_CONTIGUOUS"]
    np.testing.assert_array_equal(ur5.regressor(*f), ref)
    big = np.zeros((7, 12))
    big[:, ::2] = q  # a strided view
    np.testing.assert_array_equal(ur5.regressor(big[:, ::2], qd, qdd), ref)
    # lists and integers are converted to float64
    np.testing.assert_allclose(ur5.rnea([0, 0, 0, 0, 0, 0], [0] * 6, [0] * 6), ur5.rnea(np.zeros(6), np.zeros(6), np.zeros(6)))
    np.testing.assert_array_equal(ur5.rnea(q.astype(np.float32), qd, qdd)[0],
                                  ur5.rnea(q.astype(np.float32).astype(np.float64), qd, qdd)[0])


def test_regressor_times_nominal_is_rnea(ur5):
    q, qd, qdd = states(ur5, 20, seed=3)
    y = ur5.regressor(q, qd, qdd)
    tau = ur5.rnea(q, qd, qdd)
    np.testing.assert_allclose(y @ ur5.nominal_params, tau.reshape(-1), rtol=1e-10, atol=1e-9)
    # the base regressor with the base values gives the same torques
    b = ur5.base_parameters()
    yb = ur5.regressor(q, qd, qdd, base=True)
    np.testing.assert_allclose(yb @ b.nominal, tau.reshape(-1), rtol=1e-8, atol=1e-8)
    np.testing.assert_allclose(b.K @ ur5.nominal_params, b.nominal)
    # inverse_dynamics with another θ equals Y θ
    th = ur5.nominal_params * np.linspace(0.5, 1.5, ur5.n_params)
    np.testing.assert_allclose(ur5.inverse_dynamics(th, q, qd, qdd).reshape(-1), y @ th, rtol=1e-10, atol=1e-9)


def test_mass_matrix_from_rnea(ur5):
    """M e_j = τ(q, 0, e_j) − τ(q, 0, 0): the mass matrix from inverse dynamics."""
    q, _, _ = states(ur5, 3, seed=5)
    n = ur5.dof
    for qi in q:
        m = ur5.mass_matrix(qi)
        g = ur5.rnea(qi, np.zeros(n), np.zeros(n))
        cols = np.array([ur5.rnea(qi, np.zeros(n), e) - g for e in np.eye(n)]).T
        np.testing.assert_allclose(m, cols, rtol=1e-9, atol=1e-9)
        np.testing.assert_allclose(m, m.T, atol=1e-12)
        assert np.all(np.linalg.eigvalsh(m) > 0)


def test_base_parameters(ur5):
    b = ur5.base_parameters()
    assert len(b) == b.n_base == len(b.names) == len(b.groupings) == b.K.shape[0]
    assert b.K.shape[1] == ur5.n_params and b.tol == 1e-6
    assert b.smallest_kept > b.tol > b.largest_dropped
    assert b.report["names"] == b.names
    # the base regressor has full column rank, the standard one does not
    q, qd, qdd = states(ur5, 50, seed=9)
    assert np.linalg.matrix_rank(ur5.regressor(q, qd, qdd, base=True)) == b.n_base
    assert np.linalg.matrix_rank(ur5.regressor(q, qd, qdd)) == b.n_base
    bi = ur5.base_parameters(inertial_only=True)
    assert bi.n_base < b.n_base
    with pytest.raises(ValueError, match="tol"):
        ur5.base_parameters(tol=2.0)


def test_pinocchio_order_round_trip(ur5):
    th = ur5.nominal_params * np.linspace(0.9, 1.1, ur5.n_params)
    pi = ur5.to_pinocchio(th)
    assert pi.shape == (60,)
    # body 1: [m, mcx, mcy, mcz, Ixx, Ixy, Iyy, Ixz, Iyz, Izz] from [XX, XY, XZ, YY, YZ, ZZ, MX, MY, MZ, M]
    np.testing.assert_array_equal(pi[:10], th[[9, 6, 7, 8, 0, 1, 3, 2, 4, 5]])
    np.testing.assert_array_equal(ur5.from_pinocchio(pi, th), th)
    back = ur5.from_pinocchio(pi)
    mask = np.array(ur5.inertial_mask)
    np.testing.assert_array_equal(back[mask], th[mask])
    np.testing.assert_array_equal(back[~mask], ur5.nominal_params[~mask])
    with pytest.raises(ValueError, match=r"pi: expected shape \(60,\)"):
        ur5.from_pinocchio(np.zeros(59))


@pytest.mark.parametrize(
    "call, message",
    [
        (lambda r: r.rnea(np.zeros(5), np.zeros(6), np.zeros(6)), r"q: expected shape \(6,\) or \(N, 6\), got \(5,\)"),
        (lambda r: r.rnea(np.zeros((3, 6)), np.zeros((2, 6)), np.zeros((3, 6))), r"qd: expected the shape of q, \(3, 6\)"),
        (lambda r: r.regressor(np.zeros((3, 6)), np.zeros((3, 6)), np.zeros((3, 7))), r"qdd: expected shape \(6,\) or \(N, 6\), got \(3, 7\)"),
        (lambda r: r.mass_matrix(np.zeros((2, 3, 6))), r"q: expected shape \(6,\) or \(N, 6\), got \(2, 3, 6\)"),
        (lambda r: r.rnea(np.full(6, np.nan), np.zeros(6), np.zeros(6)), r"q: element 0 .* is NaN: expected finite"),
        (lambda r: r.inverse_dynamics(np.zeros(3), np.zeros(6), np.zeros(6), np.zeros(6)), r"theta: expected shape \(72,\)"),
    ],
)
def test_bad_shapes(ur5, call, message):
    with pytest.raises(ValueError, match=message):
        call(ur5)


def test_bad_files(tmp_path):
    with pytest.raises(OSError, match="nope.toml"):
        idexp.Robot.load(tmp_path / "nope.toml")
    bad = tmp_path / "bad.toml"
    text = (ROBOTS / "ur5.toml").read_text()
    text = text.replace('urdf = "ur5.urdf"', f'urdf = "{ROBOTS / "ur5.urdf"}"')
    bad.write_text(text.replace("fc = 6.0", "fc = \"six\"", 1))
    with pytest.raises(idexp.IdexpError, match="bad.toml") as e:
        idexp.Robot.load(bad)
    assert isinstance(e.value, ValueError)
    assert "line" in str(e.value) and "expected f64" in str(e.value), str(e.value)
    print(e.value)
    broken = tmp_path / "broken.urdf"
    broken.write_text("<robot name='x'><link name='a'>")
    with pytest.raises(idexp.IdexpError, match="broken.urdf"):
        idexp.Robot.load(broken)


def test_urdf_and_toml_agree():
    """The shipped UR5 URDF and TOML describe the same rigid body dynamics."""
    a = idexp.Robot.load(ROBOTS / "ur5.urdf")
    assert a.dof == 6
    q, qd, qdd = states(a, 4, seed=11)
    ya = a.regressor(q, qd, qdd)
    assert np.all(np.isfinite(ya))
    np.testing.assert_allclose(ya @ a.nominal_params, a.rnea(q, qd, qdd).reshape(-1), rtol=1e-10, atol=1e-9)
