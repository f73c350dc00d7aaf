"""The payload's exports where they go (issue 43, item 6): MuJoCo loads every
payload MJCF, a flat body (on the consistency boundary) and the shipped example
included; KUKA's statement follows a grammar of KRL's LOAD_DATA array
assignment with REALs of at most 7 significant digits; the report says when the
payload sits on the consistency boundary."""

import json
import os
import re
import shutil
import subprocess

import numpy as np
import pytest

from conftest import DESIGNS, IDEXP
from test_payload_frames import write_twins, write_urdf

pin = pytest.importorskip("pinocchio")
mujoco = pytest.importorskip("mujoco")

ENV = dict(os.environ, IDEXP_NO_PROGRESS="1")

# KRL: LOAD_DATA[n] = {M r, CM {X r, Y r, Z r, A r, B r, C r}, J {X r, Y r, Z r}},
# r a REAL literal in plain decimal notation
REAL = r"(-?\d+\.\d+)"
KRL = re.compile(
    r"^LOAD_DATA\[(\d+)\] = \{M " + REAL + r", CM \{X " + REAL + r", Y " + REAL + r", Z " + REAL
    + r", A " + REAL + r", B " + REAL + r", C " + REAL + r"\}, J \{X " + REAL + r", Y " + REAL + r", Z " + REAL + r"\}\}$"
)


def krl_statement(text):
    """The one non-comment line of kuka_load.txt, parsed by the grammar: (tool, [10 values])."""
    lines = [l for l in text.splitlines() if l.strip() and not l.startswith(";")]
    assert len(lines) == 1, text
    m = KRL.match(lines[0])
    assert m, f"not a KRL LOAD_DATA[n] assignment: {lines[0]}"
    for lit in m.groups()[1:]:
        digits = lit.replace("-", "").replace(".", "").lstrip("0")
        assert len(digits.rstrip("0") or "0") <= 7, f"{lit}: more than 7 significant digits"
    return int(m.group(1)), [float(v) for v in m.groups()[1:]]


def check_mjcf(folder, payload):
    """MuJoCo loads payload_mjcf.xml; its body carries the payload (the tensor to 1e-8 relative)."""
    m = mujoco.MjModel.from_xml_path(str(folder / "payload_mjcf.xml"))
    b = m.body("payload").id
    assert abs(m.body_mass[b] - payload["mass"]) < 1e-12
    assert np.allclose(m.body_ipos[b], payload["com"], atol=1e-12)
    rot = np.zeros(9)
    mujoco.mju_quat2Mat(rot, m.body_iquat[b])
    rot = rot.reshape(3, 3)
    tensor = rot @ np.diag(m.body_inertia[b]) @ rot.T
    i = payload["inertia"]
    want = np.array([[i[0], i[1], i[2]], [i[1], i[3], i[4]], [i[2], i[4], i[5]]])
    assert np.abs(tensor - want).max() < 1e-8 * np.abs(want).max()
    # and MuJoCo's dynamics run on it
    d = mujoco.MjData(m)
    mujoco.mj_forward(m, d)


def test_a_flat_payload_on_the_boundary_loads_in_mujoco_and_is_reported(tmp_path):
    """Point masses in a plane of tool0 (Izz = Ixx + Iyy about the centre): noiseless
    Pinocchio twins; the consistent fit lies on the boundary, MuJoCo loads the MJCF."""
    urdf = write_urdf(tmp_path)
    model = pin.buildModelFromUrdf(str(urdf))
    # four point masses in the plane z = 0.08 of tool0
    pts = np.array([[0.05, 0.02, 0.08], [-0.04, 0.03, 0.08], [0.01, -0.06, 0.08], [-0.02, -0.01, 0.08]])
    ms = np.array([0.4, 0.3, 0.5, 0.6])
    mass = ms.sum()
    c = (ms[:, None] * pts).sum(0) / mass
    ic = sum(mi * ((p - c) @ (p - c) * np.eye(3) - np.outer(p - c, p - c)) for mi, p in zip(ms, pts))
    assert abs(ic[0, 0] + ic[1, 1] - ic[2, 2]) < 1e-15
    p = {"mass": mass, "com": list(c), "inertia": [ic[0, 0], ic[0, 1], ic[0, 2], ic[1, 1], ic[1, 2], ic[2, 2]]}
    g = np.random.default_rng(5)
    nh, w = 4, 2 * np.pi / 10.0
    q0 = np.array([0.0, -1.4, 1.6, -1.8, -1.57, 0.0])
    a, b = g.uniform(-0.3, 0.3, (6, nh)), g.uniform(-0.3, 0.3, (6, nh))
    write_twins(tmp_path, model, "tool0", p, w, q0, a, b)
    design = tmp_path / "flat.toml"
    design.write_text(
        f'name = "flat"\nrobot = "{urdf}"\nframe = "tool0"\nmethod = "ols"\nkuka_tool = 7\n'
        '[[loaded]]\nname = "loaded"\nfiles = ["loaded"]\nharmonics = 4\n'
        '[[unloaded]]\nname = "unloaded"\nfiles = ["unloaded"]\nharmonics = 4\n'
    )
    out = tmp_path / "out"
    r = subprocess.run([str(IDEXP), "payload", "identify", str(design), "--out", str(out)], capture_output=True, text=True, env=ENV)
    assert r.returncode == 0, r.stderr
    j = json.loads((out / "payload.json").read_text())
    got = j["payload"]
    assert abs(got["mass"] - mass) < 1e-6 and np.allclose(got["com"], c, atol=1e-6)
    assert j["consistent"]["on_boundary"] is True
    assert "consistency boundary" in (out / "report.txt").read_text()
    check_mjcf(out, got)
    tool, v = krl_statement((out / "kuka_load.txt").read_text())
    assert tool == 7
    assert abs(v[0] - got["mass"]) <= 5e-7 * got["mass"]
    np.testing.assert_allclose(v[1:4], 1e3 * np.array(got["com"]), rtol=6e-7, atol=1e-9)


def test_the_shipped_example_loads_in_mujoco_and_kuka_follows_the_grammar(tmp_path):
    """The README's payload chain on copies of the shipped designs (outputs under tmp)."""
    d = tmp_path / "designs"
    d.mkdir()
    for f in ["payload_ur5_excite.toml", "sim_ur5_payload.toml", "sim_ur5_payload_unloaded.toml", "payload_ur5.toml"]:
        shutil.copy(DESIGNS / f, d / f)
    (d / "robots").symlink_to(DESIGNS / "robots")
    for cmd in [["payload", "excite", "payload_ur5_excite.toml"], ["simulate", "sim_ur5_payload.toml"],
                ["simulate", "sim_ur5_payload_unloaded.toml"], ["payload", "identify", "payload_ur5.toml"]]:
        design = d / cmd[-1]
        name = design.stem
        r = subprocess.run([str(IDEXP), *cmd[:-1], str(design), "--out", str(tmp_path / "out" / name)], capture_output=True, text=True, env=ENV)
        assert r.returncode == 0, (cmd, r.stderr)
    out = tmp_path / "out" / "payload_ur5"
    j = json.loads((out / "payload.json").read_text())
    got = j["payload"]
    assert abs(got["mass"] - 1.8) < 0.01
    check_mjcf(out, got)
    tool, v = krl_statement((out / "kuka_load.txt").read_text())
    assert tool == 1
    assert abs(v[0] - got["mass"]) <= 5e-7 * got["mass"]
    script = (out / "payload.script").read_text()
    assert "tool0" in script
