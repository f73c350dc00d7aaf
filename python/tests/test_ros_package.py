"""URDFs used as their ROS package ships them: example-robot-data's UR10 and Panda, with
`package://example-robot-data/...` collision meshes found by idexp the way ROS
tools find them (the folder named like the package above the URDF; the
package tree is `tests/data/ros/`), collision-checked by `idexp excite`, and
the delivered trajectory replayed independently by scripts/safety-replay.py
(Pinocchio and coal on the same meshes as the vendor ships them, found through
example-robot-data's own install): both say safe, over the same pairs, and
the replay's distances are never below idexp's (idexp checks convex hulls,
which lie outside the meshes)."""

import importlib.util
import json
import pathlib
import sys

import numpy as np
import pytest

import idexp

from conftest import ROOT

pin = pytest.importorskip("pinocchio")
coal = pytest.importorskip("coal")

ERD = ROOT / "tests" / "data" / "ros" / "example-robot-data"


def replay_module():
    spec = importlib.util.spec_from_file_location("safety_replay_ros", ROOT / "scripts" / "safety-replay.py")
    mod = importlib.util.module_from_spec(spec)
    sys.modules["safety_replay_ros"] = mod
    spec.loader.exec_module(mod)
    return mod


DESIGN = """name = "excite_{name}"
robot = "{name}.toml"
seed = 1
[trajectory]
harmonics = 3
frequency = 0.1
{q0}
[objective]
sample_rate = 10.0
[limits]
position = 0.6
velocity = 0.6
acceleration = 0.6
missing = "skip"
[collision]
margin = 0.01
[ga]
population = 12
generations = 4
[refine]
starts = 1
max_evals = 60
"""


CASES = {
    # the UR10 as it ships; q0 with the arm up (q = 0 puts its wrist below the floor)
    "ur10": (
        "robots/ur_description/urdf/ur10_robot.urdf",
        'base_link = "base_link"\ntip_link = "tool0"\n',
        "q0 = [0.0, -1.5707963267948966, 0.0, -1.5707963267948966, 0.0, 0.0]",
    ),
    # the Panda as it ships, cut at the hand before its mimic finger joints
    "panda": ("robots/panda_description/urdf/panda.urdf", 'base_link = "panda_link0"\ntip_link = "panda_hand"\n', ""),
}


@pytest.mark.parametrize("name", sorted(CASES))
def test_package_urdf_is_collision_checked_and_the_replay_agrees(cli, tmp_path, name):
    rel, keys, q0 = CASES[name]
    (tmp_path / f"{name}.toml").write_text(f'name = "{name}"\nurdf = "{ERD / rel}"\n{keys}')
    design = tmp_path / f"excite_{name}.toml"
    design.write_text(DESIGN.format(name=name, q0=q0))
    out = tmp_path / "out"
    cli("excite", design, "--out", out)
    status = json.loads((out / "status.json").read_text())
    report = json.loads((out / "report.json").read_text())
    safety = report["result"]["execution"]["safety"]
    assert safety["collisions"] == "imposed", safety
    assert status["summary"]["safe_to_play"] is True, status
    idexp_pairs = {
        m["name"].removeprefix("distance ").split(" ≥ ")[0]: m
        for m in report["result"]["margins"]
        if m["kind"].endswith("collision")
    }
    assert len(idexp_pairs) > 10, idexp_pairs
    sr = replay_module()
    # the delivered trajectory (every 20th sample): no replayed sample below the margin
    summary, (_, _, _, _, pairs) = sr.replay(design, out, stride=20, cap=0.05)
    assert summary["verdict"] == "SAFE", [p for p in summary["pairs"] if p["below_margin"]]
    assert {p.label for p in pairs} == set(idexp_pairs)
    # one period at idexp's verification rate (every 5th sample replayed):
    # per pair, the mesh distance is never below idexp's least hull distance
    (tmp_path / "periodic").mkdir()
    (tmp_path / "periodic" / "trajectory.csv").write_text((out / "periodic.csv").read_text())
    cap = 0.05
    _, (_, _, dp, _, pairs_p) = sr.replay(design, tmp_path / "periodic", stride=5, cap=cap)
    checked = 0
    for i, p in enumerate(pairs_p):
        hull = idexp_pairs[p.label]["worst"]
        if hull >= cap:
            assert dp[:, i].min() >= cap - 1e-12, p.label
            continue
        assert dp[:, i].min() >= hull - 1e-9, f"{p.label}: mesh {dp[:, i].min()} < idexp's least hull distance {hull}"
        checked += 1
    assert checked >= 1


def installed_erd_file(rel):
    """A file of the example-robot-data package as pip installed it (its
    cmeel prefix: share/example-robot-data/...); scripts/python-test.sh
    installs the package, so it is an error when it is missing."""
    import importlib.metadata as md

    try:
        dist = md.distribution("example-robot-data")
    except md.PackageNotFoundError:
        pytest.fail("the PyPI package example-robot-data is not installed (scripts/python-test.sh installs it)")
    hits = [f for f in dist.files if str(f).endswith(rel)]
    assert hits, f"example-robot-data has no {rel}"
    return pathlib.Path(dist.locate_file(hits[0]))


def test_the_installed_panda_loads_as_an_arm_with_its_fingers_locked(cli):
    """example-robot-data's panda.urdf as pip installs it, given directly (no
    robot file, no tip_link): the two finger joints (`panda_finger_joint2`
    mimics `panda_finger_joint1`) are locked at 0 and merged into the hand,
    the arm's seven joints are the model; `robot info` says so, and names
    the mesh file of each link's collision geometry. The arm's torques equal
    Pinocchio's RNEA on the same file reduced with the fingers locked at
    their neutral position (`pin.buildReducedModel`), plus the URDF's joint
    damping (read as viscous friction)."""
    urdf = installed_erd_file("robots/panda_description/urdf/panda.urdf")
    robot = idexp.Robot.load(urdf)
    assert robot.dof == 7
    assert robot.joint_names == [f"panda_joint{i}" for i in range(1, 8)]
    info = json.loads(cli("robot", "info", urdf, "--json"))
    (left,) = info["left_out"]
    assert "`panda_finger_joint1`" in left and "`panda_finger_joint2`" in left and "<mimic>" in left, left
    text = cli("robot", "info", urdf)
    assert "Left out of the model:" in text and "panda_finger_joint2` follows `panda_finger_joint1`" in text, text
    # every link's collision meshes: found inside the installed package, named by body
    geo = info["collision_geometry"]
    links = {g["link"] for g in geo}
    assert {f"panda_link{i}" for i in range(8)} | {"panda_hand", "panda_leftfinger", "panda_rightfinger"} <= links, links
    share = urdf.parents[3]
    for g in geo:
        assert g["problem"] is None, g
        if g["shape"] == "mesh":
            f = pathlib.Path(g["file"])
            assert f.is_file() and share in f.parents, g
            assert g["uri"].startswith("package://example-robot-data/"), g
            assert g["uri"].split("/", 3)[3] == str(f.relative_to(share)), g
    # the same from the library through Python
    prov = robot.provenance()
    assert prov["left_out"] == info["left_out"]
    assert [(c["link"], c["file"]) for c in prov["collision"]] == [(g["link"], g["file"]) for g in geo]
    fingers = [g for g in geo if g["link"] in ("panda_leftfinger", "panda_rightfinger")]
    assert fingers and all(g["body"] == "panda_link7" for g in fingers), fingers
    assert any(str(pathlib.Path(g["file"])) in text for g in geo if g["file"]), text

    full = pin.buildModelFromUrdf(str(urdf))
    locked = [full.getJointId(n) for n in ("panda_finger_joint1", "panda_finger_joint2")]
    model = pin.buildReducedModel(full, locked, pin.neutral(full))
    data = model.createData()
    assert list(model.names)[1:] == robot.joint_names
    damping = np.full(7, 0.003)  # <dynamics damping="0.003"> of every arm joint
    g = np.random.default_rng(11)
    lo, hi = robot.limits["lower"], robot.limits["upper"]
    worst = 0.0
    for _ in range(50):
        q = g.uniform(lo, hi)
        v = g.uniform(-2, 2, 7)
        a = g.uniform(-5, 5, 7)
        ref = pin.rnea(model, data, q, v, a) + damping * v
        tau = robot.rnea(q, v, a)
        np.testing.assert_allclose(tau, ref, rtol=0, atol=1e-9)
        worst = max(worst, np.abs(tau - ref).max())
    # a comparison that can fail: the locked fingers carry mass (left out, the torques would differ)
    mass_fingers = sum(full.inertias[j].mass for j in locked)
    assert mass_fingers > 0.01
    print(f"panda (installed): max |idexp − pinocchio reduced| = {worst:.2e} N·m; fingers {mass_fingers:.3f} kg merged")
