"""Every condition number `idexp excite` and `idexp assess` report, recomputed
from the files they write with Pinocchio's joint torque regressor and numpy
only: the samples named in criterion.json, its columns (the robot's standard
parameter names; friction columns built here by hand), its noise weights and
its scaling rule. Nothing of idexp is imported for the computation; the
command line only produces the files."""

import json
import re

import numpy as np
import pytest

from conftest import DESIGNS, ROBOTS

pin = pytest.importorskip("pinocchio")

REL = 1e-8

# Pinocchio's dynamic parameters per body: m, mx, my, mz, Ixx, Ixy, Iyy, Ixz, Iyz, Izz
# (inertia about the joint frame origin), as idexp's XX..M of the same link
BODY = {"M": 0, "MX": 1, "MY": 2, "MZ": 3, "XX": 4, "XY": 5, "YY": 6, "XZ": 7, "YZ": 8, "ZZ": 9}


def read_samples(folder, samples, n):
    path = samples["file"]
    path = path if path.startswith("/") else str(folder / path)
    a = np.genfromtxt(path, delimiter=",", names=True)
    if "segment" in samples:
        # only the rows of that segment (trajectory.csv: 0 lead-in, k period k, -1 lead-out)
        a = a[a["segment"] == samples["segment"]]
    a = a[:: samples["every"]]
    assert len(a) == samples["count"]
    t = a["t"]
    assert (t[0], t[-1]) == tuple(samples["t_range"])
    if samples["rate_hz"] is not None:
        np.testing.assert_allclose(np.diff(t) * samples["rate_hz"], 1.0, rtol=0, atol=1e-6)
    cols = lambda p: np.stack([a[f"{p}{j + 1}"] for j in range(n)], axis=1)
    return cols("q"), cols("qd"), cols("qdd")


def stack(model, data, rec, q, qd, qdd):
    """C (N·n × m): Pinocchio's regressor column of each named parameter,
    Coulomb sign(q̇_j) and viscous q̇_j on joint j's row."""
    n = model.nv
    qd = np.where(np.abs(qd) < rec["zero_velocity"], 0.0, qd)
    picks = []
    for c in rec["columns"]:
        kind, j = re.fullmatch(r"([A-Za-z]+)(\d+)", c["parameter"]).groups()
        picks.append((kind, int(j) - 1))
    out = np.zeros((len(q) * n, len(picks)))
    for i in range(len(q)):
        y = pin.computeJointTorqueRegressor(model, data, q[i], qd[i], qdd[i])
        block = out[i * n:(i + 1) * n]
        for k, (kind, j) in enumerate(picks):
            if kind == "Fc":
                block[j, k] = np.sign(qd[i, j])
            elif kind == "Fv":
                block[j, k] = qd[i, j]
            else:
                block[:, k] = y[:, 10 * j + BODY[kind]]
    return out


def nominal(model, rec):
    """Each column's combination of standard parameters at the URDF's values
    (friction from the robot file is not in the URDF: taken as reported)."""
    pi = np.concatenate([model.inertias[b].toDynamicParameters() for b in range(1, model.njoints)])
    vals = []
    for c in rec["columns"]:
        if c["parameter"][:2] in ("Fc", "Fv"):
            vals.append(c["nominal"])
            continue
        v = 0.0
        for name, k in c["combination"]:
            kind, j = re.fullmatch(r"([A-Za-z]+)(\d+)", name).groups()
            v += k * pi[10 * (int(j) - 1) + BODY[kind]]
        vals.append(v)
    np.testing.assert_allclose(vals, [c["nominal"] for c in rec["columns"]], rtol=1e-9, atol=1e-12)
    return np.array(vals)


def replay(model, data, folder, rec, fig):
    q, qd, qdd = read_samples(folder, fig["samples"], model.nv)
    c = stack(model, data, rec, q, qd, qdd)
    c = c / np.tile(np.array(rec["noise"]), len(q))[:, None]
    norms = np.linalg.norm(c, axis=0)
    np.testing.assert_allclose(norms, fig["column_norms"], rtol=REL)
    if fig["scaling"] == "unit_column":
        scale = 1.0 / norms
    elif fig["scaling"] == "nominal":
        nom = np.abs(nominal(model, rec))
        scale = np.maximum(nom, 1e-3 * nom.max())
    else:
        scale = np.ones(len(norms))
    np.testing.assert_allclose(scale, fig["scale"], rtol=REL)
    s = np.linalg.svd(c * scale, compute_uv=False)
    np.testing.assert_allclose(s, fig["singular_values"], rtol=REL, atol=REL * s[0])
    cond = s[0] / s[-1]
    assert cond == pytest.approx(fig["cond"], rel=REL)
    return cond, s


def model_for(rec):
    model = pin.buildModelFromUrdf(str(ROBOTS / "ur5.urdf"))
    model.gravity.linear = np.array(rec["gravity"])
    assert list(model.names)[1:] == rec["joints"]
    return model, model.createData()


def test_excite_ur5_criterion_is_recomputed_with_pinocchio(cli, tmp_path):
    out = tmp_path / "ur5"
    stdout = cli("excite", DESIGNS / "excite_ur5.toml", "--out", out)
    rec = json.loads((out / "criterion.json").read_text())
    report = json.loads((out / "report.json").read_text())
    text = (out / "report.txt").read_text()
    model, data = model_for(rec)
    grid, ident, delivered, period = rec["figures"]

    # the criterion: one period, 100 samples at 10 Hz (criterion_samples.csv)
    assert grid["samples"]["file"] == "criterion_samples.csv"
    assert grid["samples"]["count"] == 100 and grid["samples"]["rate_hz"] == 10.0
    cond, s = replay(model, data, out, rec, grid)
    assert cond == pytest.approx(report["result"]["criterion"], rel=REL)
    assert cond == pytest.approx(report["result"]["spectrum"]["cond"], rel=REL)
    assert f"condition number: {cond:.4f}" in text
    assert f"condition number {cond:.4f}" in stdout
    # the same times as every 100th row of periodic.csv (1 kHz)
    per = np.genfromtxt(out / "periodic.csv", delimiter=",", names=True)
    crit = np.genfromtxt(out / "criterion_samples.csv", delimiter=",", names=True)
    np.testing.assert_array_equal(per["t"][::100], crit["t"])
    np.testing.assert_allclose(per["q1"][::100], crit["q1"], rtol=0, atol=1e-12)

    # identifiability on the same samples
    assert ident["samples"] == grid["samples"]
    icond, _ = replay(model, data, out, rec, ident)
    assert icond == pytest.approx(report["identifiability"]["cond"], rel=REL)

    # the delivered trajectory: every row of trajectory.csv at 1 kHz, lead-in and lead-out included
    assert delivered["samples"]["file"] == "trajectory.csv" and delivered["samples"]["every"] == 1
    rows = sum(1 for _ in open(out / "trajectory.csv")) - 1
    assert delivered["samples"]["count"] == rows and delivered["samples"]["rate_hz"] == 1000.0
    dcond, _ = replay(model, data, out, rec, delivered)
    assert dcond == pytest.approx(report["delivered_identifiability"]["cond"], rel=REL)
    assert f"condition number of the delivered trajectory: {dcond:.4f}" in text
    assert f"delivered trajectory: condition number {dcond:.4f}" in stdout
    # two figures, two sets of samples: not the same number
    assert abs(dcond - cond) > 1e-3

    # the criterion's samples read from trajectory.csv: segment 1 (period 1,
    # which starts after the lead-in), every 100th row: the same number
    assert period["samples"]["file"] == "trajectory.csv"
    assert (period["samples"]["segment"], period["samples"]["every"]) == (1, 100)
    pcond, _ = replay(model, data, out, rec, period)
    assert pcond == pytest.approx(cond, rel=1e-8)
    assert "--segment 1 --every 100" in text
    # and the reading that gives another number: the first 10 s of
    # trajectory.csv from t = 0 (the lead-in from rest, then most of period 1)
    a = np.genfromtxt(out / "trajectory.csv", delimiter=",", names=True)
    assert a["segment"][0] == 0 and a["t"][0] == 0.0
    q, qd, qdd = (np.stack([a[f"{p}{j + 1}"][:10000:100] for j in range(model.nv)], axis=1) for p in ("q", "qd", "qdd"))
    c = stack(model, data, rec, q, qd, qdd)
    c = c / np.tile(np.array(rec["noise"]), len(q))[:, None]
    s = np.linalg.svd(c / np.linalg.norm(c, axis=0), compute_uv=False)
    assert abs(s[0] / s[-1] - cond) > 1e-3 * cond


def test_assess_cond_is_recomputed_with_pinocchio(cli, tmp_path):
    src = tmp_path / "design"
    cli("excite", DESIGNS / "excite_ur5.toml", "--out", src)
    out = tmp_path / "assess"
    stdout = cli(
        "assess", ROBOTS / "ur5.toml", src / "trajectory.csv", "--every", "10", "--noise", "2,2,1,0.5,0.5,0.5", "--out", out
    )
    rec = json.loads((out / "criterion.json").read_text())
    report = json.loads((out / "report.json").read_text())
    model, data = model_for(rec)
    (fig,) = rec["figures"]
    assert fig["samples"]["every"] == 10 and fig["samples"]["rate_hz"] == 100.0
    assert rec["noise"] == [2, 2, 1, 0.5, 0.5, 0.5]
    cond, _ = replay(model, data, out, rec, fig)
    assert cond == pytest.approx(report["cond"], rel=REL)
    assert f"condition number (unit columns): {cond:.4f}" in stdout
    assert f"samples used: {fig['samples']['description']}" in stdout


def test_payload_excite_criterion_is_recomputed_with_pinocchio(cli, tmp_path):
    """`idexp payload excite`: the criterion on the payload link's ten columns
    (wrist 3 of the UR5) recomputed with Pinocchio's regressor, on the
    criterion's samples and on period 1 of trajectory.csv; `idexp.excite` on
    the same design finds the same optimum."""
    import idexp

    design = DESIGNS / "payload_ur5_excite.toml"
    out = tmp_path / "payload"
    stdout = cli("payload", "excite", design, "--out", out)
    rec = json.loads((out / "criterion.json").read_text())
    report = json.loads((out / "report.json").read_text())
    assert [c["parameter"] for c in rec["columns"]] == [
        f"{k}6" for k in ("XX", "XY", "XZ", "YY", "YZ", "ZZ", "MX", "MY", "MZ", "M")
    ]
    model, data = model_for(rec)
    grid, ident, delivered, period = rec["figures"]
    cond, _ = replay(model, data, out, rec, grid)
    assert cond == pytest.approx(report["result"]["criterion"], rel=REL)
    assert f"condition number {cond:.4f}" in stdout
    pcond, _ = replay(model, data, out, rec, period)
    assert pcond == pytest.approx(cond, rel=1e-8)
    dcond, _ = replay(model, data, out, rec, delivered)
    assert dcond == pytest.approx(report["delivered_identifiability"]["cond"], rel=REL)
    r = idexp.excite(str(design))
    assert r.cond == pytest.approx(cond, rel=1e-12)
