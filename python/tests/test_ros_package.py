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
import sys

import pytest

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
