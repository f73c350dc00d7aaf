"""The payload's frame against Pinocchio (issue 43, item 1).

A payload given in a frame F (mass m, centre c and inertia I_c in F's axes)
means, as in a URDF and in Pinocchio, the rigid body Y = Inertia(m, c, I_c)
placed in F's link by F's pose: the link's inertia becomes
`inertias[joint] + frame.placement.act(Y)`. These tests compute that with
Pinocchio alone and compare it with idexp's side:

* the joint torques of the robot carrying the payload (`idexp.with_payload`,
  the map `idexp simulate` and `idexp payload identify` use) equal
  `pinocchio.rnea` of the merged model, for the UR5's `tool0` (rotated by
  rpy (−π/2, 0, 0) and offset against `wrist_3_link`) and random frames with
  rotation and offset on the wrist, on `tool0` and on the forearm;
* `idexp payload identify` on run files whose torques Pinocchio computed
  (noiseless, loaded and unloaded twins) recovers the mass and the centre of
  mass in F's axes to 1e-6.
"""

import json
import os
import re
import subprocess

import numpy as np
import pytest

import idexp
from conftest import IDEXP, ROBOTS

pin = pytest.importorskip("pinocchio")

# frames added to the UR5: name, parent link, xyz, rpy
EXTRA = [
    ("frame_wrist", "wrist_3_link", (0.031, -0.047, 0.112), (0.7, -1.1, 2.3)),
    ("frame_tool", "tool0", (-0.02, 0.05, 0.15), (-2.4, 0.3, 1.2)),
    ("frame_tool_2", "frame_tool", (0.01, 0.0, -0.04), (0.2, 1.4, -0.6)),
    ("frame_forearm", "forearm_link", (0.12, 0.04, 0.2), (1.9, 0.4, -0.8)),
]

# the issue's example: 2.0 kg, centre (30, 20, 100) mm in tool0
ISSUE = {"mass": 2.0, "com": [0.03, 0.02, 0.10], "inertia": [0.012, 0.001, -0.0005, 0.010, 0.0007, 0.006]}


def write_urdf(folder):
    """ur5.urdf with the EXTRA frames as fixed joints (and no meshes: Pinocchio
    and idexp read only kinematics and inertials here)."""
    text = (ROBOTS / "ur5.urdf").read_text()
    text = re.sub(r"<visual>.*?</visual>|<collision>.*?</collision>", "", text, flags=re.S)
    add = "".join(
        f'<link name="{n}"/><joint name="{n}_joint" type="fixed"><parent link="{p}"/><child link="{n}"/>'
        f'<origin xyz="{x[0]} {x[1]} {x[2]}" rpy="{r[0]} {r[1]} {r[2]}"/></joint>\n'
        for n, p, x, r in EXTRA
    )
    text = text.replace("</robot>", add + "</robot>")
    path = folder / "ur5_frames.urdf"
    path.write_text(text)
    return path


def random_payload(g):
    """A physically consistent rigid body: mass, centre, inertia about the centre."""
    m = g.uniform(0.5, 5.0)
    c = g.uniform(-0.15, 0.15, 3)
    r, _ = np.linalg.qr(g.normal(size=(3, 3)))
    d = g.uniform(0.2, 1.0, 3)
    # principal moments of point masses: each ≤ the sum of the others
    mom = np.array([d[1] + d[2], d[0] + d[2], d[0] + d[1]]) * 0.01 * m
    ic = r @ np.diag(mom) @ r.T
    return {"mass": m, "com": list(c), "inertia": [ic[0, 0], ic[0, 1], ic[0, 2], ic[1, 1], ic[1, 2], ic[2, 2]]}


def pin_loaded(model, frame, p):
    """Pinocchio's model with the payload merged into the frame's joint by SE3.act."""
    i = p["inertia"]
    ic = np.array([[i[0], i[1], i[2]], [i[1], i[3], i[4]], [i[2], i[4], i[5]]])
    y = pin.Inertia(p["mass"], np.array(p["com"]), ic)
    m = model.copy()
    f = m.frames[m.getFrameId(frame)]
    m.inertias[f.parentJoint] = m.inertias[f.parentJoint] + f.placement.act(y)
    return m


@pytest.fixture(scope="module")
def urdf(tmp_path_factory):
    return write_urdf(tmp_path_factory.mktemp("frames"))


def test_tool0_is_rotated_and_offset(urdf):
    """The case the tests must cover: tool0's placement in its joint is not a pure translation."""
    model = pin.buildModelFromUrdf(str(urdf))
    f = model.frames[model.getFrameId("tool0")]
    assert np.linalg.norm(f.placement.translation) > 0.05
    assert np.abs(f.placement.rotation - np.eye(3)).max() > 0.5


@pytest.mark.parametrize("frame", ["tool0"] + [e[0] for e in EXTRA])
def test_payload_torques_equal_pinocchio_rnea_with_the_payload_merged_by_se3_act(urdf, frame):
    robot = idexp.Robot.load(urdf)
    model = pin.buildModelFromUrdf(str(urdf))
    data = model.createData()
    g = np.random.default_rng(abs(hash(frame)) % 2**32)
    lo, hi = robot.limits["lower"], robot.limits["upper"]
    # the robot alone agrees first (its drive terms are zero for a bare URDF)
    q = g.uniform(np.maximum(lo, -3), np.minimum(hi, 3))
    v, a = g.uniform(-2, 2, 6), g.uniform(-5, 5, 6)
    np.testing.assert_allclose(robot.rnea(q, v, a), pin.rnea(model, data, q, v, a), rtol=0, atol=1e-9)
    worst = 0.0
    for p in [ISSUE] + [random_payload(g) for _ in range(3)]:
        loaded = idexp.with_payload(robot, frame=frame, **p)
        mp = pin_loaded(model, frame, p)
        dp = mp.createData()
        payload_alone = 0.0
        for _ in range(20):
            q = g.uniform(np.maximum(lo, -3), np.minimum(hi, 3))
            v, a = g.uniform(-2, 2, 6), g.uniform(-5, 5, 6)
            tau = loaded.rnea(q, v, a)
            ref = pin.rnea(mp, dp, q, v, a)
            np.testing.assert_allclose(tau, ref, rtol=0, atol=1e-9)
            worst = max(worst, np.abs(tau - ref).max())
            payload_alone = max(payload_alone, np.abs(ref - pin.rnea(model, data, q, v, a)).max())
        # the payload's own torques are large: the comparison can see a wrong frame
        assert payload_alone > 1.0
    print(f"{frame}: max |τ_idexp − τ_pinocchio| = {worst:.2e} N·m")


def fourier(t, w, q0, a, b):
    """q(t) of idexp's Fourier trajectory (trajectory.json's a, b per joint and harmonic)."""
    q = np.tile(q0, (len(t), 1))
    for k in range(a.shape[1]):
        kw = (k + 1) * w
        q += a[:, k] / kw * np.sin(kw * t[:, None]) - b[:, k] / kw * np.cos(kw * t[:, None])
    return q


def derivatives(t, w, a, b):
    qd = np.zeros((len(t), a.shape[0]))
    qdd = np.zeros_like(qd)
    for k in range(a.shape[1]):
        kw = (k + 1) * w
        s, c = np.sin(kw * t[:, None]), np.cos(kw * t[:, None])
        qd += a[:, k] * c + b[:, k] * s
        qdd += kw * (-a[:, k] * s + b[:, k] * c)
    return qd, qdd


def write_run(folder, t, q, tau, traj):
    """One idexp run folder: two identical repetitions (rep_*.csv: t, q, tau) and trajectory.json."""
    folder.mkdir(parents=True)
    n = q.shape[1]
    head = ",".join(["t"] + [f"q{j + 1}" for j in range(n)] + [f"tau{j + 1}" for j in range(n)])
    for r in (1, 2):
        np.savetxt(folder / f"rep_{r:03}.csv", np.column_stack([t, q, tau]), delimiter=",", header=head, comments="", fmt="%.17g")
    (folder / "trajectory.json").write_text(json.dumps({"trajectory": traj}))


def write_twins(folder, model, frame, p, w, q0, a, b):
    """Noiseless twins from Pinocchio: `loaded` (payload `p` merged into
    `frame`'s link by SE3.act) and `unloaded`, 10 s of the Fourier motion
    (w, q0, a, b) at 100 Hz, as run folders under `folder`."""
    data = model.createData()
    t = np.arange(0, 10.0, 0.01)
    q = fourier(t, w, q0, a, b)
    qd, qdd = derivatives(t, w, a, b)
    mp = pin_loaded(model, frame, p)
    dp = mp.createData()
    tau_u = np.array([pin.rnea(model, data, q[i], qd[i], qdd[i]) for i in range(len(t))])
    tau_l = np.array([pin.rnea(mp, dp, q[i], qd[i], qdd[i]) for i in range(len(t))])
    traj = {"omega": w, "q0": list(q0), "a": a.tolist(), "b": b.tolist()}
    write_run(folder / "loaded", t, q, tau_l, traj)
    write_run(folder / "unloaded", t, q, tau_u, traj)


@pytest.mark.parametrize("frame", ["tool0", "frame_tool_2", "frame_wrist"])
def test_identify_recovers_a_pinocchio_payload_in_its_frame(urdf, tmp_path, frame):
    model = pin.buildModelFromUrdf(str(urdf))
    g = np.random.default_rng(43 + len(frame))
    nh, w = 4, 2 * np.pi / 10.0
    q0 = np.array([0.0, -1.4, 1.6, -1.8, -1.57, 0.0])
    a = g.uniform(-0.25, 0.25, (6, nh))
    b = g.uniform(-0.25, 0.25, (6, nh))
    p = ISSUE if frame == "tool0" else random_payload(g)
    write_twins(tmp_path, model, frame, p, w, q0, a, b)
    design = tmp_path / "payload.toml"
    design.write_text(
        f'name = "pin_payload"\nrobot = "{urdf}"\nframe = "{frame}"\nmethod = "ols"\nexport = []\n'
        '[[loaded]]\nname = "loaded"\nfiles = ["loaded"]\nharmonics = 4\n'
        '[[unloaded]]\nname = "unloaded"\nfiles = ["unloaded"]\nharmonics = 4\n'
    )
    out = tmp_path / "out"
    env = dict(os.environ, IDEXP_NO_PROGRESS="1")
    r = subprocess.run([str(IDEXP), "payload", "identify", str(design), "--out", str(out)], capture_output=True, text=True, env=env)
    assert r.returncode == 0, r.stderr
    got = json.loads((out / "payload.json").read_text())["payload"]
    print(f"{frame}: mass {got['mass']:.9f} (true {p['mass']:.9f}), com {got['com']} (true {p['com']})")
    assert abs(got["mass"] - p["mass"]) < 1e-6 * p["mass"]
    np.testing.assert_allclose(got["com"], p["com"], rtol=0, atol=1e-6)
