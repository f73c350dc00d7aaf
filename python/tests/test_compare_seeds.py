"""scripts/compare-seeds.py, the seed-by-seed comparison of two idexp binaries
on one excitation design (the rule for a change that moves local optima):
the same binary twice moves no seed and meets the rule; an "after" binary
that runs every seed s as s + 1 is paired seed by seed (after(s) equals
before(s + 1) exactly); bad input exits 1 with the value named."""

import csv
import os
import subprocess
import sys

import pytest

from conftest import IDEXP, ROBOTS, ROOT

SCRIPT = ROOT / "scripts" / "compare-seeds.py"

# about a second per run
MINI = f"""name = "mini"
robot = "{ROBOTS / 'ur5.toml'}"
seed = 1
[trajectory]
harmonics = 2
frequency = 0.1
q0 = [0.0, -1.5707963267948966, 0.0, -1.5707963267948966, 0.0, 0.0]
[objective]
criterion = "cond"
sample_rate = 5.0
[limits]
position = 0.5
velocity = 1.0
acceleration = 1.0
[collision]
margin = 0.01
[ga]
population = 8
generations = 3
[refine]
algorithm = "slsqp"
starts = 1
max_evals = 20
"""


@pytest.fixture
def mini(tmp_path):
    if not IDEXP.exists():
        pytest.fail(f"{IDEXP} is missing: build it with `cargo build --release`")
    design = tmp_path / "mini.toml"
    design.write_text(MINI)
    return design


def compare(*args):
    env = dict(os.environ, IDEXP_NO_PROGRESS="1")
    return subprocess.run([sys.executable, str(SCRIPT), *map(str, args)], capture_output=True, text=True, env=env)


def rows(out):
    with open(out / "seeds.csv") as f:
        return list(csv.DictReader(f))


def test_the_same_binary_twice_moves_no_seed_and_meets_the_rule(mini, tmp_path):
    out = tmp_path / "same"
    p = compare("--before", IDEXP, "--after", IDEXP, mini, "--seeds", "1-5", "--threads", "1", "--out", out)
    assert p.returncode == 0, p.stderr
    r = rows(out)
    assert [int(x["seed"]) for x in r] == [1, 2, 3, 4, 5]
    assert all(x["before"] == x["after"] and float(x["relative"]) == 0.0 for x in r)
    # the seeds do change the design (else the pairing test below proves nothing)
    assert len({x["before"] for x in r}) == 5
    assert "moved (|relative change| > 0.0001): 0;" in p.stdout
    assert "rule (seeds 1-5 no worse on average): met" in p.stdout


def test_runs_are_paired_by_seed(mini, tmp_path):
    shift = tmp_path / "shift.sh"
    shift.write_text(
        "#!/bin/sh\n# idexp with every --seed s run as s + 1\nargs=''; next=''\n"
        'for a in "$@"; do\n  if [ "$next" = 1 ]; then a=$((a + 1)); next=""; fi\n'
        '  [ "$a" = "--seed" ] && next=1\n  args="$args $a"\ndone\n'
        f"exec {IDEXP} $args\n"
    )
    shift.chmod(0o755)
    out = tmp_path / "shifted"
    p = compare("--before", IDEXP, "--after", shift, mini, "--seeds", "1-3", "--threads", "1", "--out", out)
    assert p.returncode == 0, p.stderr
    r = rows(out)
    assert r[0]["after"] == r[1]["before"] and r[1]["after"] == r[2]["before"]
    for x in r:
        b, a = float(x["before"]), float(x["after"])
        assert float(x["relative"]) == pytest.approx((a - b) / b, rel=1e-12)
    assert "not judged (seeds 1-5 not all run)" in p.stdout
    # each binary's runs are kept, one folder per seed
    assert (out / "before" / "seed-3" / "trajectory.csv").exists()
    assert (out / "after" / "seed-1" / "coefficients.json").exists()


@pytest.mark.parametrize(
    "args, says",
    [
        (["--seeds", "5-1"], "'5-1' is not a seed or a range"),
        (["--seeds", "x"], "'x' is not a seed"),
        (["--threads", "-1"], "--threads -1"),
    ],
)
def test_bad_input_exits_1_and_names_the_value(mini, args, says):
    p = compare("--before", IDEXP, "--after", IDEXP, mini, *args)
    assert p.returncode == 1 and says in p.stderr, (p.returncode, p.stderr)


def test_missing_binary_or_design_exits_1(mini, tmp_path):
    p = compare("--before", tmp_path / "nothing", "--after", IDEXP, mini)
    assert p.returncode == 1 and "nothing: not an executable file" in p.stderr
    p = compare("--before", IDEXP, "--after", IDEXP, tmp_path / "none.toml")
    assert p.returncode == 1 and "none.toml: no such file" in p.stderr


def test_a_failed_run_exits_3_with_its_error(tmp_path):
    bad = tmp_path / "bad.toml"
    bad.write_text('name = "bad"\nrobot = "nowhere.toml"\n')
    p = compare("--before", IDEXP, "--after", IDEXP, bad, "--seeds", "1")
    assert p.returncode == 3 and "nowhere.toml" in p.stderr, (p.returncode, p.stderr)
