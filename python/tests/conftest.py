"""Shared fixtures: the repository root, the shipped robots, the CLI binary."""

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
        p = subprocess.run([str(IDEXP), *map(str, args)], cwd=cwd, capture_output=True, text=True,
                           env={"IDEXP_NO_PROGRESS": "1", "PATH": "/usr/bin:/bin"})
        assert p.returncode == 0, f"idexp {' '.join(map(str, args))} failed ({p.returncode}): {p.stderr}"
        return p.stdout

    return run
