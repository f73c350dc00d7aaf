//! Identification studies (`idexp::ident::study`, `idexp identify study.toml`):
//! several experiments of different lengths, noise levels and kinds stacked
//! in one weighted fit, validation runs, the consistent estimate with a prior;
//! checked against the known truth of simulated runs.

mod ident_util;

use ident_util::{design, root, simulate};
use idexp::data::Repetition;
use idexp::ident::study::{run_study, StudyDesign, StudyResult};
use idexp::ident::EstimateStatus;
use idexp::optim::Control;
use std::path::{Path, PathBuf};
use std::process::Command;

/// A simulation of the RPR arm (true parameters from truth seed 1) written to `dir/name`.
fn sim(dir: &Path, name: &str, robot: &str, body: &str) -> PathBuf {
    let d = design(&sim_text(robot, "", body));
    let res = simulate(&d);
    let out = dir.join(name);
    res.write(&out, &d).unwrap();
    out
}

/// A simulation design: `body` is "top-level keys @@ tables" ([`fourier`], [`slopes`]).
fn sim_text(robot: &str, extra_top: &str, body: &str) -> String {
    let (top, tables) = body.split_once("@@").unwrap();
    format!("robot = \"{robot}\"\nrate = 1000.0\n{extra_top}{top}[truth]\nperturbation = 0.1\nseed = 1\n[controller]\nbandwidth = 10.0\n{tables}")
}

fn fourier(reps: usize, seed: u64, traj: u64, freq: f64, nh: usize, noise: f64, decimate: usize) -> String {
    format!(
        "decimate = {decimate}\nrepetitions = {reps}\nseed = {seed}\n@@[noise]\ntorque = {noise}\nposition = 2e-5\n[reference]\nkind = \"random_fourier\"\nn_h = {nh}\nfrequency = {freq}\namplitude = 0.6\nseed = {traj}\n"
    )
}

fn slopes(reps: usize, seed: u64, joint: usize, decimate: usize) -> String {
    format!(
        "decimate = {decimate}\nrepetitions = {reps}\nseed = {seed}\n@@[noise]\ntorque = 0.05\nposition = 2e-5\n[reference]\nkind = \"gravity_slopes\"\njoint = {joint}\nfrom = -1.2\nto = 1.2\nvelocity = 0.3\nacceleration = 2.0\nq_rest = [0.4, 0.2, 0.0]\n"
    )
}

/// The three experiments of the simulated study: 30 repetitions of a 10 s
/// Fourier trajectory, one repetition of a 5 s one with 3× the noise, and a
/// gravity experiment of the wrist (3 repetitions).
fn three_experiments(dir: &Path) -> (PathBuf, PathBuf, PathBuf) {
    let robot = "tests/data/ident/rpr_drives.toml";
    let a = sim(dir, "a", robot, &fourier(30, 11, 3, 0.1, 5, 0.05, 5));
    let b = sim(dir, "b", robot, &fourier(1, 12, 7, 0.2, 4, 0.15, 5));
    let g = sim(dir, "g", robot, &slopes(3, 13, 3, 5));
    (a, b, g)
}

fn study(dir: &Path, text: &str) -> StudyResult {
    let p = dir.join("study.toml");
    std::fs::write(&p, text).unwrap();
    let d = StudyDesign::read(&p).unwrap_or_else(|e| panic!("{e}"));
    run_study(&d, dir, &Control::new()).unwrap_or_else(|e| panic!("{e}"))
}

fn head(robot: &str) -> String {
    format!("robot = \"{}\"\ntruth = \"a/truth.json\"\n", root(robot).display())
}

const A: &str = "[[experiment]]\nname = \"a\"\nfiles = [\"a\"]\nharmonics = 40\n";
const B: &str = "[[experiment]]\nname = \"b\"\nfiles = [\"b\"]\nharmonics = 16\n";
const G: &str = "[[experiment]]\nname = \"g\"\nfiles = [\"g\"]\nkind = \"gravity\"\n";

/// Σ ((θ̂ − θ*)/σ)² with the given σ.
fn error_norm(r: &StudyResult, sigma: &[f64]) -> f64 {
    let t = r.estimate.truth.as_ref().unwrap();
    t.iter().zip(sigma).map(|(row, s)| ((row.estimate - row.truth) / s).powi(2)).sum()
}

#[test]
fn stacked_study_is_within_its_uncertainty_of_the_truth_and_better_than_each_experiment_alone() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path();
    three_experiments(dir);
    let h = head("tests/data/ident/rpr_drives.toml");
    let all = study(dir, &format!("{h}{A}{B}{G}"));
    let e = &all.estimate;
    assert_eq!(e.status, EstimateStatus::Ok);
    let t = e.truth.as_ref().unwrap();
    let zmax = t.iter().map(|r| r.z.abs()).fold(0.0, f64::max);
    assert!(zmax < 4.0, "max |z| = {zmax}:\n{}", e.text());
    // weights: repetitions for a (30: per sample) and g (3: per joint), residuals for b
    let w = |i: usize| serde_json::to_value(&e.experiments[i].weights).unwrap();
    assert_eq!(w(0), serde_json::json!(["sample", "sample", "sample"]));
    assert_eq!(w(1), serde_json::json!(["residual", "residual", "residual"]));
    assert_eq!(e.experiments[2].weights[2], idexp::ident::study::BlockWeight::Joint);
    // b's residual σ_b is the RMS of its residuals (with its share of the degrees of
    // freedom), at least its torque noise of 0.15 N·m (a single closed-loop
    // repetition adds the controller's reaction to the encoder noise)
    let rows: usize = e.experiments.iter().map(|x| x.rows_used.iter().map(|r| r.used).sum::<usize>()).sum();
    let k = e.names.len() as f64;
    for j in 0..3 {
        let x = &e.experiments[1];
        let s = x.sigma[j];
        let expect = x.errors.rms[j] / (1.0 - k / rows as f64).sqrt();
        assert!((s - expect).abs() < 1e-6 * expect, "b joint {}: σ = {s}, residual RMS {expect}", j + 1);
        assert!(s > 0.15, "b joint {}: σ = {s}", j + 1);
    }
    // every experiment's rows at the noise its weights stand for
    for x in &e.experiments {
        assert!((x.chi2_per_row - 1.0).abs() < 0.25, "{}: χ²/row {}", x.name, x.chi2_per_row);
    }
    let shares: f64 = e.experiments.iter().map(|x| x.information_share).sum();
    assert!((shares - 1.0).abs() < 1e-9, "{shares}");
    // each experiment alone: a and b identify everything, less well (every σ larger,
    // so a larger expected error in any metric); b alone (2 % of the information)
    // is also further from the truth; g alone is rank deficient
    let stacked = error_norm(&all, &e.std);
    let expected = |r: &StudyResult| -> f64 { (0..e.std.len()).map(|i| (r.estimate.std[i] / e.std[i]).powi(2)).sum() };
    for (name, x) in [("a", A), ("b", B)] {
        let alone = study(dir, &format!("{h}{x}"));
        assert_eq!(alone.estimate.status, EstimateStatus::Ok, "{name}");
        for i in 0..e.std.len() {
            assert!(
                e.std[i] <= 1.01 * alone.estimate.std[i],
                "{name}: σ of {} {} > {}",
                e.names[i],
                e.std[i],
                alone.estimate.std[i]
            );
        }
        assert!(expected(&alone) > 1.05 * e.std.len() as f64, "{name}: expected error {}", expected(&alone));
        if name == "b" {
            let err = error_norm(&alone, &e.std);
            assert!(stacked < err, "{name}: stacked error {stacked} not below {err} of the experiment alone");
        }
    }
    let g = study(dir, &format!("{h}{G}"));
    assert_eq!(g.estimate.status, EstimateStatus::RankDeficient);
    assert!(g.estimate.unusable_reason().unwrap().contains("rank_deficient"));
}

#[test]
fn the_prior_decides_what_few_data_leave_open_and_does_not_bias_rich_data() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path();
    three_experiments(dir);
    let h = head("tests/data/ident/rpr_drives.toml");
    for metric in ["entropic", "euclidean"] {
        let cons = format!("[consistent]\nmetric = \"{metric}\"\nweight = 1.0\n");
        // rich data: the prior moves the consistent estimate by less than one σ
        // (against the same fit with a negligible prior: the constraints alone)
        let rich = study(dir, &format!("{h}{A}{B}{G}{cons}"));
        let free = study(dir, &format!("{h}{A}{B}{G}{}", cons.replace("weight = 1.0", "weight = 1e-9")));
        let e = &rich.estimate;
        let c = e.consistent.as_ref().unwrap();
        let cf = free.estimate.consistent.as_ref().unwrap();
        assert!(c.status.is_ok() && cf.status.is_ok());
        // "rich": the base parameters the data know ten times better than the prior
        let kmat = &e.base_k;
        let mut rich_count = 0;
        for i in 0..e.names.len() {
            let prior_sd = kmat[i].iter().zip(&c.prior_scale).map(|(k, s)| (k * s).powi(2)).sum::<f64>().sqrt();
            if e.std[i] > 0.1 * prior_sd {
                continue;
            }
            rich_count += 1;
            let d = (c.base[i] - cf.base[i]).abs() / e.std[i];
            assert!(d < 1.0, "{metric}: {} moved {d:.2} σ by the prior\n{}", e.names[i], e.text());
        }
        assert!(rich_count >= 6, "{metric}: only {rich_count} base parameters known better than the prior");
        // few data (the wrist's gravity experiment alone, rank 9 of 18): what it
        // does not see is the prior's, and the estimate is nearer the prior
        let few = study(dir, &format!("{h}{G}{cons}"));
        assert_eq!(few.estimate.status, EstimateStatus::RankDeficient);
        let fc = few.estimate.consistent.as_ref().unwrap();
        assert!(fc.status.is_ok());
        assert_eq!(few.estimate.state(false), idexp::io::status::RunState::Complete);
        assert!(fc.unidentifiable > c.unidentifiable, "{} vs {}", fc.unidentifiable, c.unidentifiable);
        let dist = |c: &idexp::ident::study::ConsistentReport| -> f64 {
            (0..c.standard.len())
                .map(|j| ((c.standard[j] - c.prior_standard[j]) / c.prior_scale[j]).powi(2))
                .sum::<f64>()
                .sqrt()
        };
        assert!(
            dist(fc) < 0.5 * dist(c),
            "{metric}: distance to the prior {} (few data) vs {} (rich)",
            dist(fc),
            dist(c)
        );
        // the drives of the base and the slide never move in the gravity experiment: the prior's values
        let names = &fc.standard_names;
        for p in ["Ia1", "Fc1", "Fv1", "Ia2", "Fc2", "Fv2"] {
            let j = names.iter().position(|n| n == p).unwrap();
            let rel = (fc.standard[j] - fc.prior_standard[j]).abs() / fc.prior_scale[j];
            assert!(rel < 1e-4, "{metric}: {p} = {} vs prior {}", fc.standard[j], fc.prior_standard[j]);
        }
        // what it sees, it fits: the wrist's first moment MX3R of the truth within 2 %
        let t = rich.estimate.truth.as_ref().unwrap();
        let i = few.estimate.names.iter().position(|n| n == "MX3R").unwrap();
        assert!(
            (fc.base[i] - t[i].truth).abs() < 0.02 * t[i].truth.abs(),
            "MX3R {} vs {}",
            fc.base[i],
            t[i].truth
        );
    }
}

#[test]
fn weight_chosen_on_validation_runs_is_the_strongest_within_one_standard_error_of_the_best() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path();
    three_experiments(dir);
    sim(dir, "v", "tests/data/ident/rpr_drives.toml", &fourier(1, 14, 9, 0.125, 5, 0.05, 5));
    // a static pose of the arm (joint 1 vertical: no torque at rest) as a second validation run
    let d = design(&sim_text("tests/data/ident/rpr_drives.toml", "", &fourier(1, 11, 3, 0.1, 5, 0.05, 5)));
    static_pose(&simulate(&d).setup.truth, &[0.3, 0.2, 0.4], 4.0, 7)
        .write(&dir.join("pose.csv"))
        .unwrap();
    let h = head("tests/data/ident/rpr_drives.toml");
    let r = study(
        dir,
        &format!("{h}{A}{B}[[validation]]\nname = \"v\"\nfiles = [\"v\"]\nharmonics = 20\n[[validation]]\nname = \"pose\"\nfiles = [\"pose.csv\"]\nkind = \"static\"\n[consistent]\nweight = \"validation\"\nweight_grid = [0.01, 1.0, 100.0, 10000.0]\n"),
    );
    let c = r.estimate.consistent.as_ref().unwrap();
    assert_eq!(c.weight_curve.len(), 4);
    // the criterion recomputed here: per joint the torque range over both runs,
    // per (run, joint) RMS(τ − Cθ)/range, mean and sd/√K
    let sets: Vec<_> = r.validations.iter().map(|v| &v.prep.every).collect();
    let n = sets[0].n;
    let mut range = vec![(f64::INFINITY, f64::NEG_INFINITY); n];
    for d in &sets {
        for (i, &j) in d.joint.iter().enumerate() {
            range[j] = (range[j].0.min(d.y[i]), range[j].1.max(d.y[i]));
        }
    }
    let crit = |theta: &[f64]| -> (f64, f64) {
        let mut t = Vec::new();
        for d in &sets {
            let pred = &d.c * nalgebra::DVector::from_column_slice(theta);
            for j in 0..n {
                let rows: Vec<usize> = (0..d.y.len()).filter(|&i| d.joint[i] == j).collect();
                let rms = (rows.iter().map(|&i| (d.y[i] - pred[i]).powi(2)).sum::<f64>() / rows.len() as f64).sqrt();
                t.push(rms / (range[j].1 - range[j].0));
            }
        }
        let k = t.len() as f64;
        let m = t.iter().sum::<f64>() / k;
        (m, (t.iter().map(|x| (x - m).powi(2)).sum::<f64>() / (k - 1.0) / k).sqrt())
    };
    let (score, _) = crit(&c.base);
    let chosen = c.weight_curve.iter().find(|x| x.0 == c.weight).unwrap();
    assert!((score - chosen.1).abs() < 1e-9 * score, "{score} vs {}", chosen.1);
    let best = c.weight_curve.iter().min_by(|a, b| a.1.total_cmp(&b.1)).unwrap();
    let tol = c.weight_tolerance.unwrap();
    assert!(tol > 0.0 && chosen.1 <= best.1 + tol, "{chosen:?}, best {best:?}, tolerance {tol}");
    // the strongest such weight
    for x in &c.weight_curve {
        if x.0 > c.weight {
            assert!(x.1 > best.1 + tol, "{x:?} is within the tolerance and stronger than the chosen {}", c.weight);
        }
    }
    let text = r.estimate.text();
    assert!(text.contains("one standard error") && text.contains("<- chosen"), "{text}");
}

/// Keeps the samples of a 1 kHz repetition at steps alternating 10 and 12 ms
/// (a ~91 Hz recorder on a 2 ms controller clock), starting at `phase`, with
/// the time stamps moved to a controller uptime of `offset` s.
fn irregular(rep: &Repetition, phase: usize, offset: f64) -> Repetition {
    let mut idx = vec![phase];
    let mut k = 0;
    loop {
        let next = idx[idx.len() - 1] + if k % 2 == 0 { 10 } else { 12 };
        if next >= rep.len() {
            break;
        }
        idx.push(next);
        k += 1;
    }
    let pick = |v: &Vec<Vec<f64>>| idx.iter().map(|&i| v[i].clone()).collect::<Vec<_>>();
    Repetition {
        t: idx.iter().map(|&i| rep.t[i] + offset).collect(),
        q: pick(&rep.q),
        tau: pick(&rep.tau),
        r: None,
        qd: rep.qd.as_ref().map(pick),
        qdd: None,
    }
}

#[test]
fn real_data_shaped_study_irregular_currents_five_experiments_and_validation_runs() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path();
    let robot_file = "tests/data/ident/rpr_drives_tanh.toml";
    let robot = idexp::robot::load(&root(robot_file)).unwrap();
    let scale: Vec<f64> = robot.drives.iter().map(|d| d.torque_per_ampere().unwrap()).collect();
    // five experiments of different lengths and kinds, three validation runs, all at 1 kHz
    let specs: Vec<(&str, String, usize)> = vec![
        ("fa", fourier(1, 31, 3, 0.1, 5, 0.05, 1), 1),
        ("fb", fourier(3, 32, 7, 0.2, 4, 0.1, 1), 3),
        ("fc", fourier(1, 33, 5, 0.125, 5, 0.08, 1), 1),
        ("grav3", slopes(1, 34, 3, 1), 1),
        (
            "grav2",
            slopes(1, 35, 2, 1)
                .replace("from = -1.2\nto = 1.2", "from = 0.05\nto = 0.45")
                .replace("velocity = 0.3", "velocity = 0.05"),
            1,
        ),
        ("va", fourier(1, 36, 9, 0.125, 5, 0.05, 1), 1),
        ("vb", fourier(1, 37, 11, 0.2, 3, 0.05, 1), 1),
        ("vg", slopes(1, 38, 3, 1), 1),
    ];
    let mut truth = None;
    for (name, body, reps) in &specs {
        let d = design(&sim_text(robot_file, "substeps = 4\nrecord_velocity = true\n", body));
        let res = simulate(&d);
        truth.get_or_insert_with(|| res.truth().unwrap());
        let out = dir.join("logs").join(name);
        std::fs::create_dir_all(&out).unwrap();
        for (k, rep) in res.reps.iter().enumerate().take(*reps) {
            // logged as a recorder would: irregular steps, controller uptime, the
            // drive's velocities, motor currents only
            let r = irregular(rep, 3 * k, 1234.5678 + 100.0 * k as f64);
            r.write_drive(&out.join(format!("rep{k}.csv")), Some(&scale), false).unwrap();
        }
    }
    std::fs::write(dir.join("truth.json"), serde_json::to_string(truth.as_ref().unwrap()).unwrap()).unwrap();
    let mut text = format!("name = \"shaped\"\nrobot = \"{}\"\ntruth = \"truth.json\"\n", root(robot_file).display());
    for (name, kind) in [
        ("fa", "excitation"),
        ("fb", "excitation"),
        ("fc", "excitation"),
        ("grav3", "gravity"),
        ("grav2", "gravity"),
    ] {
        text += &format!("[[experiment]]\nname = \"{name}\"\nfiles = [\"logs/{name}\"]\nkind = \"{kind}\"\ncutoff = 5.0\nstandstill = \"drop\"\n");
    }
    for (name, kind) in [("va", "excitation"), ("vb", "excitation"), ("vg", "gravity")] {
        text += &format!("[[validation]]\nname = \"{name}\"\nfiles = [\"logs/{name}\"]\nkind = \"{kind}\"\ncutoff = 5.0\n");
    }
    text += "[consistent]\nweight = 1.0\n";
    let study_path = dir.join("study.toml");
    std::fs::write(&study_path, &text).unwrap();
    let out = dir.join("out");
    let o = Command::new(env!("CARGO_BIN_EXE_idexp"))
        .args(["identify", study_path.to_str().unwrap(), "--out", out.to_str().unwrap()])
        .env("IDEXP_NO_PROGRESS", "1")
        .output()
        .unwrap();
    let stdout = String::from_utf8_lossy(&o.stdout);
    assert_eq!(o.status.code(), Some(0), "{stdout}\n{}", String::from_utf8_lossy(&o.stderr));
    let est: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(out.join("estimate.json")).unwrap()).unwrap();
    let status: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(out.join("status.json")).unwrap()).unwrap();
    assert_eq!(status["status"], "complete");
    assert_eq!(status["command"], "identify");
    let exps = est["experiments"].as_array().unwrap();
    assert_eq!(exps.len(), 5);
    for x in exps {
        let s = &x["sampling"];
        assert_eq!(s["irregular"], true, "{x}");
        let rate = s["resampled_to"].as_f64().unwrap();
        assert!((rate - 1.0 / s["median_step"].as_f64().unwrap()).abs() < 1e-9);
        assert_eq!(x["torque_source"]["from"], "current");
    }
    assert_eq!(exps[1]["n_reps"], 3);
    // lengths differ
    let d: Vec<f64> = exps.iter().map(|x| x["duration"].as_f64().unwrap()).collect();
    assert!(d[0] > 1.8 * d[1], "{d:?}");
    // the estimate near the truth (low-pass filtering of ~91 Hz logs: a few σ at most)
    for row in est["truth"].as_array().unwrap() {
        let z = row["z"].as_f64().unwrap();
        assert!(z.abs() < 6.0, "{row}\n{stdout}");
    }
    // every validation run reported, and the figures recomputed from the written files
    let val = est["validation"].as_array().unwrap();
    assert_eq!(val.len(), 3);
    let theta: Vec<f64> = est["consistent"]["standard"].as_array().unwrap().iter().map(|v| v.as_f64().unwrap()).collect();
    let mut ws = idexp::robot::Workspace::new(&robot);
    for v in val {
        let name = v["name"].as_str().unwrap();
        let t = idexp::io::Table::read(&out.join("validation").join(format!("{name}.csv"))).unwrap();
        let n = 3;
        let col = |p: &str, j: usize| t.index(&format!("{p}{j}")).unwrap();
        let (mut e, mut mag) = (vec![0.0; n], vec![0.0; n]);
        let mut worst = 0.0_f64;
        for row in &t.rows {
            let q: Vec<f64> = (1..=n).map(|j| row[col("q", j)]).collect();
            let qd: Vec<f64> = (1..=n).map(|j| row[col("qd", j)]).collect();
            let qdd: Vec<f64> = (1..=n).map(|j| row[col("qdd", j)]).collect();
            let mut tau = vec![0.0; n];
            idexp::robot::inverse_dynamics(&robot, &mut ws, &theta, &q, &qd, &qdd, &mut tau);
            for j in 0..n {
                let pred = row[col("tau_consistent", j + 1)];
                worst = worst.max((tau[j] - pred).abs() / (1.0 + pred.abs()));
                e[j] += (row[col("tau", j + 1)] - pred).abs();
                mag[j] += row[col("tau", j + 1)].abs();
            }
        }
        // the consistent standard parameters through the robot's own inverse dynamics reproduce the written predictions
        assert!(worst < 1e-9, "{name}: {worst:e}");
        for j in 0..n {
            let written = v["consistent_all"]["e_rel"][j].as_f64().unwrap();
            assert!(
                (e[j] / mag[j] - written).abs() < 1e-9 * written.max(1e-12),
                "{name} joint {}: {} vs {written}",
                j + 1,
                e[j] / mag[j]
            );
        }
    }
    for f in [
        "report.txt",
        "params.csv",
        "experiments.csv",
        "validation.csv",
        "prior.csv",
        "validation.svg",
        "study.json",
    ] {
        assert!(out.join(f).exists(), "{f}");
    }
    assert!(stdout.contains("irregular time stamps"), "{stdout}");
}

#[test]
fn study_errors_name_the_file_the_entry_and_the_field_and_leave_no_folder() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path();
    let robot = root("tests/data/ident/rpr_drives.toml");
    let run = |text: &str, extra: &[&str]| {
        let p = dir.join("s.toml");
        std::fs::write(&p, text).unwrap();
        let out = dir.join("o");
        let mut args = vec!["identify", p.to_str().unwrap(), "--out", out.to_str().unwrap()];
        args.extend_from_slice(extra);
        let o = Command::new(env!("CARGO_BIN_EXE_idexp"))
            .args(&args)
            .env("IDEXP_NO_PROGRESS", "1")
            .output()
            .unwrap();
        assert!(!out.exists(), "an output folder was left behind for {text}");
        (o.status.code(), String::from_utf8_lossy(&o.stderr).into_owned())
    };
    let h = format!("robot = \"{}\"\n", robot.display());
    let (c, e) = run(&format!("{h}[[experiment]]\nfiles = [\"missing\"]\n"), &[]);
    assert_eq!(c, Some(1));
    assert!(e.contains("missing") && e.contains("no such file"), "{e}");
    let (c, e) = run(&format!("{h}[[experiment]]\nfiles = [\"a\"]\ndecimate = 0\n"), &[]);
    assert_eq!(c, Some(1));
    assert!(e.contains("s.toml") && e.contains("experiment 1 (a)") && e.contains("decimate"), "{e}");
    let (c, e) = run(&format!("{h}[[experiment]]\nfiles = [\"a\"]\nfilterr = \"none\"\n"), &[]);
    assert_eq!(c, Some(1));
    assert!(e.contains("filterr"), "{e}");
    let (c, e) = run(&format!("{h}[[experiment]]\nfiles = [\"a\"]\n"), &["--method", "ols"]);
    assert_eq!(c, Some(1));
    assert!(e.contains("--method") && e.contains("study file"), "{e}");
    let (c, e) = run(&format!("{h}[[experiment]]\nfiles = [\"a\"]\n[consistent]\nweight = -1\n"), &[]);
    assert_eq!(c, Some(1));
    assert!(e.contains("[consistent]") && e.contains("weight"), "{e}");
    // a robot file alone (no runs, not a study) is a usage problem explained
    let o = Command::new(env!("CARGO_BIN_EXE_idexp"))
        .args(["identify", robot.to_str().unwrap()])
        .output()
        .unwrap();
    assert_eq!(o.status.code(), Some(1));
    assert!(String::from_utf8_lossy(&o.stderr).contains("no run given"));
}

#[test]
fn repetitions_reach_an_averaged_validation_run() {
    // an averaged validation run (means + var_tau*) without run.json: --repetitions gives N_r to it too
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path();
    let robot = "tests/data/ident/rpr_drives.toml";
    let a = sim(dir, "a", robot, &fourier(5, 41, 3, 0.1, 5, 0.05, 5));
    let v = sim(dir, "v", robot, &fourier(5, 42, 4, 0.1, 5, 0.05, 5));
    let avg = |src: &Path, name: &str| -> PathBuf {
        let run = idexp::ident::Run::read(&[src.to_path_buf()], 3).unwrap();
        let pr = idexp::ident::process(&run, &idexp::ident::Filter::None).unwrap();
        let var = pr.tau_var.clone().unwrap();
        let mut header = vec!["t".to_string()];
        for p in ["q", "tau", "var_tau"] {
            header.extend((1..=3).map(|j| format!("{p}{j}")));
        }
        let rows = (0..pr.len()).map(|k| {
            let mut r = vec![pr.t[k]];
            r.extend((0..3).map(|j| run.reps.iter().map(|x| x.q[k][j]).sum::<f64>() / run.reps.len() as f64));
            r.extend_from_slice(&pr.tau[k]);
            r.extend_from_slice(&var[k]);
            r
        });
        let d = dir.join(name);
        std::fs::create_dir_all(&d).unwrap();
        let f = d.join("mean.csv");
        idexp::io::write_csv(&f, &header, rows).unwrap();
        f
    };
    let fa = avg(&a, "a_avg");
    let fv = avg(&v, "v_avg");
    let o = Command::new(env!("CARGO_BIN_EXE_idexp"))
        .args([
            "identify",
            root(robot).to_str().unwrap(),
            fa.to_str().unwrap(),
            "--validate",
            fv.to_str().unwrap(),
            "--repetitions",
            "5",
        ])
        .args(["--out", dir.join("o").to_str().unwrap()])
        .env("IDEXP_NO_PROGRESS", "1")
        .output()
        .unwrap();
    assert_eq!(o.status.code(), Some(0), "{}", String::from_utf8_lossy(&o.stderr));
    let est: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(dir.join("o/estimate.json")).unwrap()).unwrap();
    let v = &est["validation"][0]["errors_all"];
    assert!(v["noise_floor"].is_array(), "{v}");
}

#[test]
fn experiments_from_robot_logs_equal_the_same_samples_as_run_csvs() {
    // the UR5 fixtures of tests/logs.rs: one trajectory as idexp's run CSV, as a
    // ROS 2 bag (MCAP and sqlite3, written by rosbags) and as an RTDE recorder CSV
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path();
    let d = root("tests/data/logs");
    let head = format!("robot = \"{}\"\nweights = \"residuals\"\n", d.join("ur5_drives.toml").display());
    let entry = |name: &str, file: &str, log: &str| format!("[[experiment]]\nname = \"{name}\"\nfiles = [\"{}\"]\n{log}", d.join(file).display());
    let reference = study(dir, &format!("{head}{}", entry("csv", "ur5_idexp.csv", "")));
    assert_eq!(reference.estimate.status, EstimateStatus::Ok);
    for (name, file, log) in [
        ("mcap", "ur5_mcap", "log = { format = \"bag\" }\n"),
        ("sqlite", "ur5_sqlite3", "log = { format = \"bag\" }\n"),
        ("rtde", "ur5_rtde.csv", "log = { format = \"rtde\" }\n"),
    ] {
        let r = study(dir, &format!("{head}{}", entry(name, file, log)));
        let (a, b) = (&r.estimate.theta, &reference.estimate.theta);
        for i in 0..a.len() {
            assert!(
                (a[i] - b[i]).abs() <= 1e-9 * b[i].abs().max(1e-9),
                "{name}: {} {} vs {}",
                r.estimate.names[i],
                a[i],
                b[i]
            );
        }
    }
    // a spec field of another format is named
    let p = dir.join("bad.toml");
    std::fs::write(
        &p,
        format!("{head}{}", entry("x", "ur5_mcap", "log = { format = \"bag\", q = \"actual_q_{j}\" }\n")),
    )
    .unwrap();
    let e = StudyDesign::read(&p).unwrap_err().to_string();
    assert!(e.contains("experiment 1 (x): log") && e.contains('q'), "{e}");
}

#[test]
fn identify_reads_robot_logs_given_on_the_command_line() {
    let d = root("tests/data/logs");
    let tmp = tempfile::tempdir().unwrap();
    let run = |args: &[&str], out: &str| -> serde_json::Value {
        let o = Command::new(env!("CARGO_BIN_EXE_idexp"))
            .arg("identify")
            .arg(d.join("ur5_drives.toml"))
            .args(args)
            .args(["--weights", "joint", "--out", tmp.path().join(out).to_str().unwrap()])
            .env("IDEXP_NO_PROGRESS", "1")
            .output()
            .unwrap();
        assert_eq!(o.status.code(), Some(0), "{args:?}: {}", String::from_utf8_lossy(&o.stderr));
        serde_json::from_str(&std::fs::read_to_string(tmp.path().join(out).join("estimate.json")).unwrap()).unwrap()
    };
    let csv = run(&[d.join("ur5_idexp.csv").to_str().unwrap()], "csv");
    let bag = run(&[d.join("ur5_sqlite3").to_str().unwrap(), "--log-format", "bag"], "bag");
    let rtde = run(
        &[d.join("ur5_rtde.csv").to_str().unwrap(), "--log-map", d.join("rtde_map.toml").to_str().unwrap()],
        "rtde",
    );
    for (what, e) in [("bag", &bag), ("rtde", &rtde)] {
        for (a, b) in e["theta"].as_array().unwrap().iter().zip(csv["theta"].as_array().unwrap()) {
            let (a, b) = (a.as_f64().unwrap(), b.as_f64().unwrap());
            assert!((a - b).abs() <= 1e-9 * b.abs().max(1e-9), "{what}: {a} vs {b}");
        }
    }
    // --topic without a log form is a clear error
    let o = Command::new(env!("CARGO_BIN_EXE_idexp"))
        .arg("identify")
        .arg(d.join("ur5_drives.toml"))
        .arg(d.join("ur5_idexp.csv"))
        .args(["--topic", "/joint_states", "--out", tmp.path().join("x").to_str().unwrap()])
        .output()
        .unwrap();
    assert_eq!(o.status.code(), Some(1));
    assert!(String::from_utf8_lossy(&o.stderr).contains("--log-format"));
}

/// Poses held at rest for `secs` s at 100 Hz, logged as a robot logs them:
/// positions with 2e-5 noise, velocities that are noise (σ 3e-4, 4 decimals:
/// the sign flips from sample to sample), torques = the true gravity torques
/// + 0.05 N·m noise.
fn static_pose(truth: &idexp::robot::Robot, q0: &[f64], secs: f64, seed: u64) -> Repetition {
    use rand::SeedableRng;
    use rand_distr::{Distribution, Normal};
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
    let (n, p) = (truth.dof(), truth.n_params());
    let theta = truth.nominal_params();
    let mut ws = idexp::robot::Workspace::new(truth);
    let mut y = vec![0.0; n * p];
    idexp::robot::regressor_rows(truth, &mut ws, q0, &vec![0.0; n], &vec![0.0; n], &mut y);
    let g: Vec<f64> = (0..n).map(|j| (0..p).map(|c| y[j * p + c] * theta[c]).sum()).collect();
    let (nq, nv, nt) = (
        Normal::new(0.0, 2e-5).unwrap(),
        Normal::new(0.0, 3e-4).unwrap(),
        Normal::new(0.0, 0.05).unwrap(),
    );
    let m = (secs * 100.0) as usize;
    let t: Vec<f64> = (0..m).map(|k| k as f64 * 0.01).collect();
    let round4 = |x: f64| (x * 1e4).round() / 1e4;
    Repetition {
        t,
        q: (0..m).map(|_| q0.iter().map(|&x| x + nq.sample(&mut rng)).collect()).collect(),
        tau: (0..m).map(|_| g.iter().map(|&x| x + nt.sample(&mut rng)).collect()).collect(),
        r: None,
        qd: Some((0..m).map(|_| (0..n).map(|_| round4(nv.sample(&mut rng))).collect()).collect()),
        qdd: None,
    }
}

/// e_j = mean |τ_j − τ̂_j| per joint, read from a validation/<run>.csv with this test's own parser.
fn e_from_csv(path: &Path, n: usize, column: &str) -> Vec<f64> {
    let text = std::fs::read_to_string(path).unwrap();
    let mut lines = text.lines();
    let header: Vec<&str> = lines.next().unwrap().split(',').collect();
    let col = |name: String| header.iter().position(|h| *h == name).unwrap_or_else(|| panic!("{name} in {header:?}"));
    let (it, ip): (Vec<usize>, Vec<usize>) = (1..=n).map(|j| (col(format!("tau{j}")), col(format!("{column}{j}")))).unzip();
    let mut sum = vec![0.0; n];
    let mut rows = 0;
    for l in lines {
        let v: Vec<f64> = l.split(',').map(|x| x.parse().unwrap()).collect();
        for j in 0..n {
            sum[j] += (v[it[j]] - v[ip[j]]).abs();
        }
        rows += 1;
    }
    sum.iter().map(|s| s / rows as f64).collect()
}

#[test]
fn static_validation_poses_at_rest_are_validated_without_options_and_their_errors_recomputed_from_the_csv() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path();
    let robot = "tests/data/ident/rpr_drives.toml";
    let d = design(&sim_text(robot, "", &fourier(10, 11, 3, 0.1, 5, 0.05, 5)));
    let res = simulate(&d);
    res.write(&dir.join("a"), &d).unwrap();
    let poses = [[0.0, 0.1, 0.5], [0.7, 0.3, -0.8], [-1.2, 0.45, 1.3], [2.0, 0.2, -1.5]];
    let mut val = String::new();
    for (i, q0) in poses.iter().enumerate() {
        let f = dir.join(format!("pose_{}.csv", i + 1));
        static_pose(&res.setup.truth, q0, 5.0, 100 + i as u64).write(&f).unwrap();
        val.push_str(&format!(
            "[[validation]]\nname = \"pose_{}\"\nfiles = [\"pose_{}.csv\"]\nkind = \"static\"\n",
            i + 1,
            i + 1
        ));
    }
    let h = head(robot);
    let text = format!("{h}[[experiment]]\nname = \"a\"\nfiles = [\"a\"]\nharmonics = 40\n{val}");
    let r = study(dir, &text);
    let out = dir.join("out");
    r.write(&out, None).unwrap();
    let fc = [1.5, 4.0, 0.3];
    for (i, v) in r.estimate.validation.iter().enumerate() {
        assert_eq!(v.kind, idexp::ident::study::ExperimentKind::Static);
        // at rest the prediction is gravity: e_j near the noise's mean |ε| = 0.05·√(2/π) = 0.04
        for j in 0..3 {
            assert!(v.errors_all.e[j] < 0.1, "{}: e_{} = {} N·m", v.name, j + 1, v.errors_all.e[j]);
        }
        let csv = out.join("validation").join(format!("{}.csv", v.name));
        let e = e_from_csv(&csv, 3, "tau_ls");
        for j in 0..3 {
            assert!(
                (e[j] - v.errors_all.e[j]).abs() < 1e-9 * (1.0 + e[j]),
                "{} joint {}: {} vs {}",
                v.name,
                j + 1,
                e[j],
                v.errors_all.e[j]
            );
        }
        // validation.csv says the same
        let vt = std::fs::read_to_string(out.join("validation.csv")).unwrap();
        let row = vt.lines().find(|l| l.starts_with(&format!("pose_{},static,1,", i + 1))).unwrap();
        let ev: f64 = row.split(',').nth(3).unwrap().parse().unwrap();
        assert!((ev - e[0]).abs() < 1e-9 * (1.0 + ev), "{ev} vs {}", e[0]);
    }
    // without the dead band the Coulomb term takes the noise's sign: ±F_c flips every sample
    let r0 = study(dir, &format!("dead_band = 0.0\n{text}"));
    for v in &r0.estimate.validation {
        for j in 0..3 {
            assert!(
                v.errors_all.e[j] > 0.5 * fc[j],
                "{} joint {}: e = {} without the dead band",
                v.name,
                j + 1,
                v.errors_all.e[j]
            );
        }
    }
    // the poses as an experiment: a static run has no speed rule (its rows are kept,
    // Coulomb 0 within the dead band), and the estimate stays within its uncertainty
    let exp: String = val.replace("[[validation]]", "[[experiment]]").replace("name = \"pose_", "name = \"rest_");
    let rs = study(dir, &format!("{h}[[experiment]]\nname = \"a\"\nfiles = [\"a\"]\nharmonics = 40\n{exp}"));
    for x in rs.estimate.experiments.iter().skip(1) {
        assert!(x.rows_used.iter().all(|u| u.used == u.total), "{}: {:?}", x.name, x.rows_used);
        assert!(x.rows_used[0].reason.contains("dead band"), "{}", x.rows_used[0].reason);
    }
    let zmax = rs.estimate.truth.as_ref().unwrap().iter().map(|t| t.z.abs()).fold(0.0, f64::max);
    assert!(zmax < 4.0, "max |z| = {zmax}:\n{}", rs.estimate.text());
}

/// Link masses and traces of the inertia about the COM of standard parameters `th` (names `names`).
fn masses_and_traces(names: &[String], th: &[f64], links: usize) -> Vec<(f64, f64)> {
    let v = |k: String| th[names.iter().position(|n| *n == k).unwrap()];
    (1..=links)
        .map(|l| {
            let m = v(format!("M{l}"));
            let c2 = (v(format!("MX{l}")).powi(2) + v(format!("MY{l}")).powi(2) + v(format!("MZ{l}")).powi(2)) / (m * m);
            (m, v(format!("XX{l}")) + v(format!("YY{l}")) + v(format!("ZZ{l}")) - 2.0 * m * c2)
        })
        .collect()
}

#[test]
fn a_geared_arm_whose_robot_file_does_not_know_its_drives_gets_plausible_links() {
    // designs/sim_geared3_fourier.toml: the truth has reflected rotor inertias of
    // 1.5–4 kg·m² and friction; the study's robot file has ia = fc = fv = 0
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path();
    for (name, file) in [("a", "designs/sim_geared3_fourier.toml"), ("v", "designs/sim_geared3_validate.toml")] {
        let text = std::fs::read_to_string(root(file))
            .unwrap()
            .replace("robots/geared3.toml", "designs/robots/geared3.toml");
        let d = design(&text);
        simulate(&d).write(&dir.join(name), &d).unwrap();
    }
    let truth = idexp::data::Truth::read(&dir.join("a/truth.json")).unwrap();
    let text = format!(
        "robot = \"{}\"\ntruth = \"a/truth.json\"\n[[experiment]]\nname = \"a\"\nfiles = [\"a\"]\nharmonics = 20\n[[validation]]\nname = \"v\"\nfiles = [\"v\"]\nharmonics = 20\n[consistent]\n",
        root("designs/robots/geared3_unknown_drives.toml").display()
    );
    let true_links = masses_and_traces(&truth.names, &truth.theta, 3);
    let r = study(dir, &text);
    let c = r.estimate.consistent.as_ref().unwrap();
    assert!(c.status.is_ok(), "{:?}", c.status);
    let links = masses_and_traces(&c.standard_names, &c.standard, 3);
    for (l, ((m, tr), (m0, tr0))) in links.iter().zip(&true_links).enumerate() {
        assert!((0.5..=2.0).contains(&(m / m0)), "link {}: mass {m} vs {m0}\n{}", l + 1, r.estimate.text());
        assert!((0.5..=2.0).contains(&(tr / tr0)), "link {}: tr I_c {tr} vs {tr0}\n{}", l + 1, r.estimate.text());
    }
    // every drive parameter is unknown, listed, and the data decide it: the
    // rotor inertias within 10 % of the truth
    let unknown: Vec<&str> = c.unknown.iter().map(|u| u.name.as_str()).collect();
    assert_eq!(unknown, ["Ia1", "Fc1", "Fv1", "Ia2", "Fc2", "Fv2", "Ia3", "Fc3", "Fv3"]);
    for u in &c.unknown {
        let t = truth.theta[truth.names.iter().position(|n| *n == u.name).unwrap()];
        assert!(u.std_data.is_finite(), "{}", u.name);
        if u.name.starts_with("Ia") {
            assert!((u.value - t).abs() < 0.1 * t, "{}: {} vs {t}", u.name, u.value);
        }
    }
    let report = r.estimate.text();
    assert!(report.contains("drive parameters without a known value") && report.contains("Ia2"), "{report}");
    // the former default (every zero pulled to 0) pushes the rotor inertias into the links
    let old = study(dir, &text.replace("[consistent]\n", "[consistent]\nunknown = \"none\"\n"));
    let oc = old.estimate.consistent.as_ref().unwrap();
    assert!(oc.unknown.is_empty());
    let ol = masses_and_traces(&oc.standard_names, &oc.standard, 3);
    assert!(ol.iter().zip(&true_links).any(|((_, tr), (_, tr0))| tr / tr0 > 2.0), "{ol:?} vs {true_links:?}");
    // a link parameter cannot be unknown; a name that is not a parameter is refused
    for (list, what) in [("[\"M2\"]", "link inertial"), ("[\"Ia9\"]", "not a parameter")] {
        let p = dir.join("bad.toml");
        std::fs::write(&p, text.replace("[consistent]\n", &format!("[consistent]\nunknown = {list}\n"))).unwrap();
        let d = StudyDesign::read(&p).unwrap();
        let e = run_study(&d, dir, &Control::new()).unwrap_err().to_string();
        assert!(e.contains("unknown") && e.contains(what), "{e}");
    }
}

#[test]
fn exported_robot_toml_alone_carries_the_identified_inertials_through_a_urdf_written_beside_it() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path();
    let robot = "tests/data/rxz_chain.urdf";
    sim(dir, "a", robot, &fourier(3, 11, 3, 0.1, 5, 0.05, 5));
    let text = format!(
        "robot = \"{}\"\nexport = [\"toml\"]\n[[experiment]]\nname = \"a\"\nfiles = [\"a\"]\nharmonics = 20\n[consistent]\nmetric = \"euclidean\"\n",
        root(robot).display()
    );
    let r = study(dir, &text);
    let c = r.estimate.consistent.as_ref().unwrap();
    assert!(c.status.is_ok(), "{:?}", c.status);
    let out = dir.join("out");
    r.write(&out, None).unwrap();
    // robot.toml points at the URDF written beside it, not at the input URDF
    let toml_text = std::fs::read_to_string(out.join("robot.toml")).unwrap();
    let table: toml::Table = toml_text.parse().unwrap();
    assert_eq!(table["urdf"].as_str(), Some("robot.urdf"), "{toml_text}");
    // loaded by idexp: the identified standard parameters (within print precision)
    let back = idexp::robot::load(&out.join("robot.toml")).unwrap();
    let th = back.nominal_params();
    assert_eq!(back.param_names(), c.standard_names);
    for (j, (a, b)) in th.iter().zip(&c.standard).enumerate() {
        assert!((a - b).abs() < 1e-9 * (1.0 + b.abs()), "{}: {a} vs {b}", c.standard_names[j]);
    }
    // the URDF it points to, read by urdf-rs: every link's mass is the identified one
    let u = urdf_rs::read_file(out.join("robot.urdf")).unwrap();
    for (l, link) in c.links.iter().enumerate() {
        let ul = u
            .links
            .iter()
            .find(|x| x.name == link.link)
            .unwrap_or_else(|| panic!("{} in robot.urdf", link.link));
        assert!(
            (ul.inertial.mass.value - link.mass[0]).abs() < 1e-9 * link.mass[0],
            "link {}: {} vs {}",
            l + 1,
            ul.inertial.mass.value,
            link.mass[0]
        );
    }
    assert!(
        c.links.iter().any(|l| (l.mass[0] - l.mass[1]).abs() > 1e-3 * l.mass[1]),
        "every mass at its nominal value"
    );
}
