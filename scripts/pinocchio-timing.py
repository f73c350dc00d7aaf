"""Pinocchio's C++ kernels next to idexp's criterion figures, same models
(designs/robots/{ur5,panda}.urdf), same states (those benches/robot.rs writes
to target/bench-states/), one thread. Run by scripts/pinocchio-timing.sh,
which builds the C++ timing program and runs the bench first.

usage: python pinocchio-timing.py <timing-binary> <target-dir>
"""

import json
import os
import subprocess
import sys

import pinocchio as pin

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
ROBOTS = [("ur5", "ur5_6dof"), ("panda", "panda_7dof")]
# (Pinocchio kernel, idexp criterion bench, what idexp's kernel computes)
PAIRS = [
    ("crba", "mass_matrix_into", "M(q) into a buffer (Pinocchio: upper triangle)"),
    ("rnea", "rnea", "inverse dynamics (idexp: + friction)"),
    ("computeJointTorqueRegressor", "regressor_row_block", "regressor n×p (idexp: + drive columns)"),
    ("computeRNEADerivatives", "id_derivatives", "∂τ/∂q, ∂τ/∂q̇ (Pinocchio: + M)"),
    ("aba", "forward_dynamics_into", "forward dynamics (idexp: CRBA + Cholesky)"),
    (None, "regressor_derivatives", "Y, ∂Y/∂q, ∂Y/∂q̇, ∂Y/∂q̈ (no Pinocchio kernel)"),
]


def criterion_ns(target, group, bench):
    path = os.path.join(target, "criterion", group, bench, "new", "estimates.json")
    try:
        with open(path) as f:
            return json.load(f)["median"]["point_estimate"]
    except (OSError, KeyError, ValueError):
        return None


def main():
    if len(sys.argv) != 3:
        sys.exit(__doc__)
    binary, target = sys.argv[1], sys.argv[2]
    out = os.path.join(target, "pinocchio-timing")
    os.makedirs(out, exist_ok=True)
    rows = []
    for name, group in ROBOTS:
        urdf = os.path.join(ROOT, "designs", "robots", f"{name}.urdf")
        states = os.path.join(target, "bench-states", f"{name}.txt")
        if not os.path.exists(states):
            sys.exit(f"{states}: missing; run `cargo bench --bench robot` first (it writes the states)")
        model = pin.buildModelFromUrdf(urdf)
        model_bin = os.path.join(out, f"{name}.bin")
        model.saveToBinary(model_bin)
        res = subprocess.run([binary, model_bin, states, name], check=True, capture_output=True, text=True)
        pin_ns = {}
        for line in res.stdout.splitlines():
            label, kernel, median, _minimum, _calls = line.split()
            pin_ns[kernel] = float(median)
        for kernel, bench, what in PAIRS:
            rows.append((name, model.nv, kernel, pin_ns.get(kernel), bench, criterion_ns(target, group, bench), what))
    load = open("/proc/loadavg").read().split()[:3]
    print(f"one thread; load average {' '.join(load)}; Pinocchio {pin.__version__} C++ (median of 15 batches), "
          "idexp criterion median (target/criterion)")
    print()
    print("| robot | Pinocchio kernel | Pinocchio µs | idexp bench | idexp µs | Pinocchio / idexp | idexp computes |")
    print("|---|---|---|---|---|---|---|")
    fmt = lambda ns: "—" if ns is None else f"{ns / 1000:.2f}"
    for name, nv, kernel, p, bench, i, what in rows:
        ratio = f"{p / i:.2f}×" if p and i else "—"
        print(f"| {name} ({nv}) | {kernel or '—'} | {fmt(p)} | {bench} | {fmt(i)} | {ratio} | {what} |")


if __name__ == "__main__":
    main()
