"""The MJCF export loaded by MuJoCo (an independent dynamics code).

`mj_inverse` gives qfrc_inverse = M(q) q̈ + c(q, q̇) + g(q) − qfrc_passive −
qfrc_constraint, with M including the joint armature and qfrc_passive =
−damping·q̇. idexp's inverse dynamics of the same model (`Robot.rnea`) is
τ = τ_rb + Ia q̈ + Fc·sign(q̇) + Fv q̇: the armature is Ia and the damping Fv
term for term. MuJoCo's `frictionloss` is not Fc·sign(q̇) but a dry-friction
constraint force, at most Fc in magnitude, found by the constraint solver
together with the other constraints (soft, with solref/solimp), so its value
at a given q̈ is not the Coulomb term: the comparison disables the friction
loss (and the joint limits, inactive at the states drawn anyway) and adds
idexp's Coulomb term Fc·sign(q̇) to MuJoCo's torques; that the friction loss
written is Fc is checked on the compiled model (`dof_frictionloss`).
"""

import math
import pathlib
import subprocess

import numpy as np
import pytest

import idexp

mujoco = pytest.importorskip("mujoco")

ROOT = pathlib.Path(__file__).resolve().parents[2]
ROBOTS = ROOT / "designs" / "robots"


def drive_values(robot, kind):
    """Per joint, the nominal value of parameter `kind` (`Ia`, `Fc`, `Fv`), 0 if absent."""
    names = robot.param_names
    theta = robot.nominal_params
    out = np.zeros(robot.dof)
    for j in range(robot.dof):
        key = f"{kind}{j + 1}"
        if key in names:
            out[j] = theta[names.index(key)]
    return out


def random_states(robot, n, seed):
    rng = np.random.default_rng(seed)
    lim = robot.limits
    lo = np.where(np.isfinite(lim["lower"]), lim["lower"], -math.pi)
    hi = np.where(np.isfinite(lim["upper"]), lim["upper"], math.pi)
    q = lo + (hi - lo) * (0.05 + 0.9 * rng.random((n, robot.dof)))
    qd = rng.uniform(-2.0, 2.0, (n, robot.dof))
    qdd = rng.uniform(-5.0, 5.0, (n, robot.dof))
    return q, qd, qdd


def mujoco_inverse(model, q, qd, qdd):
    data = mujoco.MjData(model)
    out = np.empty_like(q)
    for k in range(q.shape[0]):
        data.qpos[:] = q[k]
        data.qvel[:] = qd[k]
        data.qacc[:] = qdd[k]
        mujoco.mj_inverse(model, data)
        out[k] = data.qfrc_inverse
    return out


def compiled(xml):
    model = mujoco.MjModel.from_xml_string(xml)
    model.opt.disableflags |= int(mujoco.mjtDisableBit.mjDSBL_FRICTIONLOSS) | int(mujoco.mjtDisableBit.mjDSBL_LIMIT)
    return model


@pytest.mark.parametrize("name", ["ur5.toml", "panda.toml", "iiwa14.toml", "ur5.urdf"])
def test_mj_inverse_equals_idexp_inverse_dynamics(name):
    robot = idexp.Robot.load(ROBOTS / name)
    model = compiled(idexp.mjcf(robot))
    assert model.nq == robot.dof and model.nv == robot.dof
    ia, fc, fv = (drive_values(robot, k) for k in ("Ia", "Fc", "Fv"))
    # the drive terms, as MuJoCo compiled them
    np.testing.assert_array_equal(model.dof_armature, ia)
    np.testing.assert_array_equal(model.dof_damping, fv)
    np.testing.assert_array_equal(model.dof_frictionloss, fc)
    np.testing.assert_array_equal(model.opt.gravity, robot.gravity)
    q, qd, qdd = random_states(robot, 200, seed=7)
    tau = robot.rnea(q, qd, qdd)
    tau_mj = mujoco_inverse(model, q, qd, qdd) + fc * np.sign(qd)
    scale = np.maximum(np.abs(tau), 1.0)
    err = np.max(np.abs(tau_mj - tau) / scale)
    assert err < 1e-9, f"{name}: largest relative difference {err:.3e}"
    # a wrong model is caught: the armature left out changes the torques
    if np.any(ia > 0):
        tau_no_ia = tau - ia * qdd
        assert np.max(np.abs(tau_mj - tau_no_ia) / scale) > 1e-6


def test_identified_model_and_written_file_load_back(tmp_path):
    """An identified-like model (parameters changed, physically consistent):
    robot.xml written into a folder loads from there with the same torques."""
    robot = idexp.Robot.load(ROBOTS / "panda.toml")
    theta = robot.nominal_params.copy()
    names = robot.param_names
    for j in range(robot.dof):
        for kind, factor in (("M", 1.1), ("Ia", 1.3), ("Fv", 0.7), ("Fc", 1.2)):
            key = f"{kind}{j + 1}"
            if key in names:
                k = names.index(key)
                theta[k] *= factor
        # scaling the mass scales the first moments and inertia with it: a consistent body
        for kind in ("XX", "XY", "XZ", "YY", "YZ", "ZZ", "MX", "MY", "MZ"):
            theta[names.index(f"{kind}{j + 1}")] *= 1.1
    ident = robot.with_params(theta)
    path = pathlib.Path(idexp.write_mjcf(ident, tmp_path / "out"))
    assert path == tmp_path / "out" / "robot.xml"
    model = mujoco.MjModel.from_xml_path(str(path))
    model.opt.disableflags |= int(mujoco.mjtDisableBit.mjDSBL_FRICTIONLOSS) | int(mujoco.mjtDisableBit.mjDSBL_LIMIT)
    q, qd, qdd = random_states(ident, 100, seed=3)
    tau = ident.rnea(q, qd, qdd)
    tau_mj = mujoco_inverse(model, q, qd, qdd) + drive_values(ident, "Fc") * np.sign(qd)
    err = np.max(np.abs(tau_mj - tau) / np.maximum(np.abs(tau), 1.0))
    assert err < 1e-9, err
    # the nominal model's torques differ: the file is the identified model's
    assert np.max(np.abs(robot.rnea(q, qd, qdd) - tau)) > 1e-3


def test_not_expressible_is_stated_in_comments():
    """The coupled wrist of industrial6 and the tanh shape cannot be written in MJCF: said in the file."""
    xml = idexp.mjcf(idexp.Robot.load(ROBOTS / "industrial6.toml"))
    assert "NOT EXPRESSED: the coupling matrix" in xml
    mujoco.MjModel.from_xml_string(xml)  # still a valid model
    rpr = idexp.mjcf(idexp.Robot.load(ROOT / "tests" / "data" / "ident" / "rpr_drives_tanh.toml"))
    assert "Coulomb shape tanh" in rpr
    mujoco.MjModel.from_xml_string(rpr)


def test_cli_writes_the_same_file(tmp_path):
    exe = ROOT / "target" / "release" / "idexp"
    if not exe.exists():
        pytest.skip("the command-line binary is not built")
    robot = idexp.Robot.load(ROBOTS / "ur5.toml")
    r = subprocess.run([str(exe), "robot", "mjcf", str(ROBOTS / "ur5.toml"), "--out", str(tmp_path)], capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    assert (tmp_path / "robot.xml").read_text() == idexp.mjcf(robot)
