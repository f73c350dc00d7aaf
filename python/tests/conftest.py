"""Shared fixtures: the repository root, the shipped robots, the CLI binary."""

import os
import pathlib
import subprocess

import pytest

ROOT = pathlib.Path(__file__).resolve().parents[2]
DESIGNS = ROOT / "designs"
ROBOTS = DESIGNS / "robots"
IDEXP = ROOT / "target" / "release" / "idexp"


@pytest.fixture(scope="session")
def ur5():
    import idexp

    return idexp.Robot.load(ROBOTS / "ur5.toml")


@pytest.fixture(scope="session")
def cli():
    """Runs the built command line (`target/release/idexp`) and returns stdout."""
    if not IDEXP.exists():
        pytest.fail(f"{IDEXP} is missing: build it with `cargo build --release` (scripts/python-test.sh does)")

    def run(*args, cwd=ROOT):
        # the BLAS settings of this process (OPENBLAS_CORETYPE picks OpenBLAS's
        # kernels, and the consistent fit's last digits depend on them): the
        # command line must compute with the same kernels as the package
        env = {k: v for k, v in os.environ.items() if k.startswith(("OPENBLAS_", "OMP_"))}
        env.update({"IDEXP_NO_PROGRESS": "1", "PATH": "/usr/bin:/bin"})
        p = subprocess.run([str(IDEXP), *map(str, args)], cwd=cwd, capture_output=True, text=True, env=env)
        assert p.returncode == 0, f"idexp {' '.join(map(str, args))} failed ({p.returncode}): {p.stderr}"
        return p.stdout

    return run
