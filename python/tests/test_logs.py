"""Robot logs from Python: a ROS 2 bag written by rosbags (MCAP and sqlite3)
and a UR RTDE-recorder CSV give the samples of the same run in idexp's CSV;
rosbags reads back the stamps idexp reports; bad specs raise IdexpError."""

import csv

import numpy as np
import pytest
from rosbags.highlevel import AnyReader

import idexp
from conftest import ROOT

LOGS = ROOT / "tests/data/logs"


@pytest.fixture(scope="module")
def robot():
    return idexp.Robot.load(LOGS / "ur5_drives.toml")


@pytest.fixture(scope="module")
def reference():
    rows = list(csv.reader(open(LOGS / "ur5_idexp.csv")))
    a = np.array(rows[1:], dtype=float)
    return {"t": a[:, 0], "q": a[:, 1:7], "tau": a[:, 7:13], "qd": a[:, 13:19]}


@pytest.mark.parametrize("bag", ["ur5_mcap", "ur5_sqlite3"])
def test_bags_give_the_run_csv_samples(robot, reference, bag):
    r = idexp.read_log(LOGS / bag, robot, format="bag")
    for k in ("t", "q", "tau", "qd"):
        np.testing.assert_array_equal(r[k], reference[k])
    assert r["qdd"] is None
    assert r["report"]["samples"] == 400
    assert r["report"]["steps"]["uniform"]


def test_irregular_stamps_agree_with_rosbags(robot):
    r = idexp.read_log(LOGS / "irregular_mcap", robot, format="bag", topic="/joint_states")
    with AnyReader([LOGS / "irregular_mcap"]) as reader:
        conns = [c for c in reader.connections if c.topic == "/joint_states"]
        stamps = [reader.deserialize(raw, c.msgtype).header.stamp for c, _, raw in reader.messages(connections=conns)]
    ns = np.array([s.sec * 10**9 + s.nanosec for s in stamps], dtype=np.int64)
    np.testing.assert_array_equal(r["t"], (ns - ns[0]) / 1e9)
    assert not r["report"]["steps"]["uniform"]


def test_rtde_csv_and_a_map_dict(robot, reference):
    r = idexp.read_log(LOGS / "ur5_rtde.csv", robot, format="rtde")
    np.testing.assert_array_equal(r["t"], reference["t"])
    np.testing.assert_allclose(r["tau"], reference["tau"], rtol=1e-13, atol=1e-12)
    spec = {"format": "csv", "t": "timestamp", "index_base": 0, "q": "actual_q_{j}", "tau": "target_moment_{j}"}
    m = idexp.read_log(LOGS / "ur5_rtde.csv", robot, spec=spec)
    np.testing.assert_array_equal(m["q"], reference["q"])
    assert m["qd"] is None


def test_bad_specs_and_bags_raise(robot):
    with pytest.raises(ValueError, match="format"):
        idexp.read_log(LOGS / "ur5_rtde.csv", robot)
    with pytest.raises(idexp.IdexpError, match="topic"):
        idexp.read_log(LOGS / "irregular_sqlite3", robot, format="bag")
    with pytest.raises(ValueError, match="unknown field"):
        idexp.read_log(LOGS / "ur5_rtde.csv", robot, spec={"format": "rtde", "torqe": "current"})
    info = idexp.log_info(LOGS / "ur5_sqlite3")
    assert {t["topic"] for t in info["topics"]} == {"/joint_states", "/notes"}
