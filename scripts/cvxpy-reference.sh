#!/usr/bin/env bash
# CVXPY + Clarabel on the relaxed D- and A-optimal reference instances, the
# very instances idexp solves (written by examples/positions_reference.rs):
#   D: p = 26, 1,000 candidates, F_i = J_iᵀJ_i, J_i 3×26 standard normal (seed 1)
#   A: p = 8, 5,000 candidates, J_i 3×8 (seed 2)
# Makes the venv target/cvxpy-venv (cvxpy + clarabel from PyPI) on first use,
# writes the instances and idexp's results to target/positions-reference/, then
# times CVXPY + Clarabel (problem construction included, as a user would run
# it) and compares the optimum with idexp's certified value.
#
# Usage: scripts/cvxpy-reference.sh [repeats]   (default 3; the best time is reported)
set -euo pipefail
cd "$(dirname "$0")/.."
repeats="${1:-3}"
venv=target/cvxpy-venv
out=target/positions-reference
if [ ! -x "$venv/bin/python" ] || ! "$venv/bin/python" -c "import cvxpy, clarabel" 2>/dev/null; then
  python3 -m venv "$venv"
  "$venv/bin/pip" install --quiet cvxpy clarabel
fi
cargo run --release --quiet --example positions_reference -- "$out"
"$venv/bin/python" - "$out" "$repeats" <<'PY'
import json, sys, time
import numpy as np
import cvxpy as cp

out, repeats = sys.argv[1], int(sys.argv[2])
for name in ["d_1000x26", "a_5000x8"]:
    inst = json.load(open(f"{out}/{name}.json"))
    J = np.array(inst["jacobians"])          # n × 3 × p
    n, _, p = J.shape
    F = np.einsum("nri,nrj->nij", J, J)      # F_i = J_iᵀ J_i
    best, val = float("inf"), None
    for _ in range(repeats):
        t = time.perf_counter()
        w = cp.Variable(n, nonneg=True)
        M = cp.reshape(F.reshape(n, p * p).T @ w, (p, p), order="C")
        M = (M + M.T) / 2
        if inst["criterion"] == "d":
            prob = cp.Problem(cp.Maximize(cp.log_det(M)), [cp.sum(w) == 1])
        else:
            prob = cp.Problem(cp.Minimize(cp.matrix_frac(np.eye(p), M)), [cp.sum(w) == 1])
        prob.solve(solver=cp.CLARABEL)
        best = min(best, time.perf_counter() - t)
        val = prob.value
    ours = json.load(open(f"{out}/{name}.idexp.json"))
    label = "log det M" if inst["criterion"] == "d" else "tr M^-1"
    print(f"{name}: CVXPY+Clarabel {label} = {val:.10f} ({prob.status}), best of {repeats}: {best:.3f} s | "
          f"idexp {ours['value']:.10f} ({ours['status']}, efficiency >= {ours['efficiency_bound']:.9f}) {ours['wall_s']:.3f} s | "
          f"|diff| {abs(val - ours['value']):.2e}, speed-up {best / ours['wall_s']:.1f}x")
PY
