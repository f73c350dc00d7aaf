"""Binding overhead of one `robot.regressor` call on a batch of 10,000 UR5
states: the Python call, timed here, against the same work in Rust
(`cargo bench -p idexp-python --bench regressor_batch`, the same states).

Run from the repository root, with the package installed
(scripts/python-test.sh builds it into target/python-venv):

    target/python-venv/bin/python python/bench/regressor_overhead.py

It prints the median of 20 calls (C order, then the same states in Fortran
order; and of 200 calls on one state); with
`--rust SECONDS` (criterion's median for 10000_states) also the overhead in %.
"""

import argparse
import pathlib
import time

import numpy as np

import idexp

ROOT = pathlib.Path(__file__).resolve().parents[2]


def states(n, k):
    i = np.arange(k)[:, None]
    j = np.arange(n)[None, :]
    return 2 * np.sin(0.37 * i + j), 1.5 * np.cos(0.23 * i + 2 * j), 4 * np.sin(0.11 * i + 3 * j)


def median_time(f, repeats):
    f()
    ts = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        f()
        ts.append(time.perf_counter() - t0)
    return float(np.median(ts))


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rust", type=float, help="criterion's median time of ur5_regressor_batch/10000_states (s)")
    ap.add_argument("--repeats", type=int, default=20)
    a = ap.parse_args()
    robot = idexp.Robot.load(ROOT / "designs/robots/ur5.toml")
    q, qd, qdd = states(robot.dof, 10_000)
    t_batch = median_time(lambda: robot.regressor(q, qd, qdd), a.repeats)
    qf, qdf, qddf = (np.asfortranarray(a) for a in (q, qd, qdd))
    t_fortran = median_time(lambda: robot.regressor(qf, qdf, qddf), a.repeats)
    t_one = median_time(lambda: robot.regressor(q[0], qd[0], qdd[0]), 200)
    print(f"robot.regressor, 10000 states → (60000, {robot.n_params}): median {t_batch * 1e3:.2f} ms")
    print(f"robot.regressor, the same states in Fortran order: median {t_fortran * 1e3:.2f} ms")
    print(f"robot.regressor, one state → (6, {robot.n_params}): median {t_one * 1e6:.1f} µs")
    if a.rust:
        print(f"Rust (criterion) {a.rust * 1e3:.2f} ms: overhead {100 * (t_batch / a.rust - 1):+.1f} %")


if __name__ == "__main__":
    main()
