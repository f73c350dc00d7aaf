"""idexp.payload: a simulated payload identified from a dict, the same as the command
line's files; the MJCF export read by MuJoCo and the URDF by Pinocchio give the tensor back."""

import json
import pathlib
import subprocess

import numpy as np
import pytest

import idexp

ROOT = pathlib.Path(__file__).resolve().parents[2]
BIN = ROOT / "target" / "release" / "idexp"
UR5 = ROOT / "designs" / "robots" / "ur5.toml"

PAYLOAD = {"frame": "tool0", "mass": 1.8, "com": [0.012, -0.008, 0.055], "inertia": [0.0065, 0.0004, -0.0003, 0.0071, 0.0005, 0.0042]}


def sim(out, loaded, seed):
    d = {
        "name": out.name,
        "robot": str(UR5),
        "rate": 1000.0,
        "decimate": 5,
        "repetitions": 5,
        "seed": seed,
        "truth": {"perturbation": 0.1, "seed": 7},
        "controller": {"bandwidth": 10.0},
        "noise": {"torque": 0.2, "position": 1e-5},
        "reference": {"kind": "random_fourier", "n_h": 4, "frequency": 0.1, "amplitude": 0.6, "seed": 5},
    }
    if loaded:
        d["payload"] = PAYLOAD
    idexp.simulate(d).write(str(out))


@pytest.fixture(scope="module")
def runs(tmp_path_factory):
    d = tmp_path_factory.mktemp("payload")
    sim(d / "loaded", True, 11)
    sim(d / "unloaded", False, 12)
    return d


def design():
    return {
        "name": "py_payload",
        "robot": str(UR5),
        "frame": "tool0",
        "loaded": [{"name": "loaded", "files": ["loaded"], "harmonics": 4}],
        "unloaded": [{"name": "unloaded", "files": ["unloaded"], "harmonics": 4}],
    }


def test_payload_from_a_dict_equals_the_command_line(runs, tmp_path):
    p = idexp.payload(design(), base_dir=str(runs))
    assert p.state == "complete"
    assert abs(p.mass / 1.8 - 1) < 0.01
    assert np.linalg.norm(p.com - np.array(PAYLOAD["com"])) < 0.002
    assert p.inertia.shape == (3, 3) and np.allclose(p.inertia, p.inertia.T)
    k = p.kuka()
    assert k["M"] == p.mass and abs(k["Z"] - 1e3 * p.com[2]) < 1e-9
    # the command line on the same design as a file: the same payload.json numbers
    f = runs / "py_payload.toml"
    f.write_text(
        f'name = "py_payload"\nrobot = "{UR5}"\nframe = "tool0"\n'
        '[[loaded]]\nname = "loaded"\nfiles = ["loaded"]\nharmonics = 4\n'
        '[[unloaded]]\nname = "unloaded"\nfiles = ["unloaded"]\nharmonics = 4\n'
    )
    out = tmp_path / "cli"
    r = subprocess.run([str(BIN), "payload", "identify", str(f), "--out", str(out)], capture_output=True, text=True, env={"IDEXP_NO_PROGRESS": "1"})
    assert r.returncode == 0, r.stderr
    j = json.loads((out / "payload.json").read_text())
    assert j["payload"]["mass"] == p.mass
    assert j["payload"]["com"] == list(p.com)
    p.write(str(tmp_path / "py"))
    assert json.loads((tmp_path / "py" / "payload.json").read_text())["payload"] == j["payload"]


def test_mjcf_and_urdf_exports_give_the_tensor_back(runs, tmp_path):
    mujoco = pytest.importorskip("mujoco")
    p = idexp.payload(design(), base_dir=str(runs))
    folder = pathlib.Path(p.write(str(tmp_path / "out")))
    m = mujoco.MjModel.from_xml_path(str(folder / "payload_mjcf.xml"))
    b = m.body("payload").id
    assert abs(m.body_mass[b] - p.mass) < 1e-12
    assert np.allclose(m.body_ipos[b], p.com, atol=1e-12)
    # MuJoCo stores the principal moments and the principal axes' quaternion
    rot = np.zeros(9)
    mujoco.mju_quat2Mat(rot, m.body_iquat[b])
    rot = rot.reshape(3, 3)
    tensor = rot @ np.diag(m.body_inertia[b]) @ rot.T
    assert np.allclose(tensor, p.inertia, atol=1e-9 * np.abs(p.inertia).max() + 1e-12)
    # the URDF fragment read by Pinocchio: a fixed joint, so the payload's inertia is merged
    # into the universe body (the fragment's root link `tool0` has none)
    pin = pytest.importorskip("pinocchio")
    model = pin.buildModelFromUrdf(str(folder / "payload.urdf"))
    assert model.njoints == 1 and model.existFrame("payload")
    merged = model.inertias[0]
    expected = pin.Inertia(p.mass, p.com, p.inertia)
    assert abs(merged.mass - p.mass) < 1e-12
    assert np.allclose(merged.lever, expected.lever, atol=1e-12)
    assert np.allclose(merged.inertia, expected.inertia, atol=1e-12)
