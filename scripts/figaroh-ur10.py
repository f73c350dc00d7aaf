#!/usr/bin/env python3
"""FIGAROH's criterion on its UR10 trajectory problem, for a trajectory from any tool.

    target/python-venv/bin/python scripts/figaroh-ur10.py TRAJ.csv [--segment K] [--json FILE]
    target/python-venv/bin/python scripts/figaroh-ur10.py --columns      # FIGAROH's base columns, idexp names

The problem is FIGAROH 1.0.2's UR10 example (figaroh-examples,
examples/ur10/config/ur10_unified_config.yaml): example-robot-data's UR10,
7 waypoints 2 s apart at rest, the regressor sampled at 20 Hz (241 samples
of the 12 s), no friction columns, the base columns FIGAROH's QR picks, and
the criterion FIGAROH minimises: the 2-norm condition number of that base
regressor, unscaled (`BaseOptimalTrajectory.objective_function`).

Everything below is computed by FIGAROH's own functions
(`pip install figaroh==1.0.2`): the robot (`figaroh.tools.load_robot`), the
base columns (`figaroh.optimal.base_parameter.BaseParameterComputer`: the
columns its pivoted QR keeps on its random 100-waypoint trajectory, numpy
seeded by --base-seed: the set depends on that trajectory; seeds 0 and 1
give the set written in designs/excite_ur10_figaroh.toml, seed 2 one with
MY6 instead of MY5), the
regressor (`build_regressor_basic`, `build_regressor_reduced`,
`build_baseRegressor`) and the condition number
(`figaroh.tools.qrdecomposition.cond_num`). It is cross-checked with
Pinocchio alone (`computeJointTorqueRegressor` at every sample, the same
columns picked by name): the two must agree to 1e-9 (relative), else the
script exits 3.

The trajectory: a CSV with a header `t, q1..q6, qd1..qd6, qdd1..qdd6`
(further columns ignored; idexp's trajectory.csv has `segment` last). With
--segment K only the rows of that segment are used (idexp: 1 = the designed
motion) and the row at its end (the first of the next part: idexp labels a
boundary sample with the part that starts there), their time taken from the
segment's first row. The samples are the
rows at 0, 1/20, 2/20, ... s of the motion (to 1e-6 s), so a 1 kHz file
gives 241 samples for 12 s; --rate changes 20 Hz. A file at exactly the
criterion's rate (FIGAROH's own output) is used as it is.

Also reported: the condition number with unit-norm columns (idexp's default
scaling) on the same samples, and the samples' count and time range.
Exit status: 0 done, 2 bad input, 3 FIGAROH and Pinocchio disagree.
"""

from __future__ import annotations

import argparse
import csv
import json
import os
import site
import sys
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
URDF_REL = "tests/data/ros/example-robot-data/robots/ur_description/urdf/ur10_robot.urdf"
JOINTS = ["shoulder_pan_joint", "shoulder_lift_joint", "elbow_joint", "wrist_1_joint", "wrist_2_joint", "wrist_3_joint"]
# FIGAROH's parameter order per link (Pinocchio's dynamic parameters) and idexp's names of the same parameters
FIG_PARAMS = ["m", "mx", "my", "mz", "Ixx", "Ixy", "Iyy", "Ixz", "Iyz", "Izz"]
IDEXP_PARAMS = ["M", "MX", "MY", "MZ", "XX", "XY", "YY", "XZ", "YZ", "ZZ"]

try:
    import pinocchio as pin
    from figaroh.tools.load_robot import load_robot
    from figaroh.optimal.base_parameter import BaseParameterComputer
    from figaroh.tools.regressor import build_regressor_basic, build_regressor_reduced
    from figaroh.tools.qrdecomposition import build_baseRegressor, cond_num
except ImportError as e:  # pragma: no cover - environment
    sys.exit(f"figaroh-ur10: needs FIGAROH 1.0.2 and Pinocchio (pip install figaroh==1.0.2 pin): {e}")


def fail(msg: str) -> None:
    print(f"figaroh-ur10: {msg}", file=sys.stderr)
    sys.exit(2)


def identif_config() -> dict:
    # FIGAROH's identification settings of the UR10 example: no friction, no
    # actuator inertia, no joint offset, joint torques (model_components)
    return {"has_friction": False, "has_actuator_inertia": False, "has_joint_offset": False, "is_joint_torques": True, "is_external_wrench": False}


def vendor_share() -> list[str]:
    """example-robot-data's share folders (its meshes, which FIGAROH's loader needs)."""
    out = []
    for sp in site.getsitepackages() + [site.getusersitepackages()]:
        p = Path(sp) / "cmeel.prefix" / "share"
        if (p / "example-robot-data").is_dir():
            out.append(str(p))
    return out


def figaroh_setup(urdf: Path, base_seed: int):
    share = vendor_share()
    if not share:
        fail("FIGAROH's loader needs example-robot-data's meshes (pip install example-robot-data): no cmeel.prefix/share/example-robot-data found")
    robot = load_robot(str(urdf), package_dirs=share[0], load_by_urdf=True)
    cfg = identif_config()
    # the active joints' indices, as the example's optimal_trajectory.py sets them
    cfg["active_joints"] = JOINTS
    cfg["act_Jid"] = [robot.model.getJointId(j) for j in JOINTS]
    cfg["act_J"] = [robot.model.joints[i] for i in cfg["act_Jid"]]
    cfg["act_idxq"] = [J.idx_q for J in cfg["act_J"]]
    cfg["act_idxv"] = [J.idx_v for J in cfg["act_J"]]
    np.random.seed(base_seed)
    computer = BaseParameterComputer(robot, cfg, JOINTS, np.full((3, len(JOINTS)), 0.1))
    idx_e, idx_b = computer.compute_base_indices()
    names = list(computer.standard_parameter.keys())
    kept = [n for i, n in enumerate(names) if i not in set(int(k) for k in idx_e)]
    base = [kept[int(k)] for k in idx_b]
    return robot, cfg, idx_e, idx_b, base


def idexp_name(fig: str) -> str:
    p, joint = fig.split("_", 1)
    return f"{IDEXP_PARAMS[FIG_PARAMS.index(p)]}{JOINTS.index(joint) + 1}"


def read_samples(path: Path, segment: int | None, rate: float):
    try:
        with open(path, newline="") as f:
            rows = list(csv.reader(f))
    except OSError as e:
        fail(f"{path}: {e}")
    if not rows:
        fail(f"{path}: empty file")
    head = [h.strip() for h in rows[0]]
    need = ["t"] + [f"{p}{j}" for p in ("q", "qd", "qdd") for j in range(1, 7)]
    missing = [c for c in need if c not in head]
    if missing:
        fail(f"{path}: header: missing column(s) {missing}; expected t, q1..q6, qd1..qd6, qdd1..qdd6")
    col = {c: head.index(c) for c in need}
    seg_col = head.index("segment") if "segment" in head else None
    if segment is not None and seg_col is None:
        fail(f"{path}: --segment {segment}: the file has no `segment` column")
    data = []
    inside = False
    for r, row in enumerate(rows[1:], start=2):
        if not row:
            continue
        try:
            vals = [float(row[col[c]]) for c in need]
            seg = int(float(row[seg_col])) if seg_col is not None else None
        except (ValueError, IndexError):
            fail(f"{path}: row {r}: not a number in {row[:3]}...")
        if segment is None or seg == segment:
            data.append(vals)
            inside = True
        elif inside:
            # the sample at the segment's end: the first row of the next part
            # (idexp labels a boundary sample with the part that starts there)
            data.append(vals)
            break
    if not data:
        fail(f"{path}: no rows" + (f" in segment {segment}" if segment is not None else ""))
    a = np.array(data)
    t = a[:, 0] - a[0, 0]
    k = t * rate
    keep = np.abs(k - np.round(k)) < 1e-6 * rate
    a, t = a[keep], t[keep]
    return t, a[:, 1:7], a[:, 7:13], a[:, 13:19]


def figaroh_criterion(robot, cfg, idx_e, idx_b, q, v, a):
    W = build_regressor_basic(robot, q, v, a, cfg)
    W_b = build_baseRegressor(build_regressor_reduced(W, idx_e), idx_b)
    return W_b, float(cond_num(W_b))


def pinocchio_criterion(urdf: Path, base: list, q, v, a):
    model = pin.buildModelFromUrdf(str(urdf))
    data = model.createData()
    cols = []
    for name in base:
        p, joint = name.split("_", 1)
        cols.append(10 * (model.getJointId(joint) - 1) + FIG_PARAMS.index(p))
    Y = np.vstack([pin.computeJointTorqueRegressor(model, data, q[i], v[i], a[i])[:, cols] for i in range(len(q))])
    return Y, float(np.linalg.cond(Y))


def unit_cond(W):
    return float(np.linalg.cond(W / np.linalg.norm(W, axis=0)))


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("trajectory", nargs="?", type=Path, help="trajectory CSV (t, q1..q6, qd1..qd6, qdd1..qdd6[, segment])")
    ap.add_argument("--segment", type=int, help="only the rows of this segment (idexp's trajectory.csv: 1)")
    ap.add_argument("--rate", type=float, default=20.0, help="criterion samples per second (FIGAROH's UR10: 20)")
    ap.add_argument("--urdf", type=Path, default=HERE.parent / URDF_REL, help="UR10 URDF (default: example-robot-data's copy in tests/data/ros)")
    ap.add_argument("--base-seed", type=int, default=0, help="numpy seed of FIGAROH's random trajectory for its base columns")
    ap.add_argument("--columns", action="store_true", help="print FIGAROH's base columns (its names and idexp's) and stop")
    ap.add_argument("--json", type=Path, help="write the figures here as JSON")
    args = ap.parse_args(argv)
    if not args.urdf.is_file():
        fail(f"--urdf: {args.urdf}: no such file")
    if not (args.rate > 0):
        fail(f"--rate: {args.rate}: expected a positive rate (Hz)")
    robot, cfg, idx_e, idx_b, base = figaroh_setup(args.urdf, args.base_seed)
    ours = [idexp_name(n) for n in base]
    if args.columns:
        print(f"{len(base)} base columns (FIGAROH's QR, base seed {args.base_seed}):")
        print("FIGAROH:", ", ".join(base))
        print("idexp base_columns = [" + ", ".join(f'"{n}"' for n in ours) + "]")
        return 0
    if args.trajectory is None:
        fail("a trajectory CSV is needed (or --columns)")
    t, q, v, a = read_samples(args.trajectory, args.segment, args.rate)
    W_b, fig = figaroh_criterion(robot, cfg, idx_e, idx_b, q, v, a)
    Y, pc = pinocchio_criterion(args.urdf, base, q, v, a)
    rel = abs(fig - pc) / fig
    out = {
        "trajectory": str(args.trajectory),
        "segment": args.segment,
        "samples": int(len(t)),
        "time_range": [float(t[0]), float(t[-1])],
        "rate": args.rate,
        "base_columns": ours,
        "figaroh_cond": fig,
        "pinocchio_cond": pc,
        "relative_difference": rel,
        "unit_column_cond": unit_cond(W_b),
    }
    print(f"{args.trajectory}: {len(t)} samples, t = {t[0]:.3f} .. {t[-1]:.3f} s at {args.rate:g} Hz")
    print(f"FIGAROH's criterion (cond of its {W_b.shape[1]}-column base regressor, unscaled): {fig:.4f}")
    print(f"Pinocchio's regressor, the same columns: {pc:.4f} (relative difference {rel:.1e})")
    print(f"unit-column cond on the same samples: {out['unit_column_cond']:.4f}")
    if args.json:
        args.json.write_text(json.dumps(out, indent=2) + "\n")
    if rel > 1e-9:
        print("figaroh-ur10: FIGAROH and Pinocchio disagree", file=sys.stderr)
        return 3
    return 0


if __name__ == "__main__":
    sys.exit(main())
