"""idexp.calibrate_gains and idexp.plan: the command line's results from Python
(same design, same numbers), and the refusals."""

import json
import pathlib
import subprocess

import numpy as np
import pytest

import idexp

ROOT = pathlib.Path(__file__).resolve().parents[2]
BIN = ROOT / "target" / "release" / "idexp"
DESIGNS = ROOT / "designs"


@pytest.fixture(scope="module")
def gains_runs(tmp_path_factory):
    """The shipped simulated runs of designs/gains_ur5.toml (gains 15 % off in its robot file)."""
    d = tmp_path_factory.mktemp("gains")
    for name in ("sim_ur5_gains_loaded", "sim_ur5_gains_unloaded"):
        idexp.simulate(str(DESIGNS / f"{name}.toml")).write(str(d / "out" / name))
    return d


def gains_design(runs):
    text = (DESIGNS / "gains_ur5.toml").read_text()
    for f in ("gains_ur5_robot.toml", "gains_ur5_robot_true.toml"):
        text = text.replace(f'"{f}"', f'"{DESIGNS / f}"')
    text = text.replace('"../out/', f'"{runs / "out"}/')
    p = runs / "design" / "gains.toml"
    p.parent.mkdir(exist_ok=True)
    p.write_text(text)
    return p


def test_gains_from_python_equal_the_command_line_and_the_truth(gains_runs, tmp_path):
    p = gains_design(gains_runs)
    g = idexp.calibrate_gains(str(p))
    out = tmp_path / "cli"
    r = subprocess.run([str(BIN), "payload", "identify", str(p), "--out", str(out)], capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    cli = json.loads((out / "gains.json").read_text())
    assert [j["gain"] for j in cli["joints"]] == g.gains.tolist()
    assert [j["determined"] for j in cli["joints"]] == g.determined
    # against the simulated truth (the robot file the runs were simulated with)
    truth = {c[0]: c[1] for c in g.report["compare"]}["true (simulated)"]
    assert len(truth) == len(g.joints)
    for j, (gain, t, det) in enumerate(zip(g.gains, truth, g.determined)):
        if det:
            assert abs(gain / t - 1) < 0.01, (g.joints[j], gain, t)
        else:
            assert gain == g.file_gains[j]
    assert any(g.determined) and g.text().count("\n") > 5
    g.write(str(tmp_path / "py"))
    assert (tmp_path / "py" / "robot.toml").exists()


def test_a_gains_design_is_not_a_payload_and_a_payload_design_has_no_gains(gains_runs):
    p = gains_design(gains_runs)
    with pytest.raises(idexp.IdexpError, match="gains"):
        idexp.payload(str(p))
    with pytest.raises(ValueError, match=r"\[gains\]"):
        idexp.calibrate_gains(str(DESIGNS / "payload_ur5.toml"))


def test_plan_from_python_equals_the_command_line(tmp_path):
    design = DESIGNS / "plan_rpr.toml"
    pl = idexp.plan(str(design))
    assert pl.status == "planned"
    assert len(pl.repetitions) == len(pl.candidates) == 3
    assert pl.relaxed_cost <= pl.cost + 1e-9
    out = tmp_path / "cli"
    r = subprocess.run([str(BIN), "plan", str(design), "--out", str(out)], capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    cli = json.loads((out / "plan.json").read_text())
    sol = cli.get("solution", cli)
    assert sol["repetitions"] == pl.repetitions
    assert sol["cost"] == pl.cost
    assert pl.rehearsal is None and "plan" in pl.text().lower()
    pl.write(str(tmp_path / "py"))
    assert (tmp_path / "py" / "plan.json").exists()
    # an unreachable target is a plan that says so, with the reason
    d = {"robot": str(ROOT / "tests/data/ident/rpr_drives.toml"),
         "experiment": [{"name": "a", "simulate": str(DESIGNS / "sim_rpr_fourier.toml"), "cost": 14.0,
                         "identify": {"harmonics": 20}}],
         "target": [{"parameter": "MX3R", "relative": 1e-9}]}
    bad = idexp.plan(d, base_dir=str(DESIGNS))
    assert bad.status == "unreachable" and bad.refused and bad.refused[0]["reason"]


def test_plan_setup_budget_and_noise_from_a_study_from_python(tmp_path):
    # σ from a (hand-written) study estimate: σ·√n_reps per joint
    est = tmp_path / "estimate.json"
    est.write_text(json.dumps({"experiments": [
        {"name": "a", "n_reps": 4, "sigma": [0.5, 3.5, 0.04], "weights": ["residual"] * 3}]}))
    d = {"robot": str(ROOT / "tests/data/ident/rpr_drives.toml"),
         "experiment": [{"name": "a", "simulate": str(DESIGNS / "sim_rpr_fourier.toml"), "cost": 14.0,
                         "setup": 30.0, "identify": {"harmonics": 20}, "noise": {"from": str(est)}}],
         "target": [{"parameter": "MX3R", "relative": 0.002}]}
    pl = idexp.plan(d, base_dir=str(DESIGNS))
    assert pl.status == "planned", pl.text()
    sigma, source = pl.sigma[0]
    assert sigma == [1.0, 7.0, 0.08] and "estimate.json" in source
    # the setup is paid once
    assert pl.cost == 14.0 * pl.repetitions[0] + 30.0 and pl.repetitions[0] >= 2
    # a budget below it: over_budget, the best plan within it, the target it misses
    d["budget"] = pl.cost - 14.0
    over = idexp.plan(d, base_dir=str(DESIGNS))
    assert over.status == "over_budget" and over.budget == pl.cost - 14.0
    w = over.within_budget
    assert w["repetitions"] == [pl.repetitions[0] - 1] and w["cost"] <= over.budget
    assert w["missed"][0]["label"] == "σ(MX3R)" and w["missed"][0]["ratio"] > 1.0
    assert "OVER BUDGET" in over.text()
    # a bad file names the file and the field
    est.write_text(json.dumps({"experiments": [{"name": "a", "n_reps": 1, "sigma": [0.5, 3.5]}]}))
    with pytest.raises(Exception, match=r"estimate\.json.*experiments\[0\]\.sigma"):
        idexp.plan(d, base_dir=str(DESIGNS))
