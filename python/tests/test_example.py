"""The notebook-style example runs as a script and writes its figure and folders."""

import subprocess
import sys

from conftest import ROOT


def test_identify_ur5_example(tmp_path):
    p = subprocess.run([sys.executable, str(ROOT / "examples/python/identify_ur5.py"), "--out", str(tmp_path), "--repetitions", "3"],
                       cwd=ROOT, capture_output=True, text=True, timeout=600)
    assert p.returncode == 0, p.stderr
    png = tmp_path / "torques.png"
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and png.stat().st_size > 20_000
    for f in ("excite/coefficients.json", "run/rep_003.csv", "identify/estimate.json"):
        assert (tmp_path / f).exists(), f
    assert "base parameters" in p.stdout
