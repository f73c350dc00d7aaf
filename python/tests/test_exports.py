"""The exports against the command line's files (same design, same seed):
the delivered excitation trajectory (arrays and phase labels = trajectory.csv),
its URScript / ROS 2 / CSV files, the positions plan's poses, and the
physically consistent identification with its robot.toml / URDF / params.csv;
exported models load back and reproduce the torques; bad arguments raise
ValueErrors naming the argument."""

import json
import tomllib

import numpy as np
import pytest

import idexp
from conftest import DESIGNS, ROBOTS, ROOT
from test_excite import small_design
from test_positions_fit import untimed


@pytest.fixture(scope="module")
def designed(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("exports")
    d = small_design(tmp)
    return d, idexp.excite(d, seed=3)


def read_csv(path):
    return np.genfromtxt(path, delimiter=",", names=True)


def test_delivered_equals_trajectory_csv(designed, cli, tmp_path):
    d, r = designed
    out = tmp_path / "cli"
    cli("excite", d, "--seed", 3, "--out", out)
    dl = r.delivered
    assert dl is not None and r.feasible
    csv = read_csv(out / "trajectory.csv")
    n_rows = len(csv)
    assert dl["t"].shape == (n_rows,) and dl["segment"].shape == (n_rows,)
    assert dl["segment"].dtype == np.int64
    for k in ("q", "qd", "qdd"):
        assert dl[k].shape == (n_rows, 6) and dl[k].dtype == np.float64
        for j in range(6):
            # trajectory.csv holds the shortest round-trip decimal of every value
            np.testing.assert_array_equal(dl[k][:, j], csv[f"{k}{j + 1}"])
    np.testing.assert_array_equal(dl["t"], csv["t"])
    np.testing.assert_array_equal(dl["segment"], csv["segment"].astype(np.int64))
    # periods 2, 3, … repeat period 1's rows bitwise (a period of a whole
    # number of samples): `source` names the row, trajectory.csv holds the copy
    src = dl["source"]
    assert src.dtype == np.int64 and src.shape == (n_rows,)
    rep = np.flatnonzero(src != np.arange(n_rows))
    period_rows = int(round(dl["period"] * dl["rate"]))
    assert len(rep) == (dl["periods"] - 1) * period_rows
    assert (dl["segment"][rep] >= 2).all() and (dl["segment"][src[rep]] == 1).all()
    for k in ("q", "qd", "qdd"):
        np.testing.assert_array_equal(dl[k][rep], dl[k][src[rep]])
    # rest to rest at home
    np.testing.assert_allclose(dl["q"][0], dl["home"], atol=1e-12)
    np.testing.assert_allclose(dl["q"][-1], dl["home"], atol=1e-12)
    for k in ("qd", "qdd"):
        np.testing.assert_allclose(dl[k][[0, -1]], 0.0, atol=1e-9)
    # the phases tile [0, duration] and agree with the segment column
    ph = dl["phases"]
    assert ph[0][1] == 0.0 and ph[-1][2] == pytest.approx(dl["duration"], abs=1e-12)
    assert all(a[2] == pytest.approx(b[1], abs=1e-12) for a, b in zip(ph, ph[1:]))
    assert [p[0] for p in ph if p[0].startswith("period")] == [f"period {k}" for k in range(1, dl["periods"] + 1)]
    for label, start, end in ph:
        code = next(c for c, l in dl["labels"].items() if l == label)
        inside = (dl["t"] > start + 1e-9) & (dl["t"] < end - 1e-9)
        assert inside.any() and np.all(dl["segment"][inside] == code), label
    assert dl["labels"][0] == "lead_in" and dl["labels"][-1] == "lead_out"
    # inside a period the delivered trajectory is the designed one (periodic.csv)
    p1 = dl["segment"] == 1
    per = r.trajectory
    m = min(p1.sum(), len(per["t"]))
    np.testing.assert_allclose(dl["q"][p1][:m], per["q"][:m], atol=1e-9)
    # another rate: the same path
    s = r.delivered_sample(100.0)
    assert s["rate"] == 100.0 and s["t"][1] == pytest.approx(0.01)
    np.testing.assert_allclose(s["q"][::1], np.array([np.interp(s["t"], dl["t"], dl["q"][:, j]) for j in range(6)]).T,
                               atol=1e-5)


def test_trajectory_exports_equal_cli(designed, cli, tmp_path):
    d, r = designed
    out = tmp_path / "cli"
    cli("excite", d, "--seed", 3, "--out", out, "--export", "ur,ros2,csv", "--ur", "cb3", "--csv-units", "deg",
        "--csv-derivatives", "--rate", "250", "--approach-speed", "0.4")
    py = r.export(tmp_path / "py", ["ur", "ros2", "csv"], rate=250, ur="cb3", csv_units="deg", csv_derivatives=True,
                  approach_speed=0.4)
    names = sorted(p.name for p in py)
    assert names == ["excite_ur5.script", "excite_ur5_export.csv", "excite_ur5_ros2.yaml", "excite_ur5_ros2_goal.yaml"]
    for p in py:
        assert p.read_bytes() == (out / p.name).read_bytes(), p.name
    # `idexp export` from the coefficients.json vs export_trajectory
    coeff = out / "coefficients.json"
    cli("export", coeff, "--format", "ur,csv", "--out", tmp_path / "cli2")
    py2 = idexp.export_trajectory(coeff, "ur,csv", out=tmp_path / "py2")
    assert len(py2) == 2
    for p in py2:
        assert p.read_bytes() == (tmp_path / "cli2" / p.name).read_bytes(), p.name
    # the CSV export (rad, positions) is the delivered trajectory at its rate
    x = read_csv(tmp_path / "py2" / "excite_ur5_export.csv")
    dl = r.delivered
    assert len(x) == len(dl["t"])
    np.testing.assert_allclose(x[x.dtype.names[1]], dl["q"][:, 0], rtol=0, atol=1e-12)


def test_trajectory_export_errors(designed, tmp_path):
    _, r = designed
    with pytest.raises(ValueError, match="formats: `kuka`: expected ur, ros2 or csv"):
        r.export(tmp_path, ["ur", "kuka"])
    with pytest.raises(ValueError, match="formats: expected at least one"):
        r.export(tmp_path, "")
    with pytest.raises(ValueError, match=r"rate: expected a rate in \(0, 100000\] Hz, got -5"):
        r.export(tmp_path, "csv", rate=-5)
    with pytest.raises(ValueError, match="ur: expected"):
        r.export(tmp_path, "ur", ur="cb2")
    with pytest.raises(ValueError, match="csv_units"):
        r.export(tmp_path, "csv", csv_units="grad")
    with pytest.raises(ValueError, match="approach_speed"):
        r.export(tmp_path, "ur", approach_speed=0)
    with pytest.raises(OSError, match="nothing.json"):
        idexp.export_trajectory(tmp_path / "nothing.json", "ur")
    bad = tmp_path / "c.json"
    bad.write_text(json.dumps({"joint_names": ["a"]}))
    with pytest.raises(idexp.IdexpError, match="c.json.*revolute"):
        idexp.export_trajectory(bad, "ur")
    assert not list(tmp_path.glob("*.script"))


def test_positions_plan_exports_equal_cli(cli, tmp_path):
    design = DESIGNS / "positions_file_a.toml"
    r = idexp.positions(design)
    out = tmp_path / "cli"
    cli("positions", design, "--out", out, "--export", "ur,ros2,csv", "--dwell", "1.5", "--move-speed", "0.7")
    py = r.export(tmp_path / "py", "ur,ros2,csv", dwell=1.5, move_speed=0.7)
    assert sorted(p.name for p in py) == ["positions_file_a_poses.csv", "positions_file_a_poses.script",
                                          "positions_file_a_poses_ros2.yaml"]
    for p in py:
        assert p.read_bytes() == (out / p.name).read_bytes(), p.name
    # the poses are the plan's: candidates with m > 0
    pp = r.plan_poses
    plan = np.array(r.plan)
    np.testing.assert_array_equal(pp["q"], r.q[plan > 0])
    assert pp["m"] == [int(m) for m in plan[plan > 0]] and sum(pp["m"]) == sum(r.plan)
    assert pp["joint_names"] == idexp.Robot.load(ROBOTS / "industrial6.toml").joint_names
    with pytest.raises(ValueError, match="dwell"):
        r.export(tmp_path, "ur", dwell=-1)
    with pytest.raises(ValueError, match="move_speed"):
        r.export(tmp_path, "ur", move_speed=float("nan"))


@pytest.fixture(scope="module")
def rpr_run(tmp_path_factory):
    """designs/sim_rpr_fourier.toml (3 repetitions), written as a run folder."""
    spec = tomllib.loads((DESIGNS / "sim_rpr_fourier.toml").read_text())
    spec["repetitions"] = 3
    s = idexp.simulate(spec, base_dir=DESIGNS)
    return s.write(tmp_path_factory.mktemp("rpr") / "run")


RPR = ROOT / "tests/data/ident/rpr_drives.toml"


def pseudo_inertia_min_eig(p):
    """Smallest eigenvalue of a link's pseudo-inertia from idexp's 10 parameters
    (XX, XY, XZ, YY, YZ, ZZ, MX, MY, MZ, M), computed here independently."""
    xx, xy, xz, yy, yz, zz, mx, my, mz, m = p
    inertia = np.array([[xx, xy, xz], [xy, yy, yz], [xz, yz, zz]])
    j = np.zeros((4, 4))
    j[:3, :3] = 0.5 * np.trace(inertia) * np.eye(3) - inertia
    j[:3, 3] = j[3, :3] = [mx, my, mz]
    j[3, 3] = m
    return np.linalg.eigvalsh(j).min()


def test_consistent_identification_equals_cli(rpr_run, cli, tmp_path):
    robot = idexp.Robot.load(RPR)
    out = tmp_path / "cli"
    cli("identify", RPR, rpr_run, "--consistent", "--export", "toml,csv", "--out", out)
    est = json.loads((out / "estimate.json").read_text())
    a = idexp.identify(robot, rpr_run, consistent=True)
    c = a.consistent
    assert c["status"] == "ok" and c["standard_names"] == robot.param_names
    # (a JSON round trip turns the Pinocchio tuples into lists, as in the file)
    assert untimed(json.loads(json.dumps(c))) == untimed(est["consistent"])
    th = a.consistent_theta
    assert th.shape == (robot.n_params,) and th.dtype == np.float64
    np.testing.assert_array_equal(th, est["consistent"]["standard"])
    # physically consistent: every pseudo-inertia positive semidefinite
    for i in range(robot.dof):
        o = robot.param_names.index(f"XX{i + 1}")
        assert pseudo_inertia_min_eig(th[o:o + 10]) >= -1e-9
    # its base parameters K θ are the reported ones and close to WLS
    b = robot.base_parameters()
    np.testing.assert_allclose(b.values(th), c["base"], rtol=1e-9, atol=1e-12)
    assert b.names == a.names
    # the exports: byte for byte the command line's
    files = a.export(tmp_path / "py", "toml,csv")
    assert sorted(p.name for p in files) == ["params.csv", "robot.toml"]
    for p in files:
        assert p.read_bytes() == (out / p.name).read_bytes(), p.name
    # the exported robot file loads back with the consistent parameters and the same torques
    back = idexp.Robot.load(tmp_path / "py" / "robot.toml")
    np.testing.assert_allclose(back.nominal_params, th, rtol=1e-9, atol=1e-12)
    q = np.random.default_rng(4).uniform(-0.4, 0.4, (20, 3)) + [0, 0.25, 0]
    np.testing.assert_allclose(back.rnea(q, q, q), a.model().rnea(q, q, q), rtol=1e-9, atol=1e-9)
    # a DH robot has no URDF; without consistent=True there is no model
    with pytest.raises(ValueError, match="formats: \"urdf\":.*DH table"):
        a.export(tmp_path / "u", "urdf")
    w = idexp.identify(robot, rpr_run)
    assert w.consistent is None and w.consistent_theta is None
    with pytest.raises(ValueError, match="consistent=True"):
        w.export(tmp_path / "w", ["toml"])
    assert [p.name for p in w.export(tmp_path / "w", ["csv"])] == ["params.csv"]
    with pytest.raises(ValueError, match="formats: `xml`"):
        a.export(tmp_path / "x", ["xml"])
    with pytest.raises(ValueError, match="margin"):
        idexp.identify(robot, rpr_run, consistent=True, margin=-1)
    # (regularization is the study's [consistent] weight = { relative = r }:
    # the message names that key)
    with pytest.raises(ValueError, match=r"\[consistent\].*`weight`.*relative.*inf"):
        idexp.identify(robot, rpr_run, consistent=True, regularization=float("inf"))


def test_model_export_of_a_urdf_robot(tmp_path):
    """ur5.toml (URDF kinematics + drives): new consistent parameters (every
    link's inertial block scaled, drives changed) written as robot.urdf +
    robot.toml load back as the same model."""
    ur5 = idexp.Robot.load(ROBOTS / "ur5.toml")
    th = ur5.nominal_params.copy()
    mask = np.array(ur5.inertial_mask)
    scale = np.repeat(np.linspace(1.05, 1.3, ur5.dof), 10)
    th[mask] *= scale
    th[~mask] *= 1.2
    m = ur5.with_params(th)
    np.testing.assert_array_equal(m.nominal_params, th)
    assert m.inertial_warnings == []
    files = m.export(tmp_path, ["urdf", "toml"])
    assert [p.name for p in files] == ["robot.urdf", "robot.toml"]
    back = idexp.Robot.load(tmp_path / "robot.toml")
    np.testing.assert_allclose(back.nominal_params, th, rtol=1e-9, atol=1e-12)
    q = np.random.default_rng(5).uniform(-1, 1, (30, 6))
    np.testing.assert_allclose(back.rnea(q, q, q), m.rnea(q, q, q), rtol=1e-9, atol=1e-9)
    # the URDF alone carries the inertials (the drives live in the TOML)
    u = idexp.Robot.load(tmp_path / "robot.urdf")
    np.testing.assert_allclose(u.to_pinocchio(), m.to_pinocchio(), rtol=1e-9, atol=1e-12)
    # an inconsistent model is flagged
    bad = th.copy()
    bad[ur5.param_names.index("M1")] = -1.0
    assert any("link" in w.lower() or "mass" in w.lower() for w in ur5.with_params(bad).inertial_warnings)
    with pytest.raises(ValueError, match=r"theta: expected shape \(%d,\)" % ur5.n_params):
        ur5.with_params(th[:-1])


def test_exported_urdf_loads_in_pinocchio_with_the_same_torques(tmp_path):
    """robot.urdf of a changed (identified-like) model, read by Pinocchio (an
    independent URDF reader and RNEA): its `rnea` equals idexp's rigid-body
    torques Y θ (inertial columns) of the model on random states; the nominal
    model's differ. For the UR5 and for a flat body on the triangle boundary."""
    pin = pytest.importorskip("pinocchio")
    ur5 = idexp.Robot.load(ROBOTS / "ur5.toml")
    mask = np.array(ur5.inertial_mask)
    rng = np.random.default_rng(8)
    th = ur5.nominal_params.copy()
    th[mask] *= np.repeat(rng.uniform(0.8, 1.3, ur5.dof), 10)
    # link 3: a flat body (principal moments a, b, a + b), rotated
    names = ur5.param_names
    o = names.index("XX3")
    m = th[names.index("M3")]
    c = np.array(th[o + 6:o + 9]) / m
    q_, _ = np.linalg.qr(rng.normal(size=(3, 3)))
    ic = q_ @ np.diag([0.01, 0.03, 0.04]) @ q_.T
    io = ic + m * (c @ c * np.eye(3) - np.outer(c, c))
    th[o:o + 10] = [io[0, 0], io[0, 1], io[0, 2], io[1, 1], io[1, 2], io[2, 2], *(m * c), m]
    model_i = ur5.with_params(th)
    (path,) = model_i.export(tmp_path, ["urdf"])
    pm = pin.buildModelFromUrdf(str(path))
    data = pm.createData()
    assert list(pm.names)[1:] == model_i.joint_names
    worst, off = 0.0, 0.0
    for _ in range(50):
        q = rng.uniform(-3, 3, 6)
        v = rng.uniform(-2, 2, 6)
        a = rng.uniform(-5, 5, 6)
        y = model_i.regressor(q, v, a)[:, mask]
        tau = y @ th[mask]
        ref = pin.rnea(pm, data, q, v, a)
        worst = max(worst, np.max(np.abs(tau - ref)))
        off = max(off, np.max(np.abs(y @ ur5.nominal_params[mask] - ref)))
    assert worst < 1e-9, worst
    assert off > 1e-3, off
