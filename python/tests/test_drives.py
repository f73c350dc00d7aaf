"""The drive side from Python: a run logging motor currents gives the same
estimate as the same run's torques; the standstill rule follows the friction
shape and can be forced; bad drive arguments raise ValueError."""

import tomllib

import numpy as np
import pytest

import idexp
from conftest import DESIGNS, ROOT


@pytest.fixture(scope="module")
def tanh_robot():
    return idexp.Robot.load(ROOT / "tests/data/ident/rpr_drives_tanh.toml")


@pytest.fixture(scope="module")
def both_run(tmp_path_factory):
    spec = tomllib.loads((DESIGNS / "sim_rpr_pick_place.toml").read_text())
    spec["repetitions"] = 2
    spec["reference"]["cycles"] = 2
    spec["record"] = "both"
    s = idexp.simulate(spec, base_dir=DESIGNS)
    return s.write(tmp_path_factory.mktemp("drives") / "run")


def test_currents_give_the_estimate_of_the_torques(tanh_robot, both_run):
    header = (both_run / "rep_001.csv").read_text().splitlines()[0].split(",")
    assert {"cur1", "cur2", "cur3", "tau1"} <= set(header), header
    a = idexp.identify(tanh_robot, both_run, torque_from="torque")
    b = idexp.identify(tanh_robot, both_run, torque_from="current")
    assert a.names == b.names
    np.testing.assert_allclose(b.theta, a.theta, rtol=0, atol=1e-9 * np.max(np.abs(a.std)) + 1e-12)


def test_standstill_rule_follows_the_friction_shape(tanh_robot, both_run):
    auto = idexp.identify(tanh_robot, both_run).report["experiments"][0]["rows_used"]
    drop = idexp.identify(tanh_robot, both_run, standstill="drop").report["experiments"][0]["rows_used"]
    assert all(r["used"] == r["total"] for r in auto), auto
    assert all(r["used"] < r["total"] for r in drop), drop


def test_bad_drive_arguments(tanh_robot, both_run):
    with pytest.raises(ValueError, match="standstill"):
        idexp.identify(tanh_robot, both_run, standstill="sometimes")
    with pytest.raises(ValueError, match="current"):
        idexp.identify(tanh_robot, both_run, torque_from="voltage")
    with pytest.raises(ValueError, match="tolerance"):
        idexp.identify(tanh_robot, both_run, current_tolerance=-1.0)


@pytest.fixture(scope="module")
def velocity_run(tmp_path_factory):
    spec = tomllib.loads((DESIGNS / "sim_rpr_pick_place.toml").read_text())
    spec["repetitions"] = 2
    spec["reference"]["cycles"] = 2
    spec["record_velocity"] = True
    s = idexp.simulate(spec, base_dir=DESIGNS)
    return s.write(tmp_path_factory.mktemp("velocity") / "run")


def test_logged_velocities_are_used_unless_told_otherwise(tanh_robot, velocity_run, both_run):
    header = (velocity_run / "rep_001.csv").read_text().splitlines()[0].split(",")
    assert {"qd1", "qd2", "qd3", "tau1"} <= set(header), header
    auto = idexp.identify(tanh_robot, velocity_run)
    log = idexp.identify(tanh_robot, velocity_run, velocity_from="log")
    pos = idexp.identify(tanh_robot, velocity_run, velocity_from="positions")
    velocity = lambda e: e.report["experiments"][0]["velocity"]
    assert velocity(auto) == velocity(log) == "logged"
    assert velocity(pos) == "positions"
    np.testing.assert_array_equal(auto.theta, log.theta)
    # the tanh friction at rest follows the logged velocity, not the
    # differentiated positions: the two estimates differ
    assert np.max(np.abs(log.theta - pos.theta) / pos.std) > 1.0
    # a run without qd columns cannot give logged velocities
    with pytest.raises(ValueError, match="qd"):
        idexp.identify(tanh_robot, both_run, velocity_from="log")
    with pytest.raises(ValueError, match="velocity"):
        idexp.identify(tanh_robot, velocity_run, velocity_from="tachometer")
