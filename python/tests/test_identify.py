"""simulate → identify: the same estimates from a SimRun, from its folder, from
arrays and from the command line; the truth inside the error bars; errors."""

import json
import tomllib

import numpy as np
import pytest

import idexp
from conftest import DESIGNS, ROOT


@pytest.fixture(scope="module")
def sim():
    spec = tomllib.loads((DESIGNS / "sim_rpr_fourier.toml").read_text())
    spec["repetitions"] = 5
    return spec, idexp.simulate(spec, base_dir=DESIGNS)


@pytest.fixture(scope="module")
def robot():
    return idexp.Robot.load(ROOT / "tests/data/ident/rpr_drives.toml")


def test_simulated_run(sim, robot):
    _, s = sim
    assert len(s) == 5
    reps = s.repetitions
    n_t = reps[0]["t"].shape[0]
    assert all(r["q"].shape == (n_t, robot.dof) and r["tau"].shape == (n_t, robot.dof) for r in reps)
    assert np.allclose(np.diff(reps[0]["t"]), 1 / 200)
    assert len(s.truth["base"]) == len(s.truth["base_names"])


def test_identify_sources_agree_and_cover_truth(sim, robot, cli, tmp_path):
    _, s = sim
    folder = s.write(tmp_path / "run")
    a = idexp.identify(robot, s, truth=s)
    b = idexp.identify(robot, folder, truth=folder / "truth.json")
    np.testing.assert_array_equal(a.theta, b.theta)
    np.testing.assert_array_equal(a.covariance, b.covariance)
    # arrays: the repetitions as dicts, the trajectory from the folder
    c = idexp.identify(robot, s.repetitions, trajectory=folder / "trajectory.json")
    np.testing.assert_array_equal(a.theta, c.theta)
    # the command line on the folder
    out = tmp_path / "cli"
    cli("identify", ROOT / "tests/data/ident/rpr_drives.toml", folder, "--out", out)
    est = json.loads((out / "estimate.json").read_text())
    np.testing.assert_array_equal(a.theta, est["theta"])
    assert a.names == est["names"]
    # shapes and meaning
    nb = len(a.names)
    assert a.theta.shape == a.std.shape == a.rel_std.shape == (nb,)
    assert a.covariance.shape == (nb, nb)
    np.testing.assert_allclose(np.sqrt(np.diag(a.covariance)), a.std, rtol=1e-12)
    np.testing.assert_allclose(a.rel_std, a.std / np.abs(a.theta), rtol=1e-12)
    assert a.status == "ok" and set(a.errors) >= {"e", "e_rel", "rms"}
    # simulated truth: the estimates within 5 σ
    z = np.array([t["z"] for t in a.truth])
    assert np.all(np.abs(z) < 5), z
    # measured vs predicted torques: their per-joint RMS difference is the
    # library's residual, and it sits at the noise floor of the averaged torques
    tq = a.torques
    m, p = tq["measured"], tq["predicted"]
    assert m.shape == p.shape == (tq["t"].shape[0], robot.dof)
    for j in range(robot.dof):
        ok = np.isfinite(m[:, j])
        assert ok.sum() > 0.3 * len(ok)
        assert np.sqrt(np.mean((m[ok, j] - p[ok, j]) ** 2)) == pytest.approx(a.errors["rms"][j], rel=1e-9)
    np.testing.assert_array_less(a.errors["e"], 1.5 * np.array(a.errors["noise_floor"]))
    w = a.write(tmp_path / "py")
    assert json.loads((w / "estimate.json").read_text())["theta"] == est["theta"]
    assert json.loads((w / "status.json").read_text())["command"] == "identify"


def test_methods(sim, robot):
    _, s = sim
    for method in ("ols", "wls"):
        e = idexp.identify(robot, s, method=method, truth=s)
        assert e.report["method"] == method
        z = np.array([t["z"] for t in e.truth])
        assert np.all(np.abs(z) < 5), (method, z)


def test_identify_errors(sim, robot, ur5, tmp_path):
    _, s = sim
    with pytest.raises(idexp.IdexpError, match="method"):
        idexp.identify(robot, s, method="magic")
    with pytest.raises(ValueError, match="filter"):
        idexp.identify(robot, s, filter="median")
    with pytest.raises(idexp.IdexpError, match="joints"):
        idexp.identify(ur5, s)
    rep = s.repetitions[0]
    with pytest.raises(ValueError, match=r"run\[0\]\['tau'\]: expected shape"):
        idexp.identify(robot, {"t": rep["t"], "q": rep["q"], "tau": rep["tau"][:, :2]})
    with pytest.raises(ValueError, match="missing key `tau`"):
        idexp.identify(robot, {"t": rep["t"], "q": rep["q"]})
    with pytest.raises(OSError, match="nowhere"):
        idexp.identify(robot, tmp_path / "nowhere")
    bad = tmp_path / "bad.csv"
    bad.write_text("t,q1,q2,q3,tau1,tau2,tau3\n0,0,0,0,1,2,x\n")
    with pytest.raises(idexp.IdexpError, match="bad.csv.*row 1.*tau3"):
        idexp.identify(robot, bad)
