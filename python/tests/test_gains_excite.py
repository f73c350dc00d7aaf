"""objective.columns = "gains" (docs/payload.md, "An excitation for the gain
calibration") against Pinocchio: the condition number `idexp.excite` reports
for the shipped design equals one computed from Pinocchio alone — per joint
the known mass's torque on that joint's rows (rnea of the UR5 with the mass
merged into tool0's link minus rnea without it), and the torques of the
mass's nine unknown parameters, unit-column scaled — at the criterion's
samples (one period at the design's 10 Hz)."""

import numpy as np
import pytest

import idexp
from conftest import DESIGNS, ROBOTS

pin = pytest.importorskip("pinocchio")


def small_design(tmp_path):
    s = (DESIGNS / "gains_ur5_excite.toml").read_text()
    s = s.replace('robot = "gains_ur5_robot.toml"', f'robot = "{DESIGNS / "gains_ur5_robot.toml"}"')
    s = s.replace("generations = 15", "generations = 3").replace("starts = 2", "starts = 1").replace("max_evals = 150", "max_evals = 20")
    p = tmp_path / "gains_small.toml"
    p.write_text(s)
    return p


# pinocchio's dynamic parameters: m, mc_x, mc_y, mc_z, Ixx, Ixy, Iyy, Ixz, Iyz, Izz
# idexp's (PARAM_NAMES): XX, XY, XZ, YY, YZ, ZZ, MX, MY, MZ, M
TO_PIN = [4, 5, 7, 6, 8, 9, 1, 2, 3, 0]


def test_gains_criterion_equals_pinocchios(tmp_path):
    r = idexp.excite(small_design(tmp_path), seed=1)
    names = r.column_names
    assert len(names) == 15 and names[0] == "gain shoulder_pan_joint" and names[6] == "payload XX" and names[-1] == "payload MZ"
    model = pin.buildModelFromUrdf(str(ROBOTS / "ur5.urdf"))
    fid = model.getFrameId("tool0")
    frame = model.frames[fid]
    jid = frame.parentJoint

    def with_mass(phi):
        """the model with the rigid body of idexp parameters phi (about tool0's origin, in its axes) on tool0"""
        v = np.zeros(10)
        for k in range(10):
            v[TO_PIN[k]] = phi[k]
        m = model.copy()
        m.inertias[jid] = m.inertias[jid] + frame.placement.act(pin.Inertia.FromDynamicParameters(v))
        return m

    # the design's [payload]: 2 kg, centre (0.05, -0.04, 0.06), inertia about the centre
    mass, c = 2.0, np.array([0.05, -0.04, 0.06])
    ic = np.array([[0.004, 0, 0], [0, 0.004, 0], [0, 0, 0.003]])
    io = ic + mass * (c @ c * np.eye(3) - np.outer(c, c))  # about tool0's origin
    phi = np.array([io[0, 0], io[0, 1], io[0, 2], io[1, 1], io[1, 2], io[2, 2], *(mass * c), mass])
    loaded = with_mass(phi)
    unit = []
    for k in range(9):
        p = phi.copy()
        p[k] += 1.0
        unit.append(with_mass(p))
    s = r.sample(10.0)
    n_s = s["t"].shape[0]
    assert n_s == 100
    c_mat = np.zeros((6 * n_s, 15))
    for i in range(n_s):
        q, v, a = s["q"][i], s["qd"][i], s["qdd"][i]
        rows = slice(6 * i, 6 * i + 6)
        t0 = pin.rnea(model, model.createData(), q, v, a).copy()
        tl = pin.rnea(loaded, loaded.createData(), q, v, a).copy()
        c_mat[rows, :6] = np.diag(tl - t0)
        for k, mk in enumerate(unit):
            c_mat[rows, 6 + k] = pin.rnea(mk, mk.createData(), q, v, a) - tl
    c_mat /= np.linalg.norm(c_mat, axis=0)
    sv = np.linalg.svd(c_mat, compute_uv=False)
    assert r.cond == pytest.approx(sv[0] / sv[-1], rel=1e-6)
    np.testing.assert_allclose(r.singular_values, sv, rtol=1e-6)


def test_rtde_gains_equal_the_recordings_ratio(tmp_path):
    """idexp.rtde_gains on an RTDE recording written here (space separated, as
    record.py writes it) = numpy's least-squares ratio of target torque to
    target current per joint, with noise on the torques so the ratio is not exact."""
    g = np.random.default_rng(4)
    n_rows = 300
    ratio = np.array([12.1, 12.4, -12.0, 9.0, 9.1, 9.2])
    cur = g.normal(0.0, 0.8, (n_rows, 6))
    tau = cur * ratio + g.normal(0.0, 0.05, (n_rows, 6))
    cols = ["timestamp"] + [f"{w}_{j}" for w in ("actual_q", "actual_qd", "target_moment", "target_current") for j in range(6)]
    data = np.column_stack([8123.456 + 0.008 * np.arange(n_rows), g.normal(0, 1, (n_rows, 6)), np.zeros((n_rows, 6)), tau, cur])
    path = tmp_path / "rtde.csv"
    path.write_text(" ".join(cols) + "\n" + "\n".join(" ".join(repr(float(x)) for x in row) for row in data) + "\n")
    robot = idexp.Robot.load(DESIGNS / "gains_ur5_robot.toml")
    got = idexp.rtde_gains(robot, path)
    want = (tau * cur).sum(axis=0) / (cur * cur).sum(axis=0)
    np.testing.assert_allclose(got, want, rtol=1e-12)
    assert np.all(np.abs(got - ratio) < 0.01 * np.abs(ratio))
