//! Physically consistent identification, averaged runs, motor coordinates and
//! the exported models.

mod ident_util;

use idexp::robot::{self, inverse_dynamics, Workspace};
use nalgebra::{Matrix4, SymmetricEigen};
use rand::{RngExt, SeedableRng};
use std::path::{Path, PathBuf};
use std::process::Command;

fn exe() -> Command {
    let mut c = Command::new(env!("CARGO_BIN_EXE_idexp"));
    c.env("IDEXP_NO_PROGRESS", "1");
    c
}

/// Simulates the RPR arm with drives: `reps` repetitions, seed `seed`.
fn simulate(dir: &Path, name: &str, reps: usize, seed: u64, amplitude: f64) -> PathBuf {
    let design = dir.join(format!("{name}.toml"));
    std::fs::write(
        &design,
        format!(
            "robot = \"{}\"\nrate = 500.0\ndecimate = 5\nrepetitions = {reps}\nseed = {seed}\n[truth]\nperturbation = 0.1\nseed = 7\n[noise]\ntorque = 0.05\n[reference]\nkind = \"random_fourier\"\nfrequency = 0.2\namplitude = {amplitude}\nseed = {seed}\n",
            ident_util::root("tests/data/ident/rpr_drives.toml").display()
        ),
    )
    .unwrap();
    let out = dir.join(name);
    let o = exe()
        .args(["simulate", design.to_str().unwrap(), "--out", out.to_str().unwrap()])
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    out
}

fn identify(args: &[&str]) -> (std::process::Output, Option<serde_json::Value>) {
    let o = exe().arg("identify").args(args).arg("--json").output().unwrap();
    let v = serde_json::from_slice(&o.stdout).ok();
    (o, v)
}

fn f64s(v: &serde_json::Value) -> Vec<f64> {
    v.as_array().unwrap().iter().map(|x| x.as_f64().unwrap()).collect()
}

/// Independent check: eigenvalues of every link's pseudo-inertia from the standard parameters.
fn min_eigs(std: &[f64], robot: &idexp::robot::Robot) -> Vec<f64> {
    (0..robot.dof())
        .map(|i| {
            let o = robot.link_param_offset(i);
            let p = &std[o..o + 10];
            let (xx, xy, xz, yy, yz, zz) = (p[0], p[1], p[2], p[3], p[4], p[5]);
            let s = 0.5 * (xx + yy + zz);
            let j = Matrix4::new(s - xx, -xy, -xz, p[6], -xy, s - yy, -yz, p[7], -xz, -yz, s - zz, p[8], p[6], p[7], p[8], p[9]);
            SymmetricEigen::new(j).eigenvalues.min()
        })
        .collect()
}

#[test]
fn consistent_fit_reproduces_wls_on_consistent_data_and_repairs_a_poor_one() {
    let d = tempfile::tempdir().unwrap();
    let robot_file = ident_util::root("tests/data/ident/rpr_drives.toml");
    let robot = robot::load(&robot_file).unwrap();
    let good = simulate(d.path(), "good", 8, 3, 0.6);
    let val = simulate(d.path(), "val", 8, 4, 0.6);
    let margin = 1e-6;
    let out = d.path().join("id");
    let (o, v) = identify(&[
        robot_file.to_str().unwrap(),
        good.to_str().unwrap(),
        "--validate",
        val.to_str().unwrap(),
        "--consistent",
        "--margin",
        &margin.to_string(),
        "--out",
        out.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let v = v.unwrap();
    let c = &v["consistent"];
    assert_eq!(c["status"], "ok");
    let eig = min_eigs(&f64s(&c["standard"]), &robot);
    assert!(eig.iter().all(|&e| e >= margin * (1.0 - 1e-6)), "{eig:?}");
    // same torques as WLS within the noise: e_j on every sample within 1 % of WLS's
    let (ew, ec) = (f64s(&v["experiments"][0]["errors_all"]["e"]), f64s(&c["experiments"][0]["e"]));
    for j in 0..ew.len() {
        assert!((ec[j] - ew[j]).abs() <= 0.01 * ew[j], "joint {j}: {} vs {}", ec[j], ew[j]);
    }
    // K θ equals the reported base parameters
    let k: Vec<Vec<f64>> = v["base_k"].as_array().unwrap().iter().map(f64s).collect();
    let std = f64s(&c["standard"]);
    let base = f64s(&c["base"]);
    for (i, row) in k.iter().enumerate() {
        let kb: f64 = row.iter().zip(&std).map(|(a, b)| a * b).sum();
        assert!((kb - base[i]).abs() <= 1e-9 * base[i].abs().max(1.0));
    }

    // few repetitions, short small motion: a poorly exciting run
    let poor = simulate(d.path(), "poor", 2, 5, 0.05);
    let out2 = d.path().join("id2");
    let (o, v) = identify(&[
        robot_file.to_str().unwrap(),
        poor.to_str().unwrap(),
        "--validate",
        val.to_str().unwrap(),
        "--weights",
        "joint",
        "--consistent",
        "--margin",
        &margin.to_string(),
        "--out",
        out2.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let v = v.unwrap();
    // the poor run makes WLS physically implausible (a negative rotor inertia here)
    assert!(
        !v["implausible"].as_array().unwrap().is_empty(),
        "WLS is plausible: the test would not test the repair"
    );
    let c = &v["consistent"];
    assert!(!c["active"].as_array().unwrap().is_empty());
    let eig = min_eigs(&f64s(&c["standard"]), &robot);
    assert!(eig.iter().all(|&e| e >= margin * (1.0 - 1e-6)), "{eig:?}");
    let (kinds, _) = idexp::ident::consistent::kinds_of(&robot);
    for (j, k) in kinds.iter().enumerate() {
        if *k == idexp::ident::consistent::Kind::NonNegative {
            assert!(f64s(&c["standard"])[j] >= -1e-9, "{} < 0", robot.param_names()[j]);
        }
    }
    // held-out validation: the consistent model is no worse than WLS by more than 10 % (stated margin)
    let (ew, ec) = (
        f64s(&v["validation"][0]["errors_all"]["e_rel"]),
        f64s(&v["validation"][0]["consistent_all"]["e_rel"]),
    );
    println!("validation e*_j WLS {ew:?} consistent {ec:?}, implausible {}", v["implausible"]);
    for j in 0..ew.len() {
        assert!(ec[j] <= 1.10 * ew[j] + 1e-3, "joint {j}: {} vs {}", ec[j], ew[j]);
    }
}

/// Averages the repetitions of a run folder into one CSV with variance columns.
fn average(run: &Path, out: &Path) -> usize {
    let mut files: Vec<PathBuf> = std::fs::read_dir(run)
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|e| e == "csv") && p.file_name().unwrap() != "reference.csv")
        .collect();
    files.sort();
    let tables: Vec<idexp::io::Table> = files.iter().map(|f| idexp::io::Table::read(f).unwrap()).collect();
    let nr = tables.len();
    let cols = tables[0].columns.clone();
    let mut header = cols.clone();
    let taus: Vec<usize> = cols.iter().enumerate().filter(|(_, c)| c.starts_with("tau")).map(|(i, _)| i).collect();
    header.extend(taus.iter().map(|&i| format!("var_{}", cols[i])));
    let mut text = header.join(",") + "\n";
    for k in 0..tables[0].rows.len() {
        let mean: Vec<f64> = (0..cols.len()).map(|c| tables.iter().map(|t| t.rows[k][c]).sum::<f64>() / nr as f64).collect();
        let mut row: Vec<String> = mean.iter().map(|x| x.to_string()).collect();
        for &i in &taus {
            let var = tables.iter().map(|t| (t.rows[k][i] - mean[i]).powi(2)).sum::<f64>() / (nr - 1) as f64;
            row.push(var.to_string());
        }
        text += &(row.join(",") + "\n");
    }
    std::fs::create_dir_all(out.parent().unwrap()).unwrap();
    std::fs::write(out, text).unwrap();
    nr
}

#[test]
fn averaged_run_gives_the_estimate_and_covariance_of_its_repetitions() {
    let d = tempfile::tempdir().unwrap();
    let robot_file = ident_util::root("tests/data/ident/rpr_drives.toml");
    let run = simulate(d.path(), "run", 6, 11, 0.6);
    let avg = d.path().join("avg/mean.csv");
    let nr = average(&run, &avg);
    let common = ["--filter", "lowpass"];
    let (o, raw) = identify(
        &[
            &[robot_file.to_str().unwrap(), run.to_str().unwrap()][..],
            &common,
            &["--out", d.path().join("a").to_str().unwrap()],
        ]
        .concat(),
    );
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let nrs = nr.to_string();
    let (o, av) = identify(
        &[
            &[robot_file.to_str().unwrap(), avg.to_str().unwrap(), "--repetitions", &nrs][..],
            &common,
            &["--out", d.path().join("b").to_str().unwrap()],
        ]
        .concat(),
    );
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let (raw, av) = (raw.unwrap(), av.unwrap());
    // one averaged file standing for nr repetitions, its rows weighted by the
    // variance columns (estimate.json has no `averaged` flag any more)
    let x = &av["experiments"][0];
    let files = x["files"].as_array().unwrap();
    assert!(files.len() == 1 && files[0].as_str().unwrap().ends_with("mean.csv"), "{files:?}");
    assert_eq!(x["n_reps"].as_u64().unwrap() as usize, nr);
    assert!(x["weights"].as_array().unwrap().iter().all(|w| w == "sample"), "{}", x["weights"]);
    let (ta, tb) = (f64s(&raw["theta"]), f64s(&av["theta"]));
    let (sa, sb) = (f64s(&raw["std"]), f64s(&av["std"]));
    for i in 0..ta.len() {
        assert!((ta[i] - tb[i]).abs() <= 1e-8 * sa[i].max(ta[i].abs()), "θ{i}: {} vs {}", ta[i], tb[i]);
        assert!((sa[i] - sb[i]).abs() <= 1e-8 * sa[i], "σ{i}: {} vs {}", sa[i], sb[i]);
    }
    // run.json gives N_r as well
    std::fs::write(d.path().join("avg/run.json"), format!("{{\"repetitions\": {nr}}}")).unwrap();
    let (o, v) = identify(&[
        robot_file.to_str().unwrap(),
        avg.to_str().unwrap(),
        "--filter",
        "lowpass",
        "--out",
        d.path().join("c").to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert_eq!(f64s(&v.unwrap()["theta"]), tb);
}

#[test]
fn bad_averaged_input_and_impossible_exports_are_clear_errors() {
    let d = tempfile::tempdir().unwrap();
    let robot_file = ident_util::root("tests/data/ident/rpr_drives.toml");
    let run = simulate(d.path(), "run", 3, 12, 0.6);
    let avg = d.path().join("avg/mean.csv");
    average(&run, &avg);
    let text = std::fs::read_to_string(&avg).unwrap();
    let err = |args: &[&str]| -> String {
        let o = exe().arg("identify").args(args).output().unwrap();
        assert_eq!(o.status.code(), Some(1), "{}", String::from_utf8_lossy(&o.stdout));
        String::from_utf8_lossy(&o.stderr).into_owned()
    };
    for (bad, what) in [("0", "zero"), ("-1e-3", "negative"), ("NaN", "NaN")] {
        let mut lines: Vec<String> = text.lines().map(String::from).collect();
        let mut cells: Vec<String> = lines[5].split(',').map(String::from).collect();
        let n = cells.len();
        cells[n - 2] = bad.into(); // var_tau2
        lines[5] = cells.join(",");
        let f = d.path().join(format!("bad_{what}.csv"));
        std::fs::write(&f, lines.join("\n") + "\n").unwrap();
        let e = err(&[robot_file.to_str().unwrap(), f.to_str().unwrap(), "--repetitions", "3"]);
        assert!(e.contains(f.file_name().unwrap().to_str().unwrap()) && e.contains("var_tau2"), "{what}: {e}");
    }
    let e = err(&[robot_file.to_str().unwrap(), avg.to_str().unwrap(), "--repetitions", "1"]);
    // the one-run form's entry is named after the run's folder (`avg`) and
    // its --repetitions is the entry's `repetitions`
    assert!(e.contains("experiment 1 (avg)") && e.contains("repetitions") && e.contains("N_r ≥ 2"), "{e}");
    let e = err(&[robot_file.to_str().unwrap(), avg.to_str().unwrap()]);
    assert!(e.contains("mean.csv") && e.contains("repetitions = N"), "{e}");
    // the one-run form is a one-experiment study: its errors name the study
    // keys (`repetitions`, `export`, [projection] `lags`) of the flags
    // (--repetitions, --export, --fir-lags)
    // URDF export of a DH robot: says what to write instead
    let e = err(&[robot_file.to_str().unwrap(), run.to_str().unwrap(), "--export", "urdf"]);
    assert!(
        e.contains("rpr_drives.toml") && e.contains("field `export`") && e.contains("export \"toml\""),
        "{e}"
    );
    // a huge FIR lag is an error, not an allocation
    let e = err(&[
        robot_file.to_str().unwrap(),
        run.to_str().unwrap(),
        "--method",
        "projection",
        "--fir-lags",
        "100000000000,1",
    ]);
    assert!(e.contains("field `lags`") && e.contains("100000000000"), "{e}");
    // one raw repetition without variances: sample weights are impossible, the
    // message names the entry (named after the run's folder) and says what is
    // (in the study's keys: weights = "auto"; the one-run form's way out,
    // --weights joint, is not named)
    let one = run.join("rep_001.csv");
    let e = err(&[robot_file.to_str().unwrap(), one.to_str().unwrap()]);
    assert!(
        e.contains("experiment `run`") && e.contains("one repetition and no variance columns") && e.contains("weights = \"auto\""),
        "{e}"
    );
}

#[test]
fn exported_urdf_and_toml_reproduce_the_identified_torques() {
    let d = tempfile::tempdir().unwrap();
    let src_file = ident_util::root("designs/robots/ur5.toml");
    let robot = robot::load(&src_file).unwrap();
    // a consistent perturbed parameter set stands for the identified one
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(5);
    let nominal = robot.nominal_params();
    let theta: Vec<f64> = nominal.iter().map(|&x| x * rng.random_range(0.9..1.1)).collect();
    let ident = robot.with_params(&theta).unwrap();
    let src = robot::export::source_of(&src_file).unwrap();
    robot::export::write_urdf(&src, &ident, d.path()).unwrap();
    robot::export::write_robot_toml(&src, &ident, d.path(), Some("robot.urdf")).unwrap();
    let back = robot::load(&d.path().join("robot.toml")).unwrap();
    // the exported URDF on its own (its package:// meshes found through the
    // shipped mesh folder, as for any URDF whose meshes live elsewhere)
    let wrapper = d.path().join("urdf_only.toml");
    std::fs::write(
        &wrapper,
        format!(
            "name = \"ur5-identified\"\nurdf = \"robot.urdf\"\nmesh_path = [\"{}\"]\n",
            ident_util::root("designs/robots/meshes/ur5").display()
        ),
    )
    .unwrap();
    let urdf_only = robot::load(&wrapper).unwrap();
    let n = robot.dof();
    let (tb, tu) = (back.nominal_params(), urdf_only.nominal_params());
    let mut ws = Workspace::new(&robot);
    let mut wu = Workspace::new(&urdf_only);
    for _ in 0..50 {
        let q: Vec<f64> = (0..n).map(|_| rng.random_range(-3.0..3.0)).collect();
        let qd: Vec<f64> = (0..n).map(|_| rng.random_range(-2.0..2.0)).collect();
        let qdd: Vec<f64> = (0..n).map(|_| rng.random_range(-5.0..5.0)).collect();
        let (mut a, mut b) = (vec![0.0; n], vec![0.0; n]);
        inverse_dynamics(&robot, &mut ws, &theta, &q, &qd, &qdd, &mut a);
        inverse_dynamics(&back, &mut ws, tb.as_slice(), &q, &qd, &qdd, &mut b);
        let scale = a.iter().map(|x| x.abs()).fold(0.0, f64::max);
        for j in 0..n {
            assert!((a[j] - b[j]).abs() <= 1e-9 * scale, "joint {j}: {} vs {}", a[j], b[j]);
        }
        // the URDF alone: the rigid-body part (its drives are the URDF's own)
        let rb: Vec<f64> = {
            let mut t = theta.clone();
            for (k, p) in robot.params().iter().enumerate() {
                if !p.kind.is_inertial() {
                    t[k] = 0.0;
                }
            }
            let mut out = vec![0.0; n];
            inverse_dynamics(&robot, &mut ws, &t, &q, &qd, &qdd, &mut out);
            out
        };
        let mut tu0 = tu.clone();
        for (k, p) in urdf_only.params().iter().enumerate() {
            if !p.kind.is_inertial() {
                tu0[k] = 0.0;
            }
        }
        let mut c = vec![0.0; n];
        inverse_dynamics(&urdf_only, &mut wu, tu0.as_slice(), &q, &qd, &qdd, &mut c);
        for j in 0..n {
            assert!((rb[j] - c[j]).abs() <= 1e-9 * scale, "URDF joint {j}: {} vs {}", rb[j], c[j]);
        }
    }
}

#[test]
fn motor_coordinates_equal_the_hand_converted_joint_data() {
    let d = tempfile::tempdir().unwrap();
    let robot_file = ident_util::root("designs/robots/industrial6.toml");
    let robot = robot::load(&robot_file).unwrap();
    let c = robot.coupling_matrix();
    let n = robot.dof();
    // a joint-coordinate run of the coupled-wrist robot from its nominal model
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(9);
    let theta = robot.nominal_params();
    let mut ws = Workspace::new(&robot);
    let m = 400;
    let w: Vec<(f64, f64)> = (0..n).map(|_| (rng.random_range(0.3..0.8), rng.random_range(0.2..0.6))).collect();
    let mut joint_csv = String::from("t");
    let mut motor_csv = String::from("t");
    for p in ["q", "qd", "qdd", "tau"] {
        for j in 1..=n {
            joint_csv += &format!(",{p}{j}");
            motor_csv += &format!(",{p}{j}");
        }
    }
    joint_csv += "\n";
    motor_csv += "\n";
    for k in 0..m {
        let t = k as f64 * 0.02;
        let q: Vec<f64> = w.iter().map(|(f, a)| a * (std::f64::consts::TAU * f * t).sin()).collect();
        let qd: Vec<f64> = w
            .iter()
            .map(|(f, a)| a * std::f64::consts::TAU * f * (std::f64::consts::TAU * f * t).cos())
            .collect();
        let qdd: Vec<f64> = w
            .iter()
            .map(|(f, a)| -a * (std::f64::consts::TAU * f).powi(2) * (std::f64::consts::TAU * f * t).sin())
            .collect();
        let mut tau = vec![0.0; n];
        inverse_dynamics(&robot, &mut ws, theta.as_slice(), &q, &qd, &qdd, &mut tau);
        let tau: Vec<f64> = tau.iter().map(|x| x + rng.random_range(-0.05..0.05)).collect();
        let mot = |v: &[f64]| -> Vec<f64> { (&c * nalgebra::DVector::from_column_slice(v)).as_slice().to_vec() };
        let row = |a: &[&[f64]]| a.iter().flat_map(|v| v.iter()).map(|x| x.to_string()).collect::<Vec<_>>().join(",");
        joint_csv += &format!("{t},{}\n", row(&[&q, &qd, &qdd, &tau]));
        motor_csv += &format!("{t},{}\n", row(&[&mot(&q), &mot(&qd), &mot(&qdd), &tau]));
    }
    let (jf, mf) = (d.path().join("joint/run.csv"), d.path().join("motor/run.csv"));
    for (f, text) in [(&jf, &joint_csv), (&mf, &motor_csv)] {
        std::fs::create_dir_all(f.parent().unwrap()).unwrap();
        std::fs::write(f, text).unwrap();
    }
    let base = ["--weights", "joint", "--filter", "none"];
    let (o, a) = identify(
        &[
            &[robot_file.to_str().unwrap(), jf.to_str().unwrap()][..],
            &base,
            &["--out", d.path().join("a").to_str().unwrap()],
        ]
        .concat(),
    );
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let (o, b) = identify(
        &[
            &[robot_file.to_str().unwrap(), mf.to_str().unwrap(), "--coordinates", "motor"][..],
            &base,
            &["--out", d.path().join("b").to_str().unwrap()],
        ]
        .concat(),
    );
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let (ta, tb) = (f64s(&a.unwrap()["theta"]), f64s(&b.unwrap()["theta"]));
    for i in 0..ta.len() {
        assert!((ta[i] - tb[i]).abs() <= 1e-7 * ta[i].abs().max(1e-3), "θ{i}: {} vs {}", ta[i], tb[i]);
    }
}
