//! Every number `idexp excite` and `idexp assess` report (report.txt,
//! report.json, stdout, criterion.json, status.json, coefficients.json) is
//! recomputed here from the files they write, read back from disk: the
//! sample files criterion.json names, its columns (the robot's standard
//! parameters), weights and scaling. Only the regressor Y(q, q̇, q̈) comes from
//! the library; the stacking, weighting, scaling and the SVD (nalgebra's, not
//! the objective's faer eigendecomposition) are done here. Agreement to
//! 10⁻⁹ relative.
#![cfg(feature = "cli")]

use idexp::io::States;
use idexp::robot::{regressor_rows, Robot, Workspace};
use nalgebra::DMatrix;
use serde_json::Value;
use std::path::{Path, PathBuf};
use std::process::Command;

const REL: f64 = 1e-9;

fn root(p: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join(p)
}

/// A shortened excite_ur5 (same robot, limits, collision geometry and
/// criterion; a smaller search), with `extra` objective lines.
fn design(dir: &Path, name: &str, objective: &str) -> PathBuf {
    let text = format!(
        r#"name = "{name}"
robot = "{robot}"
seed = 3
[trajectory]
harmonics = 4
frequency = 0.1
q0 = [0.0, -1.5707963267948966, 0.0, -1.5707963267948966, 0.0, 0.0]
[objective]
{objective}
[limits]
position = 0.8
[collision]
margin = 0.01
floor = true
self = true
[ga]
population = 10
generations = 3
[refine]
starts = 1
max_evals = 15
"#,
        robot = root("designs/robots/ur5.toml").display()
    );
    let p = dir.join(format!("{name}.toml"));
    std::fs::write(&p, text).unwrap();
    p
}

fn run(args: &[&str]) -> String {
    let out = Command::new(env!("CARGO_BIN_EXE_idexp")).args(args).output().unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "idexp {args:?} failed: {stderr}");
    String::from_utf8(out.stdout).unwrap()
}

fn json(p: &Path) -> Value {
    serde_json::from_str(&std::fs::read_to_string(p).unwrap()).unwrap()
}

fn floats(v: &Value) -> Vec<f64> {
    v.as_array()
        .unwrap_or_else(|| panic!("not an array: {v}"))
        .iter()
        .map(|x| x.as_f64().unwrap())
        .collect()
}

fn close(what: &str, got: f64, want: f64) {
    assert!(
        (got - want).abs() <= REL * want.abs().max(1e-300),
        "{what}: reported {want:e}, recomputed {got:e} (relative {:e})",
        (got - want).abs() / want.abs()
    );
}

fn close_all(what: &str, got: &[f64], want: &[f64]) {
    assert_eq!(got.len(), want.len(), "{what}: lengths");
    let scale = want.iter().fold(0.0f64, |m, v| m.max(v.abs()));
    for (i, (g, w)) in got.iter().zip(want).enumerate() {
        assert!((g - w).abs() <= REL * scale.max(1e-300), "{what}[{i}]: reported {w:e}, recomputed {g:e}");
    }
}

/// The number printed after `label` in `text` (up to the next space or comma).
fn printed(text: &str, label: &str) -> f64 {
    let at = text.find(label).unwrap_or_else(|| panic!("`{label}` not in:\n{text}")) + label.len();
    let tok: String = text[at..].trim_start().chars().take_while(|c| !c.is_whitespace() && *c != ',').collect();
    tok.parse().unwrap_or_else(|_| panic!("`{label}` followed by {tok:?}"))
}

/// The `segment` column of a trajectory.csv, one value per data row.
fn segments(path: &Path) -> Vec<i64> {
    let text = std::fs::read_to_string(path).unwrap();
    let mut lines = text.lines();
    let col = lines.next().unwrap().split(',').position(|c| c == "segment").expect("a segment column");
    lines.map(|l| l.split(',').nth(col).unwrap().parse().unwrap()).collect()
}

/// The samples a figure names, read back from `dir` (or the path as given).
fn read_samples(dir: &Path, samples: &Value, n: usize) -> States {
    let file = samples["file"].as_str().unwrap();
    let path = if Path::new(file).is_absolute() { PathBuf::from(file) } else { dir.join(file) };
    let all = States::read(&path, n).unwrap();
    let every = samples["every"].as_u64().unwrap() as usize;
    // `segment`: only the rows whose segment column holds it, then every k-th
    let rows: Vec<usize> = match samples.get("segment").and_then(|v| v.as_i64()) {
        None => (0..all.len()).collect(),
        Some(k) => segments(&path).iter().enumerate().filter(|(_, s)| **s == k).map(|(i, _)| i).collect(),
    };
    let rows: Vec<usize> = rows.into_iter().step_by(every).collect();
    let keep = |v: &Vec<Vec<f64>>| rows.iter().map(|&i| v[i].clone()).collect::<Vec<_>>();
    let s = States {
        t: all.t.as_ref().map(|t| rows.iter().map(|&i| t[i]).collect()),
        q: keep(&all.q),
        qd: keep(&all.qd),
        qdd: keep(&all.qdd),
    };
    assert_eq!(s.len(), samples["count"].as_u64().unwrap() as usize, "{file}: sample count");
    if let Some(t) = &s.t {
        let r = floats(&samples["t_range"]);
        assert_eq!((t[0], t[t.len() - 1]), (r[0], r[1]), "{file}: time range");
        if let Some(rate) = samples["rate_hz"].as_f64() {
            for (i, w) in t.windows(2).enumerate() {
                assert!(((w[1] - w[0]) * rate - 1.0).abs() < 1e-6, "{file}: row {i} not at {rate} Hz");
            }
        }
    }
    s
}

/// The unweighted stacked regressor C (N·n × m) of the named columns.
fn stack(robot: &Robot, rec: &Value, s: &States) -> DMatrix<f64> {
    let n = robot.dof();
    let p = robot.n_params();
    let names = robot.param_names();
    let zero = rec["zero_velocity"].as_f64().unwrap();
    let cols: Vec<usize> = rec["columns"]
        .as_array()
        .unwrap()
        .iter()
        .map(|c| {
            let name = c["parameter"].as_str().unwrap();
            let i = names.iter().position(|x| x == name).unwrap_or_else(|| panic!("no parameter {name}"));
            assert_eq!(c["index"].as_u64().unwrap() as usize, i, "{name}: index");
            i
        })
        .collect();
    let mut ws = Workspace::new(robot);
    let mut y = vec![0.0; n * p];
    let mut c = DMatrix::zeros(s.len() * n, cols.len());
    for i in 0..s.len() {
        let qd: Vec<f64> = s.qd[i].iter().map(|&v| if v.abs() < zero { 0.0 } else { v }).collect();
        regressor_rows(robot, &mut ws, &s.q[i], &qd, &s.qdd[i], &mut y);
        for r in 0..n {
            for (j, &k) in cols.iter().enumerate() {
                c[(i * n + r, j)] = y[r * p + k];
            }
        }
    }
    c
}

/// Nominal value of every column's combination, from the robot's nominal parameters by name.
fn nominal(robot: &Robot, rec: &Value) -> Vec<f64> {
    let names = robot.param_names();
    let theta = robot.nominal_params();
    rec["columns"]
        .as_array()
        .unwrap()
        .iter()
        .map(|c| {
            c["combination"]
                .as_array()
                .unwrap()
                .iter()
                .map(|t| theta[names.iter().position(|x| x == t[0].as_str().unwrap()).unwrap()] * t[1].as_f64().unwrap())
                .sum()
        })
        .collect()
}

struct Recomputed {
    norms: Vec<f64>,
    scale: Vec<f64>,
    sv: Vec<f64>,
    v: DMatrix<f64>,
}

/// W½ C D of a figure, with D from the figure's scaling rule (recomputed, then
/// compared with the written `scale`), and its SVD.
/// W½·C: every joint row divided by its torque noise σ_j.
fn weighted(c: &DMatrix<f64>, noise: &[f64]) -> DMatrix<f64> {
    let mut cw = c.clone();
    for i in 0..cw.nrows() {
        cw.row_mut(i).scale_mut(1.0 / noise[i % noise.len()]);
    }
    cw
}

fn recompute(what: &str, c: &DMatrix<f64>, noise: &[f64], fig: &Value, nominal: &[f64]) -> Recomputed {
    let mut cw = weighted(c, noise);
    let norms: Vec<f64> = cw.column_iter().map(|c| c.norm()).collect();
    close_all(&format!("{what}: column norms"), &norms, &floats(&fig["column_norms"]));
    let maxn = norms.iter().fold(0.0f64, |m, v| m.max(*v));
    let scale: Vec<f64> = match fig["scaling"].as_str().unwrap() {
        "unit_column" => norms.iter().map(|&v| if v > 1e-14 * maxn { 1.0 / v } else { 0.0 }).collect(),
        "nominal" => {
            let mx = nominal.iter().fold(0.0f64, |m, v| m.max(v.abs()));
            nominal.iter().map(|v| v.abs().max(1e-3 * mx)).collect()
        }
        "none" => vec![1.0; norms.len()],
        s => panic!("unknown scaling {s}"),
    };
    close_all(&format!("{what}: scale"), &scale, &floats(&fig["scale"]));
    for (j, f) in scale.iter().enumerate() {
        cw.column_mut(j).scale_mut(*f);
    }
    let svd = cw.svd(false, true);
    let mut idx: Vec<usize> = (0..svd.singular_values.len()).collect();
    idx.sort_by(|&a, &b| svd.singular_values[b].total_cmp(&svd.singular_values[a]));
    let sv: Vec<f64> = idx.iter().map(|&i| svd.singular_values[i]).collect();
    let vt = svd.v_t.unwrap();
    let v = DMatrix::from_fn(sv.len(), sv.len(), |a, k| vt[(idx[k], a)]);
    close_all(&format!("{what}: singular values"), &sv, &floats(&fig["singular_values"]));
    let cond = sv[0] / sv[sv.len() - 1];
    close(&format!("{what}: cond"), cond, fig["cond"].as_f64().unwrap());
    Recomputed { norms, scale, sv, v }
}

/// The design's criterion J from the singular values (the cap only matters
/// for rank-deficient designs, which these are not).
fn criterion(kind: &str, sv: &[f64]) -> f64 {
    match kind {
        "cond" => sv[0] / sv[sv.len() - 1],
        "log_det" => -2.0 * sv.iter().map(|s| s.ln()).sum::<f64>(),
        "inv_sigma_min" => 1.0 / sv[sv.len() - 1],
        k => panic!("criterion {k}"),
    }
}

/// The identifiability figures of report.json from the same matrices.
fn check_identifiability(what: &str, ident: &Value, c: &DMatrix<f64>, r: &Recomputed, nominal: &[f64]) {
    let m = r.sv.len();
    let n = ident["noise"].as_array().unwrap().len();
    let ns = c.nrows() / n;
    assert_eq!(ident["samples"].as_u64().unwrap() as usize, ns, "{what}: samples");
    close_all(&format!("{what}: identifiability.singular_values"), &r.sv, &floats(&ident["singular_values"]));
    close(&format!("{what}: identifiability.cond"), r.sv[0] / r.sv[m - 1], ident["cond"].as_f64().unwrap());
    close_all(&format!("{what}: identifiability.column_norms"), &r.norms, &floats(&ident["column_norms"]));
    let sens: Vec<f64> = c.column_iter().map(|col| col.iter().map(|v| v.abs()).sum::<f64>() / (ns * n) as f64).collect();
    close_all(&format!("{what}: sensitivity"), &sens, &floats(&ident["sensitivity"]));
    close_all(&format!("{what}: nominal"), nominal, &floats(&ident["nominal"]));
    // var(θ̂) = (C_wᵀC_w)⁻¹ = D V Σ⁻² Vᵀ D with D the unit-column factors
    let sd: Vec<f64> = (0..m)
        .map(|i| r.scale[i] * (0..m).map(|k| (r.v[(i, k)] / r.sv[k]).powi(2)).sum::<f64>().sqrt())
        .collect();
    let got = floats(&ident["std_dev"]);
    for i in 0..m {
        close(&format!("{what}: std_dev[{i}]"), sd[i], got[i]);
        if nominal[i] != 0.0 {
            let rel = ident["rel_std_dev"][i].as_f64().unwrap();
            close(&format!("{what}: rel_std_dev[{i}]"), sd[i] / nominal[i].abs(), rel);
        }
    }
}

/// Runs a design through `idexp excite` and recomputes every figure.
fn excite_and_replay(name: &str, objective: &str) {
    let tmp = tempfile::tempdir().unwrap();
    let file = design(tmp.path(), name, objective);
    let dir = tmp.path().join("out");
    let stdout = run(&["excite", file.to_str().unwrap(), "--out", dir.to_str().unwrap()]);
    let robot = idexp::robot::load(&root("designs/robots/ur5.toml")).unwrap();
    let n = robot.dof();
    let rec = json(&dir.join("criterion.json"));
    let report = json(&dir.join("report.json"));
    let text = std::fs::read_to_string(dir.join("report.txt")).unwrap();
    let noise = floats(&rec["noise"]);
    let nom = nominal(&robot, &rec);
    let names: Vec<String> = rec["columns"]
        .as_array()
        .unwrap()
        .iter()
        .map(|c| c["name"].as_str().unwrap().to_string())
        .collect();
    assert_eq!(report["identifiability"]["names"], serde_json::json!(names));
    let figs = rec["figures"].as_array().unwrap();
    assert_eq!(figs.len(), 4);

    // 1. the criterion on its own samples
    let f0 = &figs[0];
    assert_eq!(f0["samples"]["file"], "criterion_samples.csv");
    let s0 = read_samples(&dir, &f0["samples"], n);
    let c0 = stack(&robot, &rec, &s0);
    let r0 = recompute("criterion", &c0, &noise, f0, &nom);
    let kind = f0["criterion"].as_str().unwrap();
    let j = criterion(kind, &r0.sv);
    for (what, v) in [
        ("criterion.json value", &f0["value"]),
        ("report.json result.criterion", &report["result"]["criterion"]),
        ("report.json result.spectrum.criterion", &report["result"]["spectrum"]["criterion"]),
        ("coefficients.json criterion_value", &json(&dir.join("coefficients.json"))["criterion_value"]),
    ] {
        close(what, j, v.as_f64().unwrap());
    }
    let cond = r0.sv[0] / r0.sv[r0.sv.len() - 1];
    for (what, v) in [
        ("report.json result.spectrum.cond", &report["result"]["spectrum"]["cond"]),
        ("coefficients.json cond", &json(&dir.join("coefficients.json"))["cond"]),
        ("status.json summary.cond", &json(&dir.join("status.json"))["summary"]["cond"]),
    ] {
        close(what, cond, v.as_f64().unwrap());
    }
    close_all(
        "report.json result.spectrum.singular_values",
        &r0.sv,
        &floats(&report["result"]["spectrum"]["singular_values"]),
    );
    // the printed figures (4 decimals)
    assert!(
        (printed(&text, "criterion value:") - j).abs() <= 5e-5 * j.abs().max(1.0),
        "report.txt criterion value"
    );
    assert!((printed(&text, "\ncondition number:") - cond).abs() <= 5e-5, "report.txt condition number");
    assert!(
        (printed(&stdout, "condition number") - cond).abs() <= 5e-5,
        "stdout condition number:\n{stdout}"
    );
    // the samples are one period on the objective's grid, and the times of
    // every k-th row of periodic.csv (the states agree to rounding)
    let design = json(&dir.join("design.json"));
    let rate = design["objective"]["sample_rate"].as_f64().unwrap();
    let period = 1.0 / design["trajectory"]["frequency"].as_f64().unwrap();
    let t0 = s0.t.as_ref().unwrap();
    assert_eq!(t0.len(), (period * rate).round() as usize);
    for (i, t) in t0.iter().enumerate() {
        assert_eq!(*t, i as f64 / rate, "criterion sample time {i}");
    }
    let every = (design["trajectory"]["controller_rate"].as_f64().unwrap() / rate).round() as usize;
    let periodic = States::read(&dir.join("periodic.csv"), n).unwrap();
    for i in 0..s0.len() {
        let k = i * every;
        assert_eq!(periodic.t.as_ref().unwrap()[k], t0[i]);
        for jn in 0..n {
            assert!((periodic.q[k][jn] - s0.q[i][jn]).abs() < 1e-12, "periodic.csv row {k} vs criterion sample {i}");
        }
    }
    // the report names these samples and the columns by their standard parameters
    assert!(text.contains(f0["samples"]["description"].as_str().unwrap()), "{text}");
    let params: Vec<&str> = rec["columns"].as_array().unwrap().iter().map(|c| c["parameter"].as_str().unwrap()).collect();
    assert!(text.contains(&params.join(" ")), "{text}");

    // 2. identifiability on the same samples
    let f1 = &figs[1];
    assert_eq!(f1["samples"], f0["samples"]);
    assert_eq!(f1["scaling"], "unit_column");
    let r1 = recompute("identifiability", &c0, &noise, f1, &nom);
    check_identifiability("design grid", &report["identifiability"], &c0, &r1, &nom);
    assert!(
        (printed(&text, "condition number (unit columns):") - r1.sv[0] / r1.sv[r1.sv.len() - 1]).abs() <= 5e-5,
        "report.txt identifiability cond"
    );

    // 3. the delivered trajectory, every row of trajectory.csv
    let f2 = &figs[2];
    assert_eq!(f2["samples"]["file"], "trajectory.csv");
    assert_eq!(f2["samples"]["every"], 1);
    let s2 = read_samples(&dir, &f2["samples"], n);
    let rows = std::fs::read_to_string(dir.join("trajectory.csv")).unwrap().lines().count() - 1;
    assert_eq!(s2.len(), rows, "every row of trajectory.csv");
    let c2 = stack(&robot, &rec, &s2);
    let r2 = recompute("delivered", &c2, &noise, f2, &nom);
    check_identifiability("delivered", &report["delivered_identifiability"], &c2, &r2, &nom);
    let dcond = r2.sv[0] / r2.sv[r2.sv.len() - 1];
    assert!((printed(&text, "condition number of the delivered trajectory:") - dcond).abs() <= 5e-5);
    assert!((printed(&stdout, "delivered trajectory: condition number") - dcond).abs() <= 5e-5, "{stdout}");
    // the two are different figures (different samples): both labelled
    assert!((dcond - cond).abs() > 1e-6 || kind != "cond");

    // 4. the criterion's samples read from trajectory.csv: segment 1 (period
    // 1, after the lead-in), every k-th row; the same figure as 2 to rounding
    let f3 = &figs[3];
    assert_eq!(
        (&f3["samples"]["file"], &f3["samples"]["segment"], &f3["samples"]["every"]),
        (&"trajectory.csv".into(), &1.into(), &every.into())
    );
    let s3 = read_samples(&dir, &f3["samples"], n);
    assert_eq!(s3.len(), s0.len());
    let lead_in = s3.t.as_ref().unwrap()[0];
    assert!(lead_in > 0.0, "period 1 starts after the lead-in");
    for i in 0..s0.len() {
        assert!(
            (s3.t.as_ref().unwrap()[i] - lead_in - t0[i]).abs() < 1e-9,
            "trajectory.csv period 1 sample {i}: the criterion's phase"
        );
        for jn in 0..n {
            assert!(
                (s3.q[i][jn] - s0.q[i][jn]).abs() < 1e-9,
                "trajectory.csv period 1 sample {i} joint {jn}: {} vs criterion sample {}",
                s3.q[i][jn],
                s0.q[i][jn]
            );
        }
    }
    let c3 = stack(&robot, &rec, &s3);
    let r3 = recompute("period 1 of trajectory.csv", &c3, &noise, f3, &nom);
    check_identifiability("period 1", &report["period_identifiability"], &c3, &r3, &nom);
    let pcond = r3.sv[0] / r3.sv[r3.sv.len() - 1];
    let icond = r1.sv[0] / r1.sv[r1.sv.len() - 1];
    assert!(
        (pcond - icond).abs() <= 1e-8 * icond,
        "period 1 of trajectory.csv {pcond} vs the criterion's samples {icond}"
    );
    let line = text
        .lines()
        .find(|l| l.contains("the same samples in trajectory.csv"))
        .expect("report.txt names the period in trajectory.csv");
    assert!((printed(line, "condition number") - pcond).abs() <= 5e-5, "{line}");
    assert!(line.contains(&format!("--segment 1 --every {every}")), "{line}");
    // the reading this guards against: trajectory.csv's first period-long
    // stretch from t = 0 is the lead-in from rest and part of period 1, not
    // a period; its cond is another number
    let all = States::read(&dir.join("trajectory.csv"), n).unwrap();
    let first = States {
        t: None,
        q: (0..s0.len()).map(|i| all.q[i * every].clone()).collect(),
        qd: (0..s0.len()).map(|i| all.qd[i * every].clone()).collect(),
        qdd: (0..s0.len()).map(|i| all.qdd[i * every].clone()).collect(),
    };
    let cf = stack(&robot, &rec, &first);
    let rf = recompute_unchecked(&cf, &noise);
    assert!(
        (rf - icond).abs() > 1e-3 * icond,
        "first {period} s of trajectory.csv: {rf} vs one period {icond}"
    );
}

/// cond of W½·C with unit columns (no reported figure to compare with).
fn recompute_unchecked(c: &DMatrix<f64>, noise: &[f64]) -> f64 {
    let mut w = weighted(c, noise);
    for mut col in w.column_iter_mut() {
        let norm = col.norm();
        if norm > 0.0 {
            col /= norm;
        }
    }
    let sv = w.singular_values();
    sv.max() / sv.min()
}

#[test]
fn every_excite_figure_is_recomputed_from_the_written_files() {
    excite_and_replay("replay_ur5", "criterion = \"cond\"\nscaling = \"unit_column\"\nsample_rate = 10.0");
}

#[test]
fn nominal_scaling_weights_and_log_det_are_recomputed_too() {
    excite_and_replay(
        "replay_weighted",
        "criterion = \"log_det\"\nscaling = \"nominal\"\nsample_rate = 8.0\nnoise = [2.0, 2.0, 1.0, 0.5, 0.5, 0.25]",
    );
}

#[test]
fn assess_figures_are_recomputed_from_the_trajectory_file() {
    let tmp = tempfile::tempdir().unwrap();
    let file = design(tmp.path(), "assess_src", "sample_rate = 10.0");
    let dir = tmp.path().join("out");
    run(&["excite", file.to_str().unwrap(), "--out", dir.to_str().unwrap()]);
    let traj = dir.join("trajectory.csv");
    let adir = tmp.path().join("assess");
    let robot_file = root("designs/robots/ur5.toml");
    let stdout = run(&[
        "assess",
        robot_file.to_str().unwrap(),
        traj.to_str().unwrap(),
        "--every",
        "7",
        "--noise",
        "1.5,1.5,1,0.3,0.3,0.3",
        "--out",
        adir.to_str().unwrap(),
    ]);
    let robot = idexp::robot::load(&robot_file).unwrap();
    let rec = json(&adir.join("criterion.json"));
    let report = json(&adir.join("report.json"));
    let fig = &rec["figures"][0];
    assert_eq!(fig["samples"]["file"], traj.display().to_string());
    assert_eq!(fig["samples"]["every"], 7);
    let s = read_samples(&adir, &fig["samples"], robot.dof());
    let all_rows = std::fs::read_to_string(&traj).unwrap().lines().count() - 1;
    assert_eq!(s.len(), all_rows.div_ceil(7));
    let noise = floats(&rec["noise"]);
    assert_eq!(noise, vec![1.5, 1.5, 1.0, 0.3, 0.3, 0.3]);
    let nom = nominal(&robot, &rec);
    let c = stack(&robot, &rec, &s);
    let r = recompute("assess", &c, &noise, fig, &nom);
    check_identifiability("assess", &report, &c, &r, &nom);
    let cond = r.sv[0] / r.sv[r.sv.len() - 1];
    assert!((printed(&stdout, "condition number (unit columns):") - cond).abs() <= 5e-5, "{stdout}");
    // the text names the samples, the columns and the weighting
    let desc = fig["samples"]["description"].as_str().unwrap();
    assert!(
        desc.contains("every 7th data row") && desc.contains(&format!("{} rows", s.len())) && desc.contains("at 142.857142857 Hz"),
        "{desc}"
    );
    assert!(stdout.contains(&format!("samples used: {desc}")), "{stdout}");
    let params: Vec<&str> = rec["columns"].as_array().unwrap().iter().map(|c| c["parameter"].as_str().unwrap()).collect();
    assert!(stdout.contains(&params.join(" ")), "{stdout}");
    assert!(
        stdout.contains("divided by its torque noise σ_j") && stdout.contains("divided by its norm"),
        "{stdout}"
    );
}
