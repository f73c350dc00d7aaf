"""positions (plan and certificate) and the multistart FRF fit, against the
command line's files."""

import json

import numpy as np
import pytest

import idexp
from conftest import DESIGNS, ROBOTS


def untimed(v):
    """A report without its wall-clock entries (`*time*`, `*seconds*`)."""
    if isinstance(v, dict):
        return {k: untimed(x) for k, x in v.items() if "time" not in k and "seconds" not in k}
    if isinstance(v, list):
        return [untimed(x) for x in v]
    return v


def test_positions_equal_to_cli(cli, tmp_path):
    design = DESIGNS / "positions_file_a.toml"
    r = idexp.positions(design)
    out = tmp_path / "cli"
    cli("positions", design, "--out", out)
    rep = json.loads((out / "report.json").read_text())
    n_c = r.n_candidates
    assert r.weights.shape == (n_c,) == r.costs.shape and r.q.shape[0] == n_c == len(r.ranks)
    assert len(r.param_names) > 0
    assert r.weights.sum() == pytest.approx(1.0, abs=1e-6) and np.all(r.weights >= -1e-9)
    assert sum(r.plan) == 10  # experiments = 10
    cert = r.certificate
    assert cert["gap_bound"] >= 0 and 0 < cert["efficiency_bound"] <= 1 + 1e-12
    w = r.write(tmp_path / "py")
    assert untimed(json.loads((w / "report.json").read_text())) == untimed(rep)
    assert "Kiefer" in r.text() or "certificate" in r.text().lower()
    with pytest.raises(OSError, match="none.toml"):
        idexp.positions(tmp_path / "none.toml")


def small_elastic(tmp_path):
    """designs/elastic_industrial6.toml reduced to 2 positions, a narrower band, few starts."""
    s = (DESIGNS / "elastic_industrial6.toml").read_text()
    s = s.replace("robots/industrial6.toml", str(ROBOTS / "industrial6.toml"))
    i = s.find("positions = [\n") + len("positions = [\n")
    j = i + s[i:].find("]\n\n")
    rows = s[i:j].splitlines()[:2]
    s = s[:i] + "\n".join(rows) + "\n" + s[j:]
    s = s.replace("band = [2.0, 150.0]", "band = [2.0, 61.0]").replace("band = [3.0, 150.0]", "band = [3.0, 61.0]")
    s = s.replace("starts = 100", "starts = 4").replace("max_iter = 200", "max_iter = 60")
    p = tmp_path / "d.toml"
    p.write_text(s)
    return p


def test_fit_chain_equal_to_cli(cli, tmp_path):
    d = small_elastic(tmp_path)
    x = tmp_path / "x"
    ms = idexp.multisine(d, out=x)
    assert (x / "multisine" / "multisine.json").exists() and "folder" in ms
    data = idexp.frf(d, out=x)
    assert data.name == "frf.json" and data.exists()
    py = idexp.fit(d, starts=4, data=data, out=tmp_path / "py")
    cl = tmp_path / "cl"
    cli("fit", d, "--starts", 4, "--data", data, "--out", cl)
    log_cli = next(cl.rglob("starts.jsonl")).read_text()
    assert py.log.read_text() == log_cli
    assert len(py.records) == 4 and py.report is not None
    assert py.best_index is not None and py.report["best_index"] == py.best_index
    # one shard of two: half the starts, no report
    sh = idexp.fit(d, starts=4, data=data, shard="1/2", out=tmp_path / "sh")
    assert sh.report is None and len(sh.records) == 2
    with pytest.raises(idexp.IdexpError, match="shard"):
        idexp.fit(d, starts=4, data=data, shard="2/2", out=tmp_path / "bad")
    with pytest.raises(ValueError, match="starts"):
        idexp.fit(d, starts=0)
