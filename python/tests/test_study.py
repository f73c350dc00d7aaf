"""idexp.study: the identification study of the command line (`idexp identify study.toml`)
from a dict, checked against the command line's files."""

import json
import pathlib
import subprocess

import numpy as np
import pytest

import idexp

ROOT = pathlib.Path(__file__).resolve().parents[2]
BIN = ROOT / "target" / "release" / "idexp"


def simulate(design, out):
    r = idexp.simulate(str(ROOT / "designs" / design))
    r.write(str(out))
    return out


@pytest.fixture(scope="module")
def runs(tmp_path_factory):
    d = tmp_path_factory.mktemp("study")
    for name in ["sim_rpr_fourier", "sim_rpr_study_b", "sim_rpr_study_gravity", "sim_rpr_study_validate"]:
        simulate(f"{name}.toml", d / name)
    return d


def design(runs):
    return {
        "name": "py_study",
        "robot": str(ROOT / "tests/data/ident/rpr_drives.toml"),
        "truth": "sim_rpr_fourier/truth.json",
        "experiment": [
            {"name": "fourier_a", "files": ["sim_rpr_fourier"], "harmonics": 20},
            {"name": "fourier_b", "files": ["sim_rpr_study_b"], "harmonics": 16},
            {"name": "gravity_wrist", "files": ["sim_rpr_study_gravity"], "kind": "gravity"},
        ],
        "validation": [{"name": "v", "files": ["sim_rpr_study_validate"], "harmonics": 20}],
        "consistent": {"metric": "entropic", "weight": 1.0},
    }


def test_study_from_a_dict_equals_the_command_line(runs, tmp_path):
    s = idexp.study(design(runs), base_dir=str(runs))
    assert s.status == "ok" and s.state == "complete"
    assert [e["name"] for e in s.experiments] == ["fourier_a", "fourier_b", "gravity_wrist"]
    assert abs(sum(e["information_share"] for e in s.experiments) - 1.0) < 1e-9
    z = [abs(r["z"]) for r in s.report["truth"]]
    assert max(z) < 4.0, z
    assert s.consistent["status"] == "ok" and len(s.consistent["links"]) == 3
    model = s.model()
    assert np.array_equal(model.nominal_params, s.consistent_theta)
    # the same study as a file through the command line: the same numbers
    f = runs / "py_study.toml"
    lines = [f'name = "py_study"', f'robot = "{ROOT / "tests/data/ident/rpr_drives.toml"}"', 'truth = "sim_rpr_fourier/truth.json"']
    for e in design(runs)["experiment"]:
        lines += ["[[experiment]]"] + [f"{k} = {json.dumps(v)}" for k, v in e.items()]
    lines += ["[[validation]]", 'name = "v"', 'files = ["sim_rpr_study_validate"]', "harmonics = 20"]
    lines += ["[consistent]", 'metric = "entropic"', "weight = 1.0"]
    f.write_text("\n".join(lines) + "\n")
    out = tmp_path / "cli"
    p = subprocess.run([str(BIN), "identify", str(f), "--out", str(out)], capture_output=True, text=True,
                       env={"IDEXP_NO_PROGRESS": "1", "PATH": "/usr/bin:/bin"})
    assert p.returncode == 0, p.stderr
    est = json.loads((out / "estimate.json").read_text())
    assert np.array_equal(np.array(est["theta"]), s.theta)
    assert np.array_equal(np.array(est["consistent"]["standard"]), s.consistent_theta)
    status = json.loads((out / "status.json").read_text())
    assert status["status"] == "complete" and status["command"] == "identify"
    # write() gives the command line's folder
    w = tmp_path / "py"
    s.write(str(w))
    assert json.loads((w / "estimate.json").read_text())["theta"] == est["theta"]
    assert (w / "validation" / "v.csv").exists() and (w / "status.json").exists()


def test_study_errors_name_the_field(runs):
    d = design(runs)
    d["experiment"][0]["decimate"] = 0
    with pytest.raises(idexp.IdexpError, match="decimate"):
        idexp.study(d, base_dir=str(runs))
    d = design(runs)
    d["experiment"][0]["cutof"] = 3
    with pytest.raises(idexp.IdexpError, match="cutof"):
        idexp.study(d, base_dir=str(runs))


def test_exported_robot_toml_points_at_an_identified_urdf_that_pinocchio_reads(tmp_path):
    """`export = ["toml"]` alone: robot.toml points at the robot.urdf written
    beside it (not at the input URDF), and Pinocchio, reading that URDF,
    gives the identified model's rigid-body torques (idexp's consistent
    model with its drive terms left out: Pinocchio has none)."""
    pin = pytest.importorskip("pinocchio")
    urdf = ROOT / "tests/data/rxz_chain.urdf"
    sim = {
        "robot": str(urdf), "rate": 1000.0, "decimate": 5, "repetitions": 3, "seed": 11,
        "truth": {"perturbation": 0.1, "seed": 1},
        "controller": {"bandwidth": 10.0},
        "noise": {"torque": 0.05, "position": 2e-5},
        "reference": {"kind": "random_fourier", "n_h": 5, "frequency": 0.1, "amplitude": 0.6, "seed": 3},
    }
    idexp.simulate(sim).write(str(tmp_path / "a"))
    s = idexp.study({
        "robot": str(urdf), "export": ["toml"],
        "experiment": [{"name": "a", "files": ["a"], "harmonics": 20}],
        "consistent": {"metric": "euclidean"},
    }, base_dir=str(tmp_path))
    assert s.consistent["status"] == "ok"
    out = tmp_path / "out"
    s.write(str(out))
    assert 'urdf = "robot.urdf"' in (out / "robot.toml").read_text()
    model = idexp.Robot.load(out / "robot.toml")
    assert np.allclose(model.nominal_params, s.consistent_theta, rtol=1e-9, atol=1e-12)
    # the rigid-body part: the identified standard parameters with every drive parameter at 0
    rigid = model.with_params(np.where(model.inertial_mask, model.nominal_params, 0.0))
    pm = pin.buildModelFromUrdf(str(out / "robot.urdf"))
    pd = pm.createData()
    g = np.random.default_rng(5)
    worst = 0.0
    for _ in range(20):
        q, v, a = g.uniform(-2, 2, 5), g.uniform(-1, 1, 5), g.uniform(-3, 3, 5)
        worst = max(worst, np.abs(pin.rnea(pm, pd, q, v, a) - rigid.rnea(q, v, a)).max())
    assert worst < 1e-8, worst
    # and the torques differ from the input URDF's nominal model (the export is not the input)
    nominal = pin.buildModelFromUrdf(str(urdf))
    nd = nominal.createData()
    q, v, a = g.uniform(-2, 2, 5), g.uniform(-1, 1, 5), g.uniform(-3, 3, 5)
    assert np.abs(pin.rnea(nominal, nd, q, v, a) - pin.rnea(pm, pd, q, v, a)).max() > 1e-3


def test_dead_band_and_unknown_drives_are_study_keys(runs):
    """`dead_band` and `[consistent] unknown` reach the study from a dict:
    the report states both, and a name that is not a drive parameter is
    refused naming the field."""
    d = design(runs)
    d["dead_band"] = 0.02
    d["consistent"]["unknown"] = ["Ia1"]
    s = idexp.study(d, base_dir=str(runs))
    assert s.status == "ok"
    text = s.text()
    assert "0.02" in text and "Ia1" in text, text
    d["consistent"]["unknown"] = ["M1"]
    with pytest.raises(idexp.IdexpError, match="unknown"):
        idexp.study(d, base_dir=str(runs))


def test_dedicated_fits_from_a_dict_equal_the_one_run_command_line(tmp_path):
    """A study whose experiments name their `joint` gives the dedicated fits of paper 002 §3.2
    (JointFits), the same numbers as `idexp identify ROBOT RUN --experiment … --joint 2`."""
    g = simulate("sim_puma_gravity.toml", tmp_path / "g")
    f = simulate("sim_puma_friction.toml", tmp_path / "f")
    d = {
        "name": "puma_dedicated",
        "robot": str(ROOT / "designs/robots/puma560.toml"),
        "experiment": [
            {"name": "gravity_2", "kind": "gravity", "joint": 2, "files": ["g"]},
            {"name": "friction_2", "kind": "friction", "joint": 2, "files": ["f"], "gravity": "gravity_2", "min_speed": 0.05},
        ],
    }
    s = idexp.study(d, base_dir=str(tmp_path))
    assert isinstance(s, idexp.JointFits)
    assert s.fits["gravity_2"]["kind"] == "gravity" and s.fits["friction_2"]["gravity_given"]
    env = {"IDEXP_NO_PROGRESS": "1", "PATH": "/usr/bin:/bin"}
    robot = str(ROOT / "designs/robots/puma560.toml")
    p = subprocess.run([str(BIN), "identify", robot, str(g), "--experiment", "gravity", "--joint", "2", "--out", str(tmp_path / "cg")],
                       capture_output=True, text=True, env=env)
    assert p.returncode == 0, p.stderr
    p = subprocess.run([str(BIN), "identify", robot, str(f), "--experiment", "friction", "--joint", "2",
                        "--gravity-fit", str(tmp_path / "cg" / "gravity.json"), "--out", str(tmp_path / "cf")],
                       capture_output=True, text=True, env=env)
    assert p.returncode == 0, p.stderr
    cg = json.loads((tmp_path / "cg" / "gravity.json").read_text())
    cf = json.loads((tmp_path / "cf" / "friction.json").read_text())
    for k, v in cg.items():
        assert s.fits["gravity_2"][k] == v, k
    for k, v in cf.items():
        assert s.fits["friction_2"][k] == v, k
    w = s.write(str(tmp_path / "py"))
    assert json.loads((tmp_path / "py" / "friction_2" / "friction.json").read_text()) == cf
    # a key that has no meaning for such a study is refused, naming it
    with pytest.raises(ValueError, match="export"):
        idexp.study(dict(d, export=["csv"]), base_dir=str(tmp_path))
