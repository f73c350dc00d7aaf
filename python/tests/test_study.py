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
