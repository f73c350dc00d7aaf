#!/usr/bin/env python3
"""Writes the robot-log fixtures of tests/logs.rs into tests/data/logs/ with
writers that are not idexp's:

- ROS 2 bags by the `rosbags` package (MCAP and sqlite3 storage), of
  sensor_msgs/msg/JointState with the joints in another order than the
  robot's, an extra joint, a second (non-JointState) topic, and bags with
  irregular stamps, two JointState topics and a duplicate stamp;
- a UR RTDE-recorder CSV with the recorder's real header (the fields of the
  RTDE client library's examples/record_configuration.xml, vectors expanded
  as name_0..name_5, space separated, values as Python writes floats: the
  way rtde/csv_writer.py writes them), timestamps as controller uptime;
- a headerless, whitespace-separated numeric CSV (time in ms);
- the same samples as the uniform bags and the RTDE CSV in idexp's own run
  CSV format (ur5_idexp.csv), for the acceptance test: identification from
  the bag or the RTDE CSV equals identification from this file.

The samples: a UR5 (designs/robots/ur5.urdf) on a 5-harmonic Fourier
trajectory (seeded), its torques by Pinocchio's RNEA plus the Coulomb and
viscous friction of tests/data/logs/ur5_drives.toml; motor currents
i = tau / (current_sign k_t N) with that file's drives.

Run with the test venv (scripts/python-test.sh installs rosbags and pin):
    target/python-venv/bin/python scripts/make-log-fixtures.py
"""

import csv
import math
import shutil
import tomllib
from pathlib import Path

import numpy as np
import pinocchio as pin
from rosbags.rosbag2 import StoragePlugin, Writer
from rosbags.typesys import Stores, get_typestore

ROOT = Path(__file__).resolve().parent.parent
OUT = ROOT / "tests" / "data" / "logs"
ROBOT = OUT / "ur5_drives.toml"
URDF = ROOT / "designs" / "robots" / "ur5.urdf"

N = 400  # samples of the uniform logs
STEP_NS = 5_000_000  # 200 Hz
EPOCH_NS = 1_733_400_000_123_456_789  # header stamp of the first sample
UPTIME_MS = 8_123_456  # RTDE controller uptime of the first sample (ms)

TS = get_typestore(Stores.ROS2_HUMBLE)
JointState = TS.types["sensor_msgs/msg/JointState"]
Header = TS.types["std_msgs/msg/Header"]
Time = TS.types["builtin_interfaces/msg/Time"]
String = TS.types["std_msgs/msg/String"]


def drives():
    spec = tomllib.loads(ROBOT.read_text())
    return spec["drive"]


def samples():
    """q, qd, qdd (N x 6) on a 5-harmonic Fourier trajectory and its torques."""
    rng = np.random.default_rng(37)
    period = 2.0
    wf = 2 * math.pi / period
    t = np.arange(N) * (STEP_NS / 1e9)
    nh = 5
    a = rng.uniform(-0.6, 0.6, (6, nh))
    b = rng.uniform(-0.6, 0.6, (6, nh))
    q0 = np.array([0.0, -1.2, 1.3, -1.6, -1.5, 0.0])
    q = np.tile(q0, (N, 1))
    qd = np.zeros((N, 6))
    qdd = np.zeros((N, 6))
    for j in range(6):
        for l in range(1, nh + 1):
            w = wf * l
            s, c = np.sin(w * t), np.cos(w * t)
            q[:, j] += a[j, l - 1] / w * s - b[j, l - 1] / w * c
            qd[:, j] += a[j, l - 1] * c + b[j, l - 1] * s
            qdd[:, j] += -a[j, l - 1] * w * s + b[j, l - 1] * w * c
    model = pin.buildModelFromUrdf(str(URDF))
    data = model.createData()
    assert model.nq == 6, model.nq
    d = drives()
    fc = np.array([x["fc"] for x in d])
    fv = np.array([x["fv"] for x in d])
    rigid = np.array([pin.rnea(model, data, q[k], qd[k], qdd[k]).copy() for k in range(N)])
    tau = rigid + fc * np.sign(qd) + fv * qd
    return q, qd, qdd, rigid, tau


ROBOT_JOINTS = ["shoulder_pan_joint", "shoulder_lift_joint", "elbow_joint", "wrist_1_joint", "wrist_2_joint", "wrist_3_joint"]
# the order in the bag: not the robot's, with a gripper joint between
BAG_ORDER = ["elbow_joint", "shoulder_pan_joint", "wrist_3_joint", "gripper_finger_joint", "shoulder_lift_joint", "wrist_1_joint", "wrist_2_joint"]


def joint_state(ns, names, q, qd, tau, extra=(0.02, 0.0, 1.5)):
    """A JointState of robot-ordered q, qd, tau in the order `names`."""
    pos, vel, eff = [], [], []
    for n in names:
        if n in ROBOT_JOINTS:
            j = ROBOT_JOINTS.index(n)
            pos.append(q[j])
            vel.append(qd[j] if qd is not None else 0.0)
            eff.append(tau[j])
        else:
            pos.append(extra[0])
            vel.append(extra[1])
            eff.append(extra[2])
    msg = JointState(
        header=Header(stamp=Time(sec=int(ns // 1_000_000_000), nanosec=int(ns % 1_000_000_000)), frame_id=""),
        name=list(names),
        position=np.array(pos, dtype=np.float64),
        velocity=np.array(vel if qd is not None else [], dtype=np.float64),
        effort=np.array(eff, dtype=np.float64),
    )
    return TS.serialize_cdr(msg, JointState.__msgtype__)


def write_bag(path, topics):
    """topics: list of (topic, msgtype, [(receive_ns, bytes)])."""
    if path.exists():
        shutil.rmtree(path)
    plugin = StoragePlugin.MCAP if path.name.endswith("mcap") else StoragePlugin.SQLITE3
    with Writer(path, version=9, storage_plugin=plugin) as w:
        conns = [(w.add_connection(t, mt, typestore=TS), msgs) for t, mt, msgs in topics]
        events = sorted((ns, i, k) for i, (_, msgs) in enumerate(conns) for k, (ns, _) in enumerate(msgs))
        for ns, i, k in events:
            conn, msgs = conns[i]
            w.write(conn, ns, msgs[k][1])


def main():
    q, qd, qdd, rigid, tau = samples()
    d = drives()
    scale = np.array([x.get("current_sign", 1) * x["torque_constant"] * x["gear_ratio"] for x in d])
    current = tau / scale

    # idexp's run CSV of the same samples (t exactly as k * 5e6 ns / 1e9)
    with open(OUT / "ur5_idexp.csv", "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(["t"] + [f"q{j}" for j in range(1, 7)] + [f"tau{j}" for j in range(1, 7)] + [f"qd{j}" for j in range(1, 7)])
        for k in range(N):
            w.writerow([repr(k * STEP_NS / 1e9)] + [repr(float(x)) for x in q[k]] + [repr(float(x)) for x in tau[k]] + [repr(float(x)) for x in qd[k]])

    # uniform bags: joints in another order, a gripper joint, a text topic;
    # the recorder receives each message 0.7..0.9 ms after its stamp
    js = [(EPOCH_NS + k * STEP_NS + 700_000 + (k % 3) * 100_000, joint_state(EPOCH_NS + k * STEP_NS, BAG_ORDER, q[k], qd[k], tau[k])) for k in range(N)]
    text = [(EPOCH_NS + k * 500_000_000, TS.serialize_cdr(String(data=f"note {k}"), String.__msgtype__)) for k in range(3)]
    for name in ["ur5_mcap", "ur5_sqlite3"]:
        write_bag(OUT / name, [("/joint_states", JointState.__msgtype__, js), ("/notes", String.__msgtype__, text)])

    # irregular stamps (2 ms +- 0.6 ms, seeded), a second JointState topic
    # without wrist_3_joint, for topic choice and the missing-joint error
    rng = np.random.default_rng(7)
    m = 40
    steps = 2_000_000 + rng.integers(-600_000, 600_001, m)
    stamps = EPOCH_NS + np.concatenate([[0], np.cumsum(steps[1:])])
    irr = [(int(s) + 300_000, joint_state(int(s), BAG_ORDER, q[k], qd[k], tau[k])) for k, s in enumerate(stamps)]
    cmd_names = [n for n in ROBOT_JOINTS if n != "wrist_3_joint"]
    cmd = [(int(s) + 400_000, joint_state(int(s), cmd_names, q[k], None, tau[k])) for k, s in enumerate(stamps[:10])]
    for name in ["irregular_mcap", "irregular_sqlite3"]:
        write_bag(OUT / name, [("/joint_states", JointState.__msgtype__, irr), ("/joint_commands", JointState.__msgtype__, cmd)])

    # a duplicate header stamp (message 4 repeats message 3's)
    dup_stamps = [EPOCH_NS + k * STEP_NS for k in range(6)]
    dup_stamps[3] = dup_stamps[2]
    dup = [(EPOCH_NS + k * STEP_NS + 500_000, joint_state(s, ROBOT_JOINTS, q[k], qd[k], tau[k])) for k, s in enumerate(dup_stamps)]
    write_bag(OUT / "duplicate_mcap", [("/joint_states", JointState.__msgtype__, dup)])

    # the RTDE recorder's CSV: its header from record_configuration.xml
    fields = [
        ("timestamp", 1), ("target_q", 6), ("target_qd", 6), ("target_qdd", 6), ("target_current", 6),
        ("target_moment", 6), ("actual_q", 6), ("actual_qd", 6), ("actual_current", 6),
        ("joint_control_output", 6), ("actual_TCP_pose", 6), ("actual_TCP_speed", 6), ("actual_TCP_force", 6),
        ("target_TCP_pose", 6), ("target_TCP_speed", 6), ("actual_digital_input_bits", 1),
        ("joint_temperatures", 6), ("actual_execution_time", 1), ("robot_mode", 1), ("joint_mode", 6),
        ("safety_mode", 1), ("actual_tool_accelerometer", 3), ("speed_scaling", 1), ("target_speed_fraction", 1),
        ("actual_momentum", 1), ("actual_main_voltage", 1), ("actual_robot_voltage", 1), ("actual_robot_current", 1),
        ("actual_joint_voltage", 6), ("actual_digital_output_bits", 1), ("runtime_state", 1),
    ]
    header = []
    for name, size in fields:
        header += [name] if size == 1 else [f"{name}_{i}" for i in range(size)]
    with open(OUT / "ur5_rtde.csv", "w", newline="") as f:
        w = csv.writer(f, delimiter=" ")
        w.writerow(header)
        for k in range(N):
            ms = UPTIME_MS + 5 * k
            # the recorder writes the double it received: Python's shortest repr
            values = {
                "timestamp": [float(f"{ms // 1000}.{ms % 1000:03d}")],
                "target_q": q[k], "target_qd": qd[k], "target_qdd": qdd[k], "target_current": current[k],
                "target_moment": rigid[k], "actual_q": q[k], "actual_qd": qd[k], "actual_current": current[k],
                "joint_control_output": [0.0] * 6, "actual_TCP_pose": [0.0] * 6, "actual_TCP_speed": [0.0] * 6,
                "actual_TCP_force": [0.0] * 6, "target_TCP_pose": [0.0] * 6, "target_TCP_speed": [0.0] * 6,
                "actual_digital_input_bits": [0], "joint_temperatures": [31.5] * 6, "actual_execution_time": [0.4],
                "robot_mode": [7], "joint_mode": [253] * 6, "safety_mode": [1], "actual_tool_accelerometer": [0.0, 0.0, 9.81],
                "speed_scaling": [1.0], "target_speed_fraction": [1.0], "actual_momentum": [0.0],
                "actual_main_voltage": [48.0], "actual_robot_voltage": [48.0], "actual_robot_current": [1.2],
                "actual_joint_voltage": [47.9] * 6, "actual_digital_output_bits": [0], "runtime_state": [2],
            }
            row = []
            for name, _ in fields:
                row += [x if isinstance(x, int) else float(x) for x in values[name]]
            w.writerow(row)

    # a headerless, whitespace-separated log: sample counter, t (ms), q1..q6, tau1..tau6
    with open(OUT / "ur5_headerless.txt", "w") as f:
        for k in range(100):
            vals = [str(k), str(5 * k)] + [repr(float(x)) for x in q[k]] + [repr(float(x)) for x in tau[k]]
            f.write("  ".join(vals) + "\n")


if __name__ == "__main__":
    main()
