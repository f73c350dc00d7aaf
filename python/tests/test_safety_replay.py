"""The independent replay of a shipped excitation design (scripts/safety-replay.py):
Pinocchio loads the URDF with the vendor's collision meshes, coal computes the
exact mesh–mesh distances (non-convex, BVH) and the floor distance from every
mesh vertex. idexp checks convex hulls of the same meshes, so its distances
must never exceed the replay's, and a design idexp calls feasible must keep
the margin at every replayed sample of its delivered trajectory."""

import csv
import importlib.util
import json
import sys

import numpy as np
import pytest

from conftest import DESIGNS, ROOT

pin = pytest.importorskip("pinocchio")
coal = pytest.importorskip("coal")


def load_script(file, name):
    """A script of scripts/ as a module."""
    spec = importlib.util.spec_from_file_location(name, ROOT / "scripts" / file)
    mod = importlib.util.module_from_spec(spec)
    sys.modules[name] = mod
    spec.loader.exec_module(mod)
    return mod


def replay_module():
    return load_script("safety-replay.py", "safety_replay")


@pytest.fixture(scope="module")
def ur5_run(cli, tmp_path_factory):
    out = tmp_path_factory.mktemp("excite_ur5")
    cli("excite", DESIGNS / "excite_ur5.toml", "--out", out)
    return out


def thin(src, dst, every):
    """trajectory.csv with every row of the lead-in, the first period and the
    lead-out, and every `every`-th row of the repeated periods."""
    with open(src, newline="") as f:
        rows = list(csv.reader(f))
    seg = rows[0].index("segment")
    keep = [r for i, r in enumerate(rows[1:]) if int(r[seg]) in (0, 1, -1) or i % every == 0]
    with open(dst, "w", newline="") as f:
        csv.writer(f).writerows([rows[0]] + keep)
    return len(keep), len(rows) - 1


def test_safety_replay_ur5_hull_distances_below_mesh_distances_and_margin_kept(ur5_run, tmp_path):
    sr = replay_module()
    status = json.loads((ur5_run / "status.json").read_text())
    report = json.loads((ur5_run / "report.json").read_text())
    assert status["summary"]["design_status"] == "feasible", status
    design = DESIGNS / "excite_ur5.toml"
    cap = 0.03

    # 1. the delivered trajectory: no replayed sample below the margin
    n, total = thin(ur5_run / "trajectory.csv", tmp_path / "trajectory.csv", 10)
    assert n > total // 3
    summary, (t, q, dist, _, pairs) = sr.replay(design, tmp_path, cap=cap)
    assert summary["samples"] == n
    labels = {p.label for p in pairs}
    assert summary["verdict"] == "SAFE", [p for p in summary["pairs"] if p["below_margin"]]
    assert dist.min() >= summary["margin"]

    # 2. idexp's pairs are the replay's (same exclusions: one joint apart)
    idexp_pairs = {m["name"].removeprefix("distance ").split(" ≥ ")[0]: m for m in report["result"]["margins"] if m["kind"].endswith("collision")}
    assert set(idexp_pairs) == labels
    assert {(e["a"], e["b"]) for e in summary["excluded"]} == {
        ("base_link", "shoulder_link"),
        ("shoulder_link", "upper_arm_link"),
        ("upper_arm_link", "forearm_link"),
        ("forearm_link", "wrist_1_link"),
        ("wrist_1_link", "wrist_2_link"),
        ("wrist_2_link", "wrist_3_link"),
        ("base_link", "floor"),
    }
    assert f"{len(summary['excluded'])} pairs not checked" in (ur5_run / "report.txt").read_text()

    # 3. one period at 1 kHz (periodic.csv, idexp's verification grid): per
    # pair, idexp's least hull distance and where; the mesh distance there and
    # its least value over the period are not smaller
    (tmp_path / "periodic").mkdir()
    (tmp_path / "periodic" / "trajectory.csv").write_text((ur5_run / "periodic.csv").read_text())
    _, (tp, _, dp, _, pairs_p) = sr.replay(design, tmp_path / "periodic", cap=cap)
    rate = report["verification_rate"]
    assert np.allclose(np.diff(tp), 1.0 / rate)
    checked = 0
    for i, p in enumerate(pairs_p):
        m = idexp_pairs[p.label]
        hull = m["worst"]
        if hull >= cap:
            assert dp[:, i].min() >= cap - 1e-12, p.label
            continue
        k = int(round(m["at"] * rate))
        assert abs(tp[k] - m["at"]) < 1e-9
        assert dp[k, i] >= hull - 1e-9, f"{p.label}: mesh {dp[k, i]} < hull {hull} at t = {m['at']}"
        assert dp[:, i].min() >= hull - 1e-9, f"{p.label}: mesh {dp[:, i].min()} < idexp's least hull distance {hull}"
        checked += 1
    # the close pairs of this design: base–upper arm, forearm–wrist 2 and 3, wrist 1–3, floor
    assert checked >= 6, checked


def test_safety_replay_finds_a_pose_below_the_margin(ur5_run, tmp_path):
    # the replay can fail: q = 0 stretches the UR5 horizontally at shoulder
    # height and puts the wrist about 4 cm below the mounting plane
    sr = replay_module()
    with open(ur5_run / "trajectory.csv", newline="") as f:
        rows = list(csv.reader(f))
    head = rows[0]
    row = ["0"] * len(head)
    q = [0.0] * 6
    for j, v in enumerate(q):
        row[head.index(f"q{j + 1}")] = repr(v)
    with open(tmp_path / "trajectory.csv", "w", newline="") as f:
        csv.writer(f).writerows([head, row])
    s, _ = sr.replay(DESIGNS / "excite_ur5.toml", tmp_path, cap=0.03)
    assert s["verdict"] == "UNSAFE"
    low = {p["pair"]: p["min"] for p in s["pairs"] if p["below_margin"]}
    assert any(k.startswith("world: wrist") and v < 0.0 for k, v in low.items()), low


def test_safety_replay_bad_input_names_the_file(tmp_path):
    sr = replay_module()
    (tmp_path / "trajectory.csv").write_text("t,q1\n0,0\n")
    with pytest.raises(sr.InputError, match=r"trajectory.csv: header lacks columns"):
        sr.replay(DESIGNS / "excite_ur5.toml", tmp_path)


@pytest.mark.parametrize(
    "design, merged",
    [
        # the hand and the fingers are merged into panda_link7, the ee_link box into wrist_3_link
        ("excite_panda_table.toml", {"panda_hand_0", "panda_leftfinger_0", "panda_leftfinger_1", "panda_rightfinger_0", "panda_rightfinger_1"}),
        ("excite_ur5.toml", {"ee_link_0"}),
    ],
)
def test_safety_replay_one_joint_exclusion_holds_for_the_merged_shapes(design, merged):
    # idexp (and the replay) leave out the bodies joined by one joint. The
    # links themselves meet at the joint; shapes merged into the child body
    # (hand, fingers, flange box) do not, and must keep the margin from the
    # parent body over the joint's whole range (their distance depends on that
    # joint alone): swept at 0.1° steps with coal on the meshes
    sr = replay_module()
    model, gmodel, _, excluded, margin, _ = sr.build(DESIGNS / design)
    data = model.createData()
    gos = list(gmodel.geometryObjects)
    names = {g.name for g in gos}
    assert merged <= names, merged - names
    req, res = coal.DistanceRequest(), coal.DistanceResult()
    worst = {}
    for child in (g for g in gos if g.name in merged):
        j = child.parentJoint
        parents = [g for g in gos if g.parentJoint == model.parents[j]]
        lo, hi = model.lowerPositionLimit[j - 1], model.upperPositionLimit[j - 1]
        for v in np.arange(lo, hi, np.radians(0.1)):
            qv = pin.neutral(model)
            qv[model.joints[j].idx_q] = v
            pin.forwardKinematics(model, data, qv)
            Mc = data.oMi[j] * child.placement
            for par in parents:
                Mp = data.oMi[par.parentJoint] * par.placement
                res.clear()
                d = coal.distance(
                    par.geometry, coal.Transform3s(Mp.rotation, Mp.translation), child.geometry, coal.Transform3s(Mc.rotation, Mc.translation), req, res
                )
                key = (par.name, child.name)
                worst[key] = min(worst.get(key, np.inf), d)
    assert worst and all(d >= margin for d in worst.values()), worst


def padding_module():
    return load_script("full-mesh-padding.py", "full_mesh_padding")


@pytest.mark.parametrize("robot", ["ur5", "panda"])
def test_collision_padding_holds_the_vendors_visual_meshes(robot):
    # every vertex of the vendor's visual (full) meshes lies within the
    # link's collision_padding of its collision hulls (coal, independently
    # of idexp); the meshes do reach beyond the bare hulls (> 0.5 mm), so
    # without the padding this fails
    fm = padding_module()
    if not fm.vendor_share():
        pytest.skip("example-robot-data (the vendors' visual meshes) is not installed")
    path = DESIGNS / "robots" / f"{robot}.toml"
    rows = fm.covered(fm.protrusion(path), path)
    meshed = [r for r in rows if r["visual_vertices"]]
    assert len(meshed) >= 7
    assert max(r["protrusion"] for r in meshed) > 5e-4
    for r in rows:
        assert r["protrusion"] <= r["body_padding"], r


def test_visual_replay_ur5_keeps_the_margin_and_idexp_bounds_it(ur5_run, tmp_path):
    # the vendor's full visual meshes (non-convex, BVH) at every 10th sample
    # of the delivered trajectory and at the time of each pair's least
    # distance in idexp's check: never below the margin, and never below
    # idexp's least (padded hull) distance of the pair
    sr = replay_module()
    if not sr.vendor_share():
        pytest.skip("example-robot-data (the vendors' visual meshes) is not installed")
    report = json.loads((ur5_run / "report.json").read_text())
    rate = report["verification_rate"]
    worst = {m["name"].removeprefix("distance ").split(" ≥ ")[0]: m for m in report["result"]["margins"] if m["kind"].endswith("collision")}
    with open(ur5_run / "periodic.csv", newline="") as f:
        rows = list(csv.reader(f))
    at = {int(round(m["at"] * rate)) for m in worst.values()}
    keep = [r for i, r in enumerate(rows[1:]) if i % 10 == 0 or i in at]
    with open(tmp_path / "trajectory.csv", "w", newline="") as f:
        csv.writer(f).writerows([rows[0]] + keep)
    cap = 0.03
    summary, (_, _, dist, _, pairs) = sr.replay(DESIGNS / "excite_ur5.toml", tmp_path, cap=cap, meshes="visual")
    assert summary["meshes"] == "visual"
    assert summary["verdict"] == "SAFE", [p for p in summary["pairs"] if p["below_margin"]]
    for i, p in enumerate(pairs):
        hull = worst[p.label]["worst"]
        assert dist[:, i].min() >= min(hull, cap) - 1e-9, f"{p.label}: visual mesh {dist[:, i].min()} < idexp's {hull}"


@pytest.fixture(scope="module")
def bench_run(cli, tmp_path_factory):
    out = tmp_path_factory.mktemp("excite_ur5_bench")
    cli("excite", DESIGNS / "excite_ur5_bench.toml", "--time-limit", "2", "--out", out)
    return out


def test_benchmark_design_without_collision_constraints_is_unsafe_for_idexp_and_the_replay(bench_run, tmp_path):
    # the benchmark designs impose no collision constraint ([collision]
    # enabled = false) and start at q = 0 (wrist below the mounting plane):
    # every constraint they impose holds, but idexp's check afterwards and the
    # replay on the vendor's meshes both call the delivered trajectory unsafe
    sr = replay_module()
    report = json.loads((bench_run / "report.json").read_text())
    assert report["result"]["status"] == "feasible"
    safety = report["result"]["execution"]["safety"]
    assert safety["collisions"] == "checked_afterwards" and safety["safe"] is False, safety
    assert "NOT safe to play" in (bench_run / "report.txt").read_text()
    closest = safety["closest"]
    assert closest["distance"] < 0.0

    # the replay of the delivered trajectory (every 20th sample): UNSAFE
    s, _ = sr.replay(DESIGNS / "excite_ur5_bench.toml", bench_run, stride=20, cap=0.05)
    assert s["margin"] == 0.0
    assert s["verdict"] == "UNSAFE"
    replay_below = sum(p["below_margin"] for p in s["pairs"])
    assert replay_below > 0

    # idexp's deepest sample replayed alone: the same pair in collision on the
    # vendor's meshes, and idexp's hull distance a lower bound of the mesh distance
    with open(bench_run / "trajectory.csv", newline="") as f:
        rows = list(csv.reader(f))
    k = int(round(closest["t"] * 1000.0))
    assert abs(float(rows[1 + k][0]) - closest["t"]) < 1e-9
    with open(tmp_path / "trajectory.csv", "w", newline="") as f:
        csv.writer(f).writerows([rows[0], rows[1 + k]])
    one, _ = sr.replay(DESIGNS / "excite_ur5_bench.toml", tmp_path, cap=0.05)
    mesh = {p["pair"]: p["min"] for p in one["pairs"]}
    assert mesh[closest["pair"]] < 0.0, (closest, mesh)
    assert mesh[closest["pair"]] >= closest["distance"] - 1e-9, (closest, mesh)


def test_python_result_carries_the_verdict_and_refuses_the_export(tmp_path):
    import idexp

    r = idexp.excite(str(DESIGNS / "excite_ur5_bench.toml"), time_limit=1.0)
    assert r.feasible
    assert r.safety["safe"] is False and r.safety["collisions"] == "checked_afterwards"
    assert r.safety["closest"]["distance"] < 0.0
    with pytest.raises(idexp.IdexpError, match="NOT safe to play"):
        r.export(tmp_path, "csv")
    r.write(tmp_path / "bench")
    with pytest.raises(idexp.IdexpError, match=r"coefficients.json.*safety.*NOT safe to play"):
        idexp.export_trajectory(tmp_path / "bench" / "coefficients.json", "csv")
    r = idexp.excite(str(DESIGNS / "excite_ur5.toml"), time_limit=1.0)
    if r.feasible:
        assert r.safety == {**r.safety, "collisions": "imposed", "safe": True}
