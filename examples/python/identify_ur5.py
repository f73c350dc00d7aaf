"""Identify a UR5 from a designed excitation, in simulation (notebook style).

1. design an excitation trajectory for the shipped UR5 (idexp.excite),
2. simulate the closed-loop robot tracking it, with "true" parameters 10 %
   away from the nominal ones and noisy torque and encoder readings
   (idexp.simulate),
3. identify the base parameters from the simulated run (idexp.identify),
4. plot measured vs predicted torques per joint with matplotlib.

Run from the repository root, with the package installed (README, "Python"):

    target/python-venv/bin/python examples/python/identify_ur5.py

Outputs in out/identify_ur5/ (the excitation folder, the run folder, the
identification folder and torques.png). About half a minute on 2 cores.
"""

import argparse
import pathlib

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

import idexp  # noqa: E402

ROOT = pathlib.Path(__file__).resolve().parents[2]

ap = argparse.ArgumentParser(description="UR5: excite, simulate, identify, plot")
ap.add_argument("--out", type=pathlib.Path, default=pathlib.Path("out/identify_ur5"))
ap.add_argument("--repetitions", type=int, default=10)
args = ap.parse_args()
out = args.out

# %% 1. excitation design: the shipped design, searched a little less long
design = {
    "name": "excite_ur5_example",
    "robot": str(ROOT / "designs/robots/ur5.toml"),
    "seed": 1,
    "trajectory": {"harmonics": 5, "frequency": 0.1, "q0": [0.0] * 6},
    "objective": {"criterion": "cond", "scaling": "unit_column", "sample_rate": 10.0},
    "limits": {"position": 0.8, "velocity": 1.0, "acceleration": 1.0},
    "ga": {"population": 24, "generations": 10},
    "refine": {"algorithm": "slsqp", "starts": 1, "max_evals": 100},
}
exc = idexp.excite(design)
print(exc)
exc.write(out / "excite")

# %% 2. closed-loop simulation of the designed trajectory
sim = idexp.simulate(
    {
        "name": "ur5_rehearsal",
        "robot": str(ROOT / "designs/robots/ur5.toml"),
        "rate": 1000.0,
        "decimate": 5,
        "repetitions": args.repetitions,
        "seed": 1,
        "truth": {"perturbation": 0.1, "seed": 7},
        "controller": {"bandwidth": 10.0, "feedforward": "nominal"},
        "noise": {"torque": 0.2, "position": 2e-5},
        "reference": {"kind": "fourier", "file": str(out / "excite" / "coefficients.json")},
    }
)
print(sim)
sim.write(out / "run")

# %% 3. identification (WLS, Fourier filtering at the trajectory's harmonics)
robot = idexp.Robot.load(ROOT / "designs/robots/ur5.toml")
ident = idexp.identify(robot, sim, method="wls", truth=sim)
ident.write(out / "identify")
print(ident)
z = np.array([row["z"] for row in ident.truth])
print(f"{len(z)} base parameters; |estimate − truth|/σ: median {np.median(np.abs(z)):.2f}, max {np.abs(z).max():.2f}")
print("relative error e*_j (%):", np.round(100 * np.array(ident.errors["e_rel"]), 2))

# %% 4. measured vs predicted torques
tq = ident.torques
t, meas, pred = tq["t"], tq["measured"], tq["predicted"]
fig, axes = plt.subplots(3, 2, figsize=(11, 8.5), sharex=True, constrained_layout=True)
for j, ax in enumerate(axes.T.flat):
    ok = np.isfinite(meas[:, j])
    ax.plot(t[ok], meas[ok, j], ".", ms=1.5, color="0.55", label="measured (averaged, filtered; samples of slow joint motion left out)")
    ax.plot(t, np.where(np.isfinite(meas[:, j]), pred[:, j], np.nan), "-", lw=1.0, color="tab:red",
            label="predicted (identified model)")
    ax.set_title(f"joint {j + 1} ({robot.joint_names[j]}): e* = {100 * ident.errors['e_rel'][j]:.1f} %", fontsize=10)
    ax.set_ylabel("torque (N·m)")
    ax.grid(alpha=0.3)
for ax in axes[-1]:
    ax.set_xlabel("t (s)")
handles, labels = axes[0, 0].get_legend_handles_labels()
fig.legend(handles, labels, loc="outside lower center", ncol=2, markerscale=6)
fig.suptitle("UR5, simulated identification run: measured vs predicted motor torques")
png = out / "torques.png"
fig.savefig(png, dpi=110)
print(f"written {png}")
