//! Drive gains calibrated with a known mass (`[gains]` of a payload design,
//! `idexp::payload::gains`): a simulated UR5 logging currents whose robot
//! file's gains are ±15 % off the simulated drives, with friction, noise, a
//! 4 ms delay of the currents and one wrong current sign; checked against the
//! simulated truth (gains, delay, the robot's masses) and by weighing a
//! second, unknown payload with the calibrated gains. A joint that stands
//! still is named and keeps its gain.

mod ident_util;

use ident_util::{design, root, simulate};
use idexp::optim::Control;
use idexp::payload::gains::{calibrate, GainsEstimate};
use idexp::payload::PayloadDesign;
use std::path::{Path, PathBuf};

/// The simulated drives' gains (joint side, s·k_t·N, N·m/A).
const TRUE_KT: [f64; 6] = [0.125, 0.125, 0.125, 0.092, 0.092, 0.092];
const N: f64 = 101.0;
/// The robot file's k_t: ±15 % off.
const FILE_FACTOR: [f64; 6] = [1.15, 0.85, 1.15, 0.85, 1.15, 0.85];

/// The UR5 robot file with torque constants `kt` and current signs `sign`, written to `dir/name`.
fn ur5_with_gains(dir: &Path, name: &str, kt: &[f64], sign: &[f64]) -> PathBuf {
    let src = std::fs::read_to_string(root("designs/robots/ur5.toml")).unwrap();
    let robots = root("designs/robots");
    let mut out = String::new();
    let mut j = 0;
    for line in src.lines() {
        if line.starts_with("urdf =") {
            out.push_str(&format!("urdf = \"{}\"\n", robots.join("ur5.urdf").display()));
        } else if line.starts_with("mesh_path") {
            out.push_str(&format!("mesh_path = [\"{}\"]\n", robots.join("meshes/ur5").display()));
        } else if line.starts_with("gear_ratio") {
            out.push_str(&format!("{line}\ntorque_constant = {}\ncurrent_sign = {}\n", kt[j], sign[j]));
            j += 1;
        } else {
            out.push_str(line);
            out.push('\n');
        }
    }
    assert_eq!(j, 6);
    let p = dir.join(name);
    std::fs::write(&p, out).unwrap();
    p
}

const MASS: f64 = 2.0;
const KNOWN: &str = "[payload]\nframe = \"tool0\"\nmass = 2.0\ncom = [0.05, -0.04, 0.06]\ninertia = [0.004, 0.0, 0.0, 0.004, 0.0, 0.003]\n";
const UNKNOWN: &str = "[payload]\nframe = \"tool0\"\nmass = 1.3\ncom = [-0.015, 0.01, 0.07]\ninertia = [0.003, 0.0002, 0.0, 0.0035, 0.0, 0.002]\n";

/// A 50 s current-logging run at 100 Hz (5 periods of 10 s, 1 kHz control) of the
/// true robot (its model 10 % off the file's, seed 7), the currents 4 ms behind.
fn run(dir: &Path, robot: &Path, name: &str, payload: &str, traj_seed: u64, seed: u64, reference: Option<&Path>) -> PathBuf {
    run_with_noise(dir, robot, name, payload, traj_seed, seed, reference, NOISE)
}

/// The acceptance case's noise (`[noise]` table).
const NOISE: &str = "torque = 0.2\nposition = 1e-5";

/// [`run`] with the `[noise]` table's body `noise`; `noise` may end in
/// further top-level keys after a line `#top` (e.g. `current_offset`).
#[allow(clippy::too_many_arguments)]
fn run_with_noise(dir: &Path, robot: &Path, name: &str, payload: &str, traj_seed: u64, seed: u64, reference: Option<&Path>, noise: &str) -> PathBuf {
    run_at(dir, robot, name, payload, traj_seed, seed, reference, noise, 10)
}

/// [`run_with_noise`] logged every `decimate`-th millisecond (10: 100 Hz; 2: 500 Hz, the RTDE rate of a UR e-Series).
#[allow(clippy::too_many_arguments)]
fn run_at(dir: &Path, robot: &Path, name: &str, payload: &str, traj_seed: u64, seed: u64, reference: Option<&Path>, noise: &str, decimate: usize) -> PathBuf {
    let (noise, top) = noise.split_once("#top\n").unwrap_or((noise, ""));
    let reference = match reference {
        Some(f) => format!("[reference]\nkind = \"fourier\"\nfile = \"{}\"\n", f.display()),
        None => format!("[reference]\nkind = \"random_fourier\"\nn_h = 4\nfrequency = 0.1\namplitude = 0.6\nseed = {traj_seed}\n"),
    };
    let text = format!(
        "name = \"{name}\"\nrobot = \"{}\"\nrate = 1000.0\ndecimate = {decimate}\nrepetitions = 5\nseed = {seed}\nrecord = \"current\"\ndrive_delay = 0.004\n{top}\n[truth]\nperturbation = 0.1\nseed = 7\n[controller]\nbandwidth = 10.0\n[noise]\n{noise}\n{reference}{payload}",
        robot.display()
    );
    let d = design(&text);
    let res = simulate(&d);
    let out = dir.join(name);
    res.write(&out, &d).unwrap();
    out
}

fn gains_design(dir: &Path, robot: &Path, loaded: &str, unloaded: &str, extra: &str) -> PayloadDesign {
    gains_design_h(dir, robot, loaded, unloaded, extra, 4)
}

/// [`gains_design`] whose Fourier filter keeps `h` harmonics of both runs.
fn gains_design_h(dir: &Path, robot: &Path, loaded: &str, unloaded: &str, extra: &str, h: usize) -> PayloadDesign {
    let text = format!(
        "name = \"g\"\nrobot = \"{}\"\nframe = \"tool0\"\n[gains]\nmass = {MASS}\n{extra}\n[[loaded]]\nname = \"{loaded}\"\nfiles = [\"{loaded}\"]\nharmonics = {h}\n[[unloaded]]\nname = \"{unloaded}\"\nfiles = [\"{unloaded}\"]\nharmonics = {h}\n",
        robot.display()
    );
    let p = dir.join(format!("gains_{loaded}_{h}.toml"));
    std::fs::write(&p, text).unwrap();
    PayloadDesign::read(&p).unwrap_or_else(|e| panic!("{e}"))
}

fn truth_base(run: &Path) -> (Vec<String>, Vec<f64>) {
    let t: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(run.join("truth.json")).unwrap()).unwrap();
    let names = t["base_names"].as_array().unwrap().iter().map(|v| v.as_str().unwrap().to_string()).collect();
    let vals = t["base"].as_array().unwrap().iter().map(|v| v.as_f64().unwrap()).collect();
    (names, vals)
}

#[test]
fn gains_off_by_15_percent_a_4ms_delay_and_a_wrong_sign_are_calibrated_and_weigh_an_unknown_payload() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let true_kt: Vec<f64> = TRUE_KT.to_vec();
    let file_kt: Vec<f64> = TRUE_KT.iter().zip(FILE_FACTOR).map(|(k, f)| k * f).collect();
    let sim_robot = ur5_with_gains(d, "true.toml", &true_kt, &[1.0; 6]);
    // the file also has wrist_1's current sign wrong
    let file_robot = ur5_with_gains(d, "file.toml", &file_kt, &[1.0, 1.0, 1.0, -1.0, 1.0, 1.0]);
    // current-sensor offsets (A, logged minus true), the same in both runs
    let offsets = [0.05, -0.08, 0.03, 0.1, -0.06, 0.04];
    let with_offsets = format!("{NOISE}\n#top\ncurrent_offset = {offsets:?}");
    run_with_noise(d, &sim_robot, "loaded", KNOWN, 5, 11, None, &with_offsets);
    run_with_noise(d, &sim_robot, "unloaded", "", 6, 12, None, &with_offsets);
    let design = gains_design(d, &file_robot, "loaded", "unloaded", "");
    let g: GainsEstimate = calibrate(&design, d, &Control::new()).unwrap_or_else(|e| panic!("{e}"));
    eprintln!("{}", g.text());
    let text = g.text();
    for (j, jg) in g.joints.iter().enumerate() {
        let truth = TRUE_KT[j] * N;
        // the joints the mass's gravity loads (shoulder lift, elbow, wrists 1 and 2) must be determined
        if (1..=4).contains(&j) {
            assert!(jg.determined, "joint {j} not determined: {:?}", jg.reason);
        }
        if jg.determined {
            let err = (jg.gain.abs() - truth) / truth;
            eprintln!("joint {j}: gain {:.4} ± {:.4}, true {truth:.4}: {:+.3} %", jg.gain, jg.std, 100.0 * err);
            assert!(err.abs() < 0.01, "joint {j}: |gain| {} vs true {truth}: {:.3} %", jg.gain, 100.0 * err);
            assert!(
                (jg.gain.abs() - truth).abs() < 3.0 * jg.std,
                "joint {j}: error {} > 3σ = {}",
                jg.gain.abs() - truth,
                3.0 * jg.std
            );
        } else {
            assert_eq!(jg.gain, file_kt[j] * N, "joint {j} keeps the file's gain");
            assert!(text.contains(&format!("  {}: ", jg.joint)), "joint {j} named: {text}");
        }
        assert_eq!(jg.sign_flipped, j == 3, "joint {j}'s sign");
        // the logged currents' offset (the wrong sign is the file's, not the log's)
        let (o, so) = jg.offset.expect("offsets estimated (no F0 in the UR5's friction)");
        let want = offsets[j];
        eprintln!("joint {j}: current offset {o:+.4} ± {so:.4} A, true {want:+.4} A");
        assert!((o - want).abs() < 3.0 * so, "joint {j}: offset {o} A vs true {want} A (σ {so})");
    }
    // the unloaded robot's base parameters (on the UR5 no link mass is one: the
    // masses enter as first moments m·c) against the simulated truth
    let (tn, tv) = truth_base(&d.join("unloaded")); // the robot without the weight
    let mut within = 0;
    for (name, v, sd) in &g.base {
        let i = tn.iter().position(|x| x == name).unwrap_or_else(|| panic!("{name} not in the truth"));
        assert!((v - tv[i]).abs() < 3.0 * sd, "{name}: {v} vs true {} (σ {sd})", tv[i]);
        within += usize::from((v - tv[i]).abs() < *sd);
    }
    eprintln!("base parameters within 1σ of the truth: {within} of {}", g.base.len());
    // robot.toml with the calibrated gains (and the sign corrected) loads and carries them
    let out = d.join("out_g");
    g.write(&design, &out, None).unwrap();
    let cal = idexp::robot::load(&out.join("robot.toml")).unwrap();
    for (j, dr) in cal.drives.iter().enumerate() {
        let k = dr.torque_per_ampere().unwrap();
        let want = if g.joints[j].determined { TRUE_KT[j] * N } else { file_kt[j] * N };
        assert!(((k - want) / want).abs() < 0.01, "robot.toml joint {j}: {k} vs {want}");
    }
    // step 2: an unknown payload weighed with the calibrated gains (and, for contrast, the file's)
    run(d, &sim_robot, "p2", UNKNOWN, 5, 21, None);
    run(d, &sim_robot, "p2_unloaded", "", 5, 22, None);
    let m_cal = weigh(d, &out.join("robot.toml"));
    // the file's gains with the sign corrected: only the magnitudes' ±15 % remain
    let m_file = weigh(d, &ur5_with_gains(d, "file_signed.toml", &file_kt, &[1.0; 6]));
    eprintln!("unknown payload 1.3 kg: {m_cal:.4} kg with the calibrated gains, {m_file:.4} kg with the file's");
    assert!(((m_cal - 1.3) / 1.3).abs() < 0.01, "calibrated: {m_cal}");
}

/// In `d`: the true and the file's robot (gains ±15 % off, signs right)
/// and the shipped gains excitation designed by the command line
/// (`idexp payload excite designs/gains_ur5_excite.toml`): its coefficients.json.
fn with_the_gains_excitation(d: &Path) -> (PathBuf, PathBuf, PathBuf) {
    let file_kt: Vec<f64> = TRUE_KT.iter().zip(FILE_FACTOR).map(|(k, f)| k * f).collect();
    let sim_robot = ur5_with_gains(d, "true.toml", &TRUE_KT, &[1.0; 6]);
    let file_robot = ur5_with_gains(d, "file.toml", &file_kt, &[1.0; 6]);
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_idexp"))
        .args(["payload", "excite"])
        .arg(root("designs/gains_ur5_excite.toml"))
        .arg("--out")
        .arg(d.join("excite"))
        .env("IDEXP_NO_PROGRESS", "1")
        .output()
        .unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    (sim_robot, file_robot, d.join("excite/coefficients.json"))
}

/// The unknown payload's mass from the runs `p2` (with it) and `p2_unloaded` in `d`, with the drives of `robot`.
fn weigh(d: &Path, robot: &Path) -> f64 {
    let text = format!(
        "name = \"p\"\nrobot = \"{}\"\nframe = \"tool0\"\n[[loaded]]\nname = \"p2\"\nfiles = [\"p2\"]\nharmonics = 4\n[[unloaded]]\nname = \"p2_unloaded\"\nfiles = [\"p2_unloaded\"]\nharmonics = 4\n",
        robot.display()
    );
    let p = d.join("p2.toml");
    std::fs::write(&p, text).unwrap();
    let pd = PayloadDesign::read(&p).unwrap();
    let e = idexp::payload::identify(&pd, d, &Control::new()).unwrap_or_else(|e| panic!("{e}"));
    e.payload.unwrap().mass
}

/// The whole acceptance case with the delay estimated: gains ±15 % off, the
/// known 2 kg mass, the acceptance noise (0.2 N·m, 1e-5 rad), friction,
/// current offsets and the currents 4 ms behind (3.5 ms against the
/// positions' sampling, see below), logged at 500 Hz (a UR e-Series' RTDE
/// rate). The loaded run plays the gains excitation
/// (`designs/gains_ur5_excite.toml`), the unloaded one a random Fourier
/// trajectory; both filtered at 20 harmonics (the closed loop's, see
/// [`the_designed_runs_closed_loop_harmonics_must_pass_the_filter`]).
/// Every gain within 1 % and 3σ, each run's delay within 0.5 ms, the
/// unloaded robot's base parameters within 3σ, and the unknown 1.3 kg
/// payload weighed with the calibrated gains within 1 %. At 100 Hz the
/// delay's σ is 0.5–0.7 ms per run (docs/payload.md), too wide to hold
/// 0.5 ms reliably; at 500 Hz it is 0.2 ms on the designed run and
/// 0.3–0.5 ms on the random one.
#[test]
fn the_acceptance_case_at_the_rtde_rate_with_the_designed_excitation_holds_the_delay() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let (sim_robot, file_robot, coefficients) = with_the_gains_excitation(d);
    let offsets = [0.05, -0.08, 0.03, 0.1, -0.06, 0.04];
    let noise = format!("{NOISE}\n#top\ncurrent_offset = {offsets:?}");
    run_at(d, &sim_robot, "loaded", KNOWN, 0, 11, Some(&coefficients), &noise, 2);
    run_at(d, &sim_robot, "unloaded", "", 6, 12, None, &noise, 2);
    let design = gains_design_h(d, &file_robot, "loaded", "unloaded", "delay = true", 20);
    let g = calibrate(&design, d, &Control::new()).unwrap_or_else(|e| panic!("{e}"));
    eprintln!("{}", g.text());
    for r in &g.runs {
        let (delay, std) = r.delay.expect("delay estimated");
        assert!(
            (delay - 0.0035).abs() < 0.0005,
            "{}: delay {:.3} ± {:.3} ms, true 3.5 ms",
            r.name,
            1e3 * delay,
            1e3 * std
        );
    }
    for (j, jg) in g.joints.iter().enumerate() {
        let truth = TRUE_KT[j] * N;
        assert!(jg.determined, "joint {j} not determined: {:?}", jg.reason);
        let err = jg.gain - truth;
        assert!(
            (err / truth).abs() < 0.01 && err.abs() < 3.0 * jg.std,
            "joint {j}: {} ± {} vs {truth}",
            jg.gain,
            jg.std
        );
    }
    let (tn, tv) = truth_base(&d.join("unloaded"));
    for (name, v, sd) in &g.base {
        let i = tn.iter().position(|x| x == name).unwrap_or_else(|| panic!("{name} not in the truth"));
        assert!((v - tv[i]).abs() < 3.0 * sd, "{name}: {v} vs true {} (σ {sd})", tv[i]);
    }
    let cal = d.join("out_cal");
    g.write(&design, &cal, None).unwrap();
    run(d, &sim_robot, "p2", UNKNOWN, 5, 21, None);
    run(d, &sim_robot, "p2_unloaded", "", 5, 22, None);
    let m = weigh(d, &cal.join("robot.toml"));
    assert!(((m - 1.3) / 1.3).abs() < 0.01, "unknown payload weighed {m} kg, true 1.3 kg");
}

/// The currents' delay against the simulated logs' own. The simulator logs
/// at controller period k the torque it commanded `drive_delay` = 4 periods
/// earlier, which drove the plant over [k − 4, k − 3] ms (zero-order hold),
/// and the position measured at the start of period k: the currents lag the
/// positions by 3.5 ms. Nearly without noise (0.01 N·m of torque noise, none
/// on the positions), so that the test sees the estimator's bias, not its
/// spread (σ 0.65–0.75 ms per 50 s run at the acceptance case's noise,
/// docs/payload.md): each run's delay within 0.5 ms. Reading the currents a
/// fraction of a sample later by a Fourier phase shift (the estimator before)
/// gave 1.65 and 2.04 ms here: the 100 Hz currents are sampled without an
/// anti-alias filter and carry Coulomb steps.
#[test]
fn the_currents_delay_is_estimated_within_half_a_millisecond() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let file_kt: Vec<f64> = TRUE_KT.iter().zip(FILE_FACTOR).map(|(k, f)| k * f).collect();
    let sim_robot = ur5_with_gains(d, "true.toml", &TRUE_KT, &[1.0; 6]);
    let file_robot = ur5_with_gains(d, "file.toml", &file_kt, &[1.0; 6]);
    let quiet = "torque = 0.01\nposition = 0.0";
    run_with_noise(d, &sim_robot, "quiet_loaded", KNOWN, 5, 11, None, quiet);
    run_with_noise(d, &sim_robot, "quiet_unloaded", "", 6, 12, None, quiet);
    let design = gains_design(d, &file_robot, "quiet_loaded", "quiet_unloaded", "delay = true");
    let g = calibrate(&design, d, &Control::new()).unwrap_or_else(|e| panic!("{e}"));
    for r in &g.runs {
        let (delay, std) = r.delay.expect("delay estimated");
        eprintln!("{}: delay {:.3} ± {:.3} ms (true 3.5 ms)", r.name, 1e3 * delay, 1e3 * std);
        assert!((delay - 0.0035).abs() < 0.0005, "{}: delay {delay} s, true 0.0035 s", r.name);
    }
    for (j, jg) in g.joints.iter().enumerate().filter(|(_, jg)| jg.determined) {
        let truth = TRUE_KT[j] * N;
        assert!(((jg.gain - truth) / truth).abs() < 0.01, "joint {j}: {} vs {truth}", jg.gain);
    }
}

/// The run of the shipped gains excitation (`designs/gains_ur5_excite.toml`,
/// 4 harmonics at 0.1 Hz), nearly noise-free: the closed loop (10 rad/s
/// position bandwidth, friction, the 2 kg mass) answers the designed motion
/// with harmonics above the 4th, and a Fourier filter at the reference's 4
/// harmonics takes them out of q̈ and q̇. That biased the wrists' gains by
/// 2–4 % and the delay by about 1 ms (a deterministic error, not noise);
/// with the filter at 20 harmonics every gain is within 0.3 % and the delay
/// within 0.5 ms. docs/payload.md, "An excitation for the gain calibration".
#[test]
fn the_designed_runs_closed_loop_harmonics_must_pass_the_filter() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let (sim_robot, file_robot, coefficients) = with_the_gains_excitation(d);
    let quiet = "torque = 0.01\nposition = 0.0";
    run_with_noise(d, &sim_robot, "designed", KNOWN, 0, 11, Some(&coefficients), quiet);
    run_with_noise(d, &sim_robot, "random", "", 6, 12, None, quiet);
    let mut worst = Vec::new();
    for h in [4, 20] {
        let g = calibrate(&gains_design_h(d, &file_robot, "designed", "random", "delay = true", h), d, &Control::new()).unwrap_or_else(|e| panic!("{e}"));
        let err: Vec<f64> = (0..6).map(|j| (g.joints[j].gain - TRUE_KT[j] * N) / (TRUE_KT[j] * N)).collect();
        // the larger delay error of the two runs (the designed one is the worse)
        let delay = g
            .runs
            .iter()
            .map(|r| r.delay.expect("delay estimated").0)
            .fold(0.0035, |a: f64, x| if (x - 0.0035).abs() > (a - 0.0035).abs() { x } else { a });
        eprintln!(
            "{h} harmonics: gain errors {:?} %, worst run's delay {:.3} ms (true 3.5 ms)",
            err.iter().map(|e| format!("{:+.2}", 100.0 * e)).collect::<Vec<_>>(),
            1e3 * delay
        );
        assert!(g.joints.iter().all(|jg| jg.determined), "{h} harmonics: {}", g.text());
        worst.push((err.iter().fold(0.0f64, |a, e| a.max(e.abs())), (delay - 0.0035).abs()));
    }
    // at the reference's harmonics the filter's error dominates; with 20 it is gone
    assert!(worst[0].0 > 0.01 && worst[0].1 > 0.0005, "4 harmonics: {:?}", worst[0]);
    assert!(worst[1].0 < 0.003 && worst[1].1 < 0.0005, "20 harmonics: {:?}", worst[1]);
}

/// A simulation whose reference is a random Fourier trajectory (seed `seed`), only to take its coefficients.
fn design_text_reference(robot: &Path, seed: u64) -> idexp::sim::SimDesign {
    design(&format!(
        "name = \"r\"\nrobot = \"{}\"\nrate = 1000.0\nrepetitions = 1\n[controller]\nbandwidth = 5.0\n[reference]\nkind = \"random_fourier\"\nn_h = 4\nfrequency = 0.1\namplitude = 0.6\nseed = {seed}\n",
        robot.display()
    ))
}

#[test]
fn a_joint_the_mass_does_not_load_is_named_and_keeps_its_gain() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let true_kt: Vec<f64> = TRUE_KT.to_vec();
    let file_kt: Vec<f64> = TRUE_KT.iter().zip(FILE_FACTOR).map(|(k, f)| k * f).collect();
    let sim_robot = ur5_with_gains(d, "true.toml", &true_kt, &[1.0; 6]);
    let file_robot = ur5_with_gains(d, "file.toml", &file_kt, &[1.0; 6]);
    // the trajectories without the vertical first axis's rotation
    let mut paths = Vec::new();
    for (name, seed) in [("fixed_loaded", 5), ("fixed_unloaded", 6)] {
        let r = simulate(&design_text_reference(&sim_robot, seed));
        let mut t = r.setup.reference.fourier().unwrap().clone();
        t.a[0].iter_mut().for_each(|v| *v = 0.0);
        t.b[0].iter_mut().for_each(|v| *v = 0.0);
        let p = d.join(format!("{name}.json"));
        std::fs::write(&p, serde_json::to_string(&t).unwrap()).unwrap();
        paths.push(p);
    }
    run(d, &sim_robot, "fixed_loaded", KNOWN, 0, 11, Some(&paths[0]));
    run(d, &sim_robot, "fixed_unloaded", "", 0, 12, Some(&paths[1]));
    let design = gains_design(d, &file_robot, "fixed_loaded", "fixed_unloaded", "");
    let g = calibrate(&design, d, &Control::new()).unwrap_or_else(|e| panic!("{e}"));
    let text = g.text();
    eprintln!("{text}");
    let j1 = &g.joints[0];
    assert!(!j1.determined, "joint 1 should not be determined: {j1:?}");
    assert_eq!(j1.gain, file_kt[0] * N, "joint 1 keeps the file's gain");
    assert!(text.contains("Not determined") && text.contains("shoulder_pan_joint:"), "{text}");
    for (j, jg) in g.joints.iter().enumerate().skip(1) {
        if jg.determined {
            let truth = TRUE_KT[j] * N;
            assert!((jg.gain - truth).abs() < 3.0 * jg.std, "joint {j}: {} vs {truth} (σ {})", jg.gain, jg.std);
        }
    }
    let out = d.join("out_fixed");
    g.write(&design, &out, None).unwrap();
    let cal = idexp::robot::load(&out.join("robot.toml")).unwrap();
    assert_eq!(cal.drives[0].torque_per_ampere().unwrap(), file_kt[0] * N);
}

#[test]
fn bad_gains_tables_are_errors_naming_the_field() {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("bad.toml");
    for (extra, field) in [
        ("mass = -1.0", "gains.mass"),
        ("mass = 2.0\nmax_std = 0.0", "gains.max_std"),
        ("mass = 2.0\nbogus = 1", "bogus"),
        ("mass = 2.0\n[[gains.compare]]\nname = \"x\"", "gains.compare[0]"),
        (
            "mass = 2.0\n[[gains.compare]]\nname = \"x\"\nvalues = [1.0]\nrtde = \"r.csv\"",
            "gains.compare[0]",
        ),
    ] {
        std::fs::write(
            &p,
            format!(
                "robot = \"{}\"\n[gains]\n{extra}\n[[loaded]]\nfiles = [\"a\"]\n[[unloaded]]\nfiles = [\"b\"]\n",
                root("designs/robots/ur5.toml").display()
            ),
        )
        .unwrap();
        let e = PayloadDesign::read(&p).unwrap_err().to_string();
        assert!(e.contains(field) && e.contains("bad.toml"), "{extra}: {e}");
    }
    std::fs::write(
        &p,
        format!(
            "robot = \"{}\"\n[gains]\nmass = 2.0\n[[loaded]]\nfiles = [\"a\"]\n",
            root("designs/robots/ur5.toml").display()
        ),
    )
    .unwrap();
    let e = PayloadDesign::read(&p).unwrap_err().to_string();
    assert!(e.contains("unloaded"), "{e}");
}

#[test]
fn bad_current_offsets_are_errors_naming_the_field() {
    let robot = root("designs/gains_ur5_robot_true.toml");
    for (extra, want) in [
        ("current_offset = [0.1, 0.0, 0.0, 0.0, 0.0, 0.0]", "record"),
        ("record = \"current\"\ncurrent_offset = [0.1, 0.0]", "2 offsets for the 6 joints"),
    ] {
        let text = format!(
            "name = \"x\"\nrobot = \"{}\"\n{extra}\n[reference]\nkind = \"random_fourier\"\nn_h = 2\nfrequency = 0.1\namplitude = 0.3\nseed = 1\n",
            robot.display()
        );
        let d: idexp::sim::SimDesign = idexp::io::parse_toml(Path::new("bad_sim.toml"), &text).unwrap();
        let e = d
            .validate("bad_sim.toml")
            .and_then(|_| idexp::sim::SimSetup::from_design(&d, &root(""), "bad_sim.toml").map(|_| ()))
            .unwrap_err()
            .to_string();
        assert!(e.contains("current_offset") && e.contains("bad_sim.toml") && e.contains(want), "{extra}: {e}");
    }
}

/// An RTDE recording as Universal Robots' `record.py` writes it (space
/// separated, `timestamp` the controller's uptime), with target torques
/// `ratio[j]` × target currents (+ `zero`: a joint whose target current is 0).
fn rtde_csv(path: &Path, ratio: &[f64], zero: Option<usize>) {
    let mut h = vec!["timestamp".to_string()];
    for what in ["actual_q", "actual_qd", "target_moment", "target_current", "actual_current"] {
        h.extend((0..6).map(|j| format!("{what}_{j}")));
    }
    let mut text = h.join(" ") + "\n";
    for k in 0..200 {
        let t = 8123.456 + 0.008 * k as f64;
        let cur: Vec<f64> = (0..6)
            .map(|j| {
                if zero == Some(j) {
                    0.0
                } else {
                    0.8 * (0.3 * k as f64 + j as f64).sin() + 0.05 * j as f64
                }
            })
            .collect();
        let mut row = vec![format!("{t:.3}")];
        row.extend((0..6).map(|j| format!("{}", 0.1 * j as f64 + 0.001 * k as f64)));
        row.extend((0..6).map(|_| "0.01".to_string()));
        row.extend((0..6).map(|j| format!("{:e}", ratio[j] * cur[j])));
        row.extend(cur.iter().map(|c| format!("{c:e}")));
        row.extend(cur.iter().map(|c| format!("{:e}", 1.01 * c)));
        text += &(row.join(" ") + "\n");
    }
    std::fs::write(path, text).unwrap();
}

#[test]
fn the_controllers_ratio_in_an_rtde_recording_is_a_compared_set() {
    let dir = tempfile::tempdir().unwrap();
    let robot = idexp::robot::load(&root("designs/gains_ur5_robot.toml")).unwrap();
    let ratio = [12.1, 12.4, -12.0, 9.0, 9.1, 9.2];
    let f = dir.path().join("rtde.csv");
    rtde_csv(&f, &ratio, None);
    let g = idexp::payload::gains::rtde_gains(&robot, &f).unwrap();
    for j in 0..6 {
        assert!((g[j] - ratio[j]).abs() < 1e-12 * ratio[j].abs(), "joint {j}: {} vs {}", g[j], ratio[j]);
    }
    // a joint without current: an error naming the file and the column
    let z = dir.path().join("rtde_zero.csv");
    rtde_csv(&z, &ratio, Some(2));
    let e = idexp::payload::gains::rtde_gains(&robot, &z).unwrap_err().to_string();
    assert!(
        e.contains("rtde_zero.csv") && e.contains("target_current_2") && e.contains("elbow_joint"),
        "{e}"
    );
    // a missing column: the reader's error naming it
    std::fs::write(&z, "timestamp actual_q_0\n0.0 0.1\n").unwrap();
    let e = idexp::payload::gains::rtde_gains(&robot, &z).unwrap_err().to_string();
    assert!(e.contains("rtde_zero.csv"), "{e}");
}
