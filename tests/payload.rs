//! Payload identification (`idexp::payload`, `idexp payload identify`):
//! simulated known payloads on a robot whose model is 10 % off, with and
//! without unloaded runs; the exports read back; what a planar arm cannot
//! sense; bad input.

mod ident_util;

use ident_util::{design, root, simulate};
use idexp::optim::Control;
use idexp::payload::{export, PayloadDesign, PayloadEstimate};
use idexp::robot::payload::{Mount, Payload};
use std::path::{Path, PathBuf};
use std::process::Command;

const TRUE_PAYLOAD: &str =
    "[payload]\nframe = \"tool0\"\nmass = 1.8\ncom = [0.012, -0.008, 0.055]\ninertia = [0.0065, 0.0004, -0.0003, 0.0071, 0.0005, 0.0042]\n";

/// A UR5 run (truth: the robot file's parameters perturbed by 10 %, seed 7)
/// tracking a random Fourier trajectory, 5 repetitions at 200 Hz, with or without the payload.
fn ur5_run(dir: &Path, name: &str, loaded: bool, seed: u64) -> PathBuf {
    let text = format!(
        "name = \"{name}\"\nrobot = \"designs/robots/ur5.toml\"\nrate = 1000.0\ndecimate = 5\nrepetitions = 5\nseed = {seed}\n[truth]\nperturbation = 0.1\nseed = 7\n[controller]\nbandwidth = 10.0\n[noise]\ntorque = 0.2\nposition = 1e-5\n[reference]\nkind = \"random_fourier\"\nn_h = 4\nfrequency = 0.1\namplitude = 0.6\nseed = 5\n{}",
        if loaded { TRUE_PAYLOAD } else { "" }
    );
    let d = design(&text);
    let res = simulate(&d);
    let out = dir.join(name);
    res.write(&out, &d).unwrap();
    out
}

fn payload_design(dir: &Path, differencing: bool) -> PayloadDesign {
    let robot = root("designs/robots/ur5.toml");
    let mut text = format!(
        "name = \"p\"\nrobot = \"{}\"\nframe = \"tool0\"\ntruth = \"loaded\"\n[guess]\nmass = 2.0\ncom = [0.0, 0.0, 0.06]\ninertia = [0.006, 0.0, 0.0, 0.006, 0.0, 0.004]\n[[loaded]]\nname = \"loaded\"\nfiles = [\"loaded\"]\nharmonics = 4\n",
        robot.display()
    );
    if differencing {
        text.push_str("[[unloaded]]\nname = \"unloaded\"\nfiles = [\"unloaded\"]\nharmonics = 4\n");
    }
    let p = dir.join("payload.toml");
    std::fs::write(&p, text).unwrap();
    PayloadDesign::read(&p).unwrap()
}

fn runs() -> tempfile::TempDir {
    let dir = tempfile::tempdir().unwrap();
    ur5_run(dir.path(), "loaded", true, 11);
    ur5_run(dir.path(), "unloaded", false, 12);
    dir
}

/// `idexp ARGS DESIGN --out OUT` without the progress bar.
fn idexp(args: &[&str], design: &Path, out: &Path) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_idexp"))
        .args(args)
        .arg(design)
        .arg("--out")
        .arg(out)
        .env("IDEXP_NO_PROGRESS", "1")
        .output()
        .unwrap()
}

fn com_error(p: &Payload, t: &Payload) -> f64 {
    (0..3).map(|k| (p.com[k] - t.com[k]).powi(2)).sum::<f64>().sqrt()
}

#[test]
fn known_payload_within_one_percent_and_two_millimetres_and_differencing_removes_the_model_error() {
    let dir = runs();
    let ctl = Control::new();
    let e: PayloadEstimate = idexp::payload::identify(&payload_design(dir.path(), true), dir.path(), &ctl).unwrap();
    let truth = e.truth.expect("truth read from the simulated run");
    assert_eq!(truth.mass, 1.8);
    let p = e.payload.expect("a payload");
    let sd = e.payload_std.clone().expect("every parameter identifiable on a six-axis arm");
    assert_eq!(e.structural.names.len(), 10);
    assert!((p.mass / truth.mass - 1.0).abs() < 0.01, "mass {} vs {}", p.mass, truth.mass);
    assert!(com_error(&p, &truth) < 0.002, "centre of mass off by {} m", com_error(&p, &truth));
    // the inertia within its reported uncertainty (3σ per entry)
    for k in 0..6 {
        let d = (p.inertia[k] - truth.inertia[k]).abs();
        assert!(
            d < 3.0 * sd.inertia[k] + 1e-5,
            "inertia entry {k}: {} vs {} (σ {})",
            p.inertia[k],
            truth.inertia[k],
            sd.inertia[k]
        );
    }
    // and the mass and centre within theirs
    assert!((p.mass - truth.mass).abs() < 4.0 * sd.mass);
    assert!(e.chi2_dof < 1.5, "χ²/dof {} with the model error cancelled", e.chi2_dof);

    // without the unloaded runs the robot model's 10 % error biases the payload
    let n = idexp::payload::identify(&payload_design(dir.path(), false), dir.path(), &ctl).unwrap();
    let q = n.payload.expect("a payload");
    let mass_err = (q.mass / truth.mass - 1.0).abs();
    assert!(
        mass_err > 0.02 || com_error(&q, &truth) > 0.005,
        "without differencing: mass error {mass_err}, centre error {}",
        com_error(&q, &truth)
    );
    assert!(mass_err > 5.0 * (p.mass / truth.mass - 1.0).abs());
    assert!(n.chi2_dof > 2.0, "the model error shows in χ²/dof: {}", n.chi2_dof);
    assert!(n.notes.iter().any(|s| s.contains("unloaded runs")));
}

/// A URScript grammar for the one statement written: name(number, [3 numbers], [6 numbers]).
fn parse_urscript(text: &str) -> Option<(f64, Vec<f64>, Vec<f64>)> {
    let stmt: Vec<&str> = text.lines().filter(|l| !l.trim().is_empty() && !l.trim_start().starts_with('#')).collect();
    if stmt.len() != 1 {
        return None;
    }
    let s = stmt[0].trim();
    let args = s.strip_prefix("set_target_payload(")?.strip_suffix(')')?;
    let (m, rest) = args.split_once(',')?;
    let rest = rest.trim();
    let list = |t: &str| -> Option<(Vec<f64>, String)> {
        let t = t.trim_start().strip_prefix('[')?;
        let (inner, after) = t.split_once(']')?;
        let v: Option<Vec<f64>> = inner.split(',').map(|x| x.trim().parse::<f64>().ok()).collect();
        Some((v?, after.to_string()))
    };
    let (cog, after) = list(rest)?;
    let (inertia, tail) = list(after.trim_start().strip_prefix(',')?)?;
    if !tail.trim().is_empty() || cog.len() != 3 || inertia.len() != 6 {
        return None;
    }
    Some((m.trim().parse().ok()?, cog, inertia))
}

#[test]
fn exports_read_back_to_the_identified_payload() {
    let p = Payload {
        mass: 1.8123,
        com: [0.0118, -0.0079, 0.0551],
        inertia: [0.0066, -0.0007, -0.0001, 0.0046, 0.0015, 0.0026],
    };
    // URScript: the statement parses and carries [Ixx, Iyy, Izz, Ixy, Ixz, Iyz]
    let ur = export::urscript(&p, "tool0", &["a header".into()]);
    let (m, cog, i) = parse_urscript(&ur).unwrap_or_else(|| panic!("not a set_target_payload statement:\n{ur}"));
    assert_eq!(m, p.mass);
    assert_eq!(cog, p.com.to_vec());
    assert_eq!(i, vec![p.inertia[0], p.inertia[3], p.inertia[5], p.inertia[1], p.inertia[2], p.inertia[4]]);
    assert!(parse_urscript("set_target_payload(1.0, [0, 0], [0,0,0,0,0,0])").is_none());
    // Franka: JSON with the keys of setLoad, inertia column-major
    let f: serde_json::Value = serde_json::from_str(&serde_json::to_string(&export::franka(&p, "tool0")).unwrap()).unwrap();
    assert_eq!(f["mass"].as_f64(), Some(p.mass));
    assert_eq!(f["F_x_Cload"][2].as_f64(), Some(p.com[2]));
    assert_eq!(f["load_inertia"][3].as_f64(), Some(p.inertia[1])); // (0, 1) in column 1
                                                                   // KUKA: principal axes re-composed give the tensor
    assert_eq!(f["frame"].as_str(), Some("tool0"));
    let k = export::parse_kuka(&export::kuka(&p, 3, "tool0", &[])).unwrap();
    assert_eq!(k.m, p.mass);
    assert!((k.xyz_mm[2] - 55.1).abs() < 1e-9);
    let t = export::tensor_from_kuka(k.abc_deg, k.j);
    assert!((t - p.inertia_matrix()).abs().max() < 1e-6 * p.inertia_matrix().abs().max());
    // URDF: a fixed payload link, read by urdf-rs
    let u = urdf_rs::read_from_string(&export::urdf(&p, "tool0", &["h -- x".into()])).unwrap();
    let link = u.links.iter().find(|l| l.name == "payload").unwrap();
    assert_eq!(link.inertial.mass.value, p.mass);
    assert_eq!(link.inertial.origin.xyz.0, p.com);
    assert_eq!(link.inertial.inertia.ixy, p.inertia[1]);
    assert_eq!(link.inertial.inertia.iyz, p.inertia[4]);
    let joint = u.joints.iter().find(|j| j.child.link == "payload").unwrap();
    assert_eq!(joint.parent.link, "tool0");
    assert!(matches!(joint.joint_type, urdf_rs::JointType::Fixed));
    // the URDF fragment's payload attached to the UR5 gives the same robot as Mount::attach
    let robot = idexp::robot::load(&root("designs/robots/ur5.toml")).unwrap();
    let mount = Mount::new(&robot, Some("tool0"), "test", "frame").unwrap();
    let phi = p.params();
    let back = Payload::from_params(&phi).unwrap();
    for k in 0..6 {
        assert!((back.inertia[k] - p.inertia[k]).abs() < 1e-15);
    }
    let loaded = mount.attach(&robot, &phi).unwrap();
    assert!((loaded.links[mount.link].inertial.mass - robot.links[mount.link].inertial.mass - p.mass).abs() < 1e-12);
}

const PLANAR: &str = "name = \"planar2r\"\ndh = \"standard\"\n[[joint]]\nname = \"j1\"\na = 0.5\nlower = -3.0\nupper = 3.0\nvelocity = 3.0\neffort = 100.0\ninertial = { mass = 4.0, com = [-0.25, 0.0, 0.0], inertia = [0.01, 0.0, 0.0, 0.08, 0.0, 0.08] }\n[[joint]]\nname = \"j2\"\na = 0.4\nlower = -3.0\nupper = 3.0\nvelocity = 3.0\neffort = 100.0\ninertial = { mass = 2.0, com = [-0.2, 0.0, 0.0], inertia = [0.005, 0.0, 0.0, 0.03, 0.0, 0.03] }\n";

#[test]
fn a_planar_arm_senses_fewer_than_ten_payload_parameters_and_says_which() {
    // two revolute joints with vertical axes: no gravity torque, motion in the horizontal plane
    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join("planar.toml");
    std::fs::write(&file, PLANAR).unwrap();
    let robot = idexp::robot::load(&file).unwrap();
    let mount = Mount::new(&robot, None, "test", "frame").unwrap();
    let st = idexp::payload::identify::structural(&robot, &mount).unwrap();
    // independently: the rank of the payload's columns Y_L T over random states
    let w = idexp::params::random_stack(&robot, 200, 3);
    let o = robot.link_param_offset(mount.link);
    let a = w.columns(o, 10) * mount.t;
    let rank = a.clone().svd(false, false).rank(1e-9 * a.norm());
    assert_eq!(st.names.len(), rank, "{:?}", st.names);
    assert_eq!(rank, 4, "in-plane: M, MX, MY and ZZ");
    let mut un = st.unidentifiable.clone();
    un.sort();
    assert_eq!(un, ["MZ", "XX", "XY", "XZ", "YY", "YZ"]);
    assert_eq!(st.k.nrows(), st.names.len());
    // on the UR5 all ten, each alone
    let ur5 = idexp::robot::load(&root("designs/robots/ur5.toml")).unwrap();
    let m5 = Mount::new(&ur5, Some("tool0"), "test", "frame").unwrap();
    let s5 = idexp::payload::identify::structural(&ur5, &m5).unwrap();
    assert_eq!(s5.independent, (0..10).collect::<Vec<_>>());
    assert!((s5.k.clone() - nalgebra::DMatrix::<f64>::identity(10, 10)).abs().max() < 1e-12);
}

#[test]
fn cli_identifies_writes_the_exports_and_rejects_bad_designs() {
    let dir = runs();
    let d = dir.path();
    let robot = root("designs/robots/ur5.toml");
    let good = format!(
        "robot = \"{}\"\nexport = [\"urscript\", \"kuka\"]\n[[loaded]]\nfiles = [\"loaded\"]\nharmonics = 4\n[[unloaded]]\nfiles = [\"unloaded\"]\nharmonics = 4\n",
        robot.display()
    );
    std::fs::write(d.join("tool.toml"), &good).unwrap();
    let out = d.join("out");
    let o = idexp(&["payload", "identify"], &d.join("tool.toml"), &out);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    for f in [
        "payload.json",
        "report.txt",
        "design.json",
        "payload.script",
        "kuka_load.txt",
        "status.json",
        "residuals.svg",
    ] {
        assert!(out.join(f).exists(), "{f} missing");
    }
    assert!(!out.join("payload.urdf").exists(), "only the exports asked for");
    let ur = std::fs::read_to_string(out.join("payload.script")).unwrap();
    let (m, _, _) = parse_urscript(&ur).unwrap();
    let json: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(out.join("payload.json")).unwrap()).unwrap();
    assert_eq!(json["payload"]["mass"].as_f64(), Some(m));
    let st: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(out.join("status.json")).unwrap()).unwrap();
    assert_eq!(st["status"], "complete");
    // the same files on one thread, byte for byte (status.json aside: its times)
    let out1 = d.join("out1");
    let o = idexp(&["--threads", "1", "payload", "identify"], &d.join("tool.toml"), &out1);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    for f in ["payload.json", "report.txt", "payload.script", "kuka_load.txt", "residuals.svg"] {
        assert_eq!(
            std::fs::read(out.join(f)).unwrap(),
            std::fs::read(out1.join(f)).unwrap(),
            "{f} differs between 2 threads and 1"
        );
    }

    // bad designs: exit 1, the file, the field and what is allowed named, no folder written
    let cases = [
        (
            good.replace(
                "[[unloaded]]\nfiles = [\"unloaded\"]\nharmonics = 4\n",
                "[[unloaded]]\nfiles = [\"unloaded\"]\n[[unloaded]]\nname = \"u2\"\nfiles = [\"unloaded\"]\n",
            ),
            "unloaded",
        ),
        (good.replace("export = [\"urscript\", \"kuka\"]", "export = [\"abb\"]"), "export"),
        (format!("{good}[guess]\nmass = -1.0\n"), "guess.mass"),
        (good.replace("robot = ", "frame = \"no_such_frame\"\nrobot = "), "no_such_frame"),
    ];
    for (i, (text, needle)) in cases.iter().enumerate() {
        let p = d.join(format!("bad{i}.toml"));
        std::fs::write(&p, text).unwrap();
        let bad_out = d.join(format!("bad_out{i}"));
        let o = idexp(&["payload", "identify"], &p, &bad_out);
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(1), "case {i}: {err}");
        assert!(err.contains(needle), "case {i}: `{needle}` not in {err}");
        assert!(!bad_out.exists(), "case {i}: a folder was written");
    }
    // payload excite refuses a design that does not excite a payload
    let o = idexp(&["payload", "excite"], &root("designs/excite_ur5.toml"), &d.join("ex"));
    assert_eq!(o.status.code(), Some(1));
    assert!(String::from_utf8_lossy(&o.stderr).contains("objective.columns = \"payload\""));
}

#[test]
fn what_a_planar_arm_cannot_sense_comes_from_the_guess() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let file = d.join("planar.toml");
    std::fs::write(&file, PLANAR).unwrap();
    let sim = format!(
        "name = \"planar\"\nrobot = \"{}\"\nrate = 1000.0\ndecimate = 5\nrepetitions = 5\nseed = 3\n[controller]\nbandwidth = 10.0\n[noise]\ntorque = 0.02\nposition = 1e-6\n[reference]\nkind = \"random_fourier\"\nn_h = 4\nfrequency = 0.1\namplitude = 0.6\nseed = 5\n[payload]\nmass = 1.5\ncom = [0.03, -0.02, 0.04]\ninertia = [0.004, 0.0, 0.0, 0.005, 0.0, 0.003]\n",
        file.display()
    );
    let sd = design(&sim);
    simulate(&sd).write(&d.join("loaded"), &sd).unwrap();
    let text = format!(
        "robot = \"{}\"\ntruth = \"loaded\"\n[guess]\nmass = 1.0\ncom = [0.0, 0.0, 0.07]\ninertia = [0.002, 0.0, 0.0, 0.002, 0.0, 0.002]\n[[loaded]]\nfiles = [\"loaded\"]\nharmonics = 4\n",
        file.display()
    );
    std::fs::write(d.join("p.toml"), text).unwrap();
    let pd = PayloadDesign::read(&d.join("p.toml")).unwrap();
    let e = idexp::payload::identify(&pd, d, &Control::new()).unwrap();
    assert_eq!(e.structural.names.len(), 4);
    assert!(e.payload_std.is_none(), "no σ of the whole payload when 6 parameters are unseen");
    let p = e.payload.expect("consistent with the guess");
    let t = e.truth.unwrap();
    // seen: the mass and the in-plane centre of mass
    assert!((p.mass / t.mass - 1.0).abs() < 0.01, "mass {}", p.mass);
    assert!((p.com[0] - t.com[0]).abs() < 0.002 && (p.com[1] - t.com[1]).abs() < 0.002, "{:?}", p.com);
    // unseen: the height of the centre of mass stays near the guess's, not the truth's
    assert!((p.com[2] - 0.07).abs() < 1e-3, "com z {} (guess 0.07, truth {})", p.com[2], t.com[2]);
    // and the seen combinations are the least-squares ones (the prior is consistent with them)
    let c = e.consistent.as_ref().unwrap();
    assert!(c.extra_cost < 1e-3, "extra weighted SSR {}", c.extra_cost);
    assert!(e.notes.iter().any(|n| n.contains("4 of the payload's 10")), "{:?}", e.notes);
    assert!(e.text().contains("no effect on the torques: "));
}

/// `idexp payload excite` on the shipped design with the proximal joints held
/// near the home pose (`limits.position_range`): every row of the delivered
/// trajectory inside the ranges, at rest at both ends, and the reported
/// condition number equal to one recomputed from trajectory.csv — the ten
/// columns of the link carrying tool0, taken from the robot's regressor,
/// unit-column scaled, nalgebra's SVD.
#[test]
fn payload_excitation_recomputed_from_its_trajectory_with_the_arm_held_near_home() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let shipped = std::fs::read_to_string(root("designs/payload_ur5_excite.toml")).unwrap();
    let range: [[f64; 2]; 6] = [[-0.15, 0.15], [-1.72, -1.42], [1.42, 1.72], [-4.0, 0.9], [-4.0, 0.9], [-3.0, 3.0]];
    let ranges = range.iter().map(|[a, b]| format!("[{a}, {b}]")).collect::<Vec<_>>().join(", ");
    let text = shipped
        .replace(
            "robot = \"robots/ur5.toml\"",
            &format!("robot = \"{}\"", root("designs/robots/ur5.toml").display()),
        )
        .replace("acceleration = 0.8\n", &format!("acceleration = 0.8\nposition_range = [{ranges}]\n"));
    assert!(
        text.contains("position_range") && !text.contains("\"robots/"),
        "the shipped design changed shape"
    );
    std::fs::write(d.join("wrist.toml"), &text).unwrap();
    let out = d.join("out");
    let o = idexp(&["payload", "excite"], &d.join("wrist.toml"), &out);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let st: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(out.join("status.json")).unwrap()).unwrap();
    assert_eq!(st["summary"]["safe_to_play"], true);
    let cond = st["summary"]["cond"].as_f64().unwrap();

    let csv = std::fs::read_to_string(out.join("trajectory.csv")).unwrap();
    let mut lines = csv.lines();
    let header: Vec<&str> = lines.next().unwrap().split(',').collect();
    let col = |name: &str| header.iter().position(|h| *h == name).unwrap();
    let rows: Vec<Vec<f64>> = lines.map(|l| l.split(',').map(|v| v.parse().unwrap()).collect()).collect();
    let (q, qd, qdd, seg) = (col("q1"), col("qd1"), col("qdd1"), col("segment"));
    for (i, r) in rows.iter().enumerate() {
        for (j, [lo, hi]) in range.iter().enumerate() {
            assert!(
                r[q + j] >= lo - 1e-9 && r[q + j] <= hi + 1e-9,
                "row {i}: q{} = {} outside [{lo}, {hi}]",
                j + 1,
                r[q + j]
            );
        }
    }
    for r in [&rows[0], &rows[rows.len() - 1]] {
        assert!((0..6).all(|j| r[qd + j].abs() < 1e-9 && r[qdd + j].abs() < 1e-9), "not at rest: {r:?}");
    }

    // the criterion's samples: period 1 at 10 Hz (every 100th row of the 1 kHz file)
    let robot = idexp::robot::load(&root("designs/robots/ur5.toml")).unwrap();
    let first = rows.iter().position(|r| r[seg] == 1.0).unwrap();
    let samples: Vec<&Vec<f64>> = rows[first..].iter().step_by(100).take_while(|r| r[seg] == 1.0).collect();
    assert_eq!(samples.len(), 100);
    let o = robot.link_param_offset(robot.dof() - 1);
    let p = robot.n_params();
    let mut ws = idexp::robot::Workspace::new(&robot);
    let mut y = nalgebra::DMatrix::zeros(6, p);
    let mut a = nalgebra::DMatrix::zeros(6 * samples.len(), 10);
    for (i, r) in samples.iter().enumerate() {
        idexp::robot::regressor(&robot, &mut ws, &r[q..q + 6], &r[qd..qd + 6], &r[qdd..qdd + 6], &mut y);
        a.view_mut((6 * i, 0), (6, 10)).copy_from(&y.columns(o, 10));
    }
    for mut c in a.column_iter_mut() {
        let n = c.norm();
        c /= n;
    }
    let sv = a.singular_values();
    let want = sv.max() / sv.min();
    assert!((cond - want).abs() < 1e-6 * want, "reported {cond}, recomputed {want}");
    // holding the arm costs a little (1.56 on the shipped design): still well conditioned
    assert!(cond < 2.5, "cond {cond}");
}

/// The rest-to-rest chain: the shipped payload excitation as a B-spline,
/// played (loaded and unloaded) by `idexp simulate` through `kind =
/// "states"` on a robot 10 % off its file, and `payload identify` with the
/// low-pass filter (a rest-to-rest run has no period for the Fourier
/// filter): mass within 1 %, centre of mass within 2 mm.
#[test]
fn a_rest_to_rest_payload_excitation_played_and_identified() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let robot = format!("robot = \"{}\"", root("designs/robots/ur5.toml").display());
    let read = |f: &str| std::fs::read_to_string(root(&format!("designs/{f}"))).unwrap();
    let ex = read("payload_ur5_excite.toml")
        .replace("robot = \"robots/ur5.toml\"", &robot)
        .replace("harmonics = 4\nfrequency = 0.1\n", "shape = \"bspline\"\nduration = 10.0\n");
    assert!(ex.contains("bspline") && !ex.contains("\"robots/"), "the shipped design changed shape");
    std::fs::write(d.join("ex.toml"), ex).unwrap();
    let o = idexp(&["payload", "excite"], &d.join("ex.toml"), &d.join("ex"));
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    for f in ["sim_ur5_payload", "sim_ur5_payload_unloaded"] {
        let text = read(&format!("{f}.toml"))
            .replace("robot = \"robots/ur5.toml\"", &robot)
            .replace("repetitions = 5", "repetitions = 2")
            .replace(
                "kind = \"fourier\"\nfile = \"../out/payload_ur5_excite/coefficients.json\"",
                &format!("kind = \"states\"\nperiodic = false\nfile = \"{}\"", d.join("ex/trajectory.csv").display()),
            );
        assert!(text.contains("\"states\"") && text.contains("repetitions = 2"), "{f} changed shape");
        std::fs::write(d.join(format!("{f}.toml")), text).unwrap();
        let o = idexp(&["simulate"], &d.join(format!("{f}.toml")), &d.join(f));
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    }
    let id = read("payload_ur5.toml")
        .replace("robot = \"robots/ur5.toml\"", &robot)
        .replace("../out/", "")
        .replace("harmonics = 4", "filter = \"lowpass\"");
    assert_eq!(id.matches("filter = \"lowpass\"").count(), 2, "the shipped design changed shape");
    std::fs::write(d.join("id.toml"), id).unwrap();
    let o = idexp(&["payload", "identify"], &d.join("id.toml"), &d.join("id"));
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let json: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(d.join("id/payload.json")).unwrap()).unwrap();
    let m = json["payload"]["mass"].as_f64().unwrap();
    let c: Vec<f64> = json["payload"]["com"].as_array().unwrap().iter().map(|v| v.as_f64().unwrap()).collect();
    let truth = [0.012, -0.008, 0.055];
    let dc = (0..3).map(|k| (c[k] - truth[k]).powi(2)).sum::<f64>().sqrt();
    assert!((m - 1.8).abs() < 0.018, "mass {m}");
    assert!(dc < 2e-3, "centre of mass {c:?}, {dc} m off");
}

/// Every `step`-th row of each repetition CSV of `src` from row `first`,
/// without the last `cut` of them, times re-based to 0, into `dst` (with
/// trajectory.json and design.json).
fn decimated_copy(src: &Path, dst: &Path, first: usize, step: usize, cut: usize) {
    std::fs::create_dir_all(dst).unwrap();
    for f in ["trajectory.json", "design.json"] {
        std::fs::copy(src.join(f), dst.join(f)).unwrap();
    }
    for r in 1..=5 {
        let name = format!("rep_{r:03}.csv");
        let text = std::fs::read_to_string(src.join(&name)).unwrap();
        let mut lines = text.lines();
        let mut out = String::from(lines.next().unwrap());
        out.push('\n');
        let rows: Vec<&str> = lines.skip(first).step_by(step).collect();
        let t0: f64 = rows[0].split(',').next().unwrap().parse().unwrap();
        for row in &rows[..rows.len() - cut] {
            let (t, rest) = row.split_once(',').unwrap();
            let t: f64 = t.parse().unwrap();
            out.push_str(&format!("{},{rest}\n", t - t0));
        }
        std::fs::write(dst.join(&name), out).unwrap();
    }
}

fn twin_design(dir: &Path, loaded: &str, unloaded: &str) -> PayloadDesign {
    let text = format!(
        "name = \"p\"\nrobot = \"{}\"\nframe = \"tool0\"\n[guess]\nmass = 2.0\ncom = [0.0, 0.0, 0.06]\ninertia = [0.006, 0.0, 0.0, 0.006, 0.0, 0.004]\n[[loaded]]\nname = \"loaded\"\nfiles = [\"{loaded}\"]\nfilter = \"lowpass\"\n[[unloaded]]\nname = \"unloaded\"\nfiles = [\"{unloaded}\"]\nfilter = \"lowpass\"\n",
        root("designs/robots/ur5.toml").display()
    );
    let p = dir.join("payload.toml");
    std::fs::write(&p, text).unwrap();
    PayloadDesign::read(&p).unwrap()
}

#[test]
fn twins_recorded_apart_are_aligned_and_another_trajectory_is_refused() {
    // loaded and unloaded runs recorded at 1 kHz; the 200 Hz twins are taken
    // from them: aligned (rows 0, 5, 10, …) and shifted by 3.4 samples (rows
    // 17, 22, …: 17 ms later) and 23 samples shorter
    let dir = tempfile::tempdir().unwrap();
    // the unloaded runs' noise is a tenth of the loaded runs': the shifted twin
    // takes other 1 kHz samples than the aligned one (another noise draw), and
    // that draw must not hide what the alignment does
    let at_1khz = |name: &str, loaded: bool, seed: u64, reference_seed: u64| {
        let (torque, position) = if loaded { (0.2, 1e-5) } else { (0.02, 1e-6) };
        let text = format!(
            "name = \"{name}\"\nrobot = \"designs/robots/ur5.toml\"\nrate = 1000.0\ndecimate = 1\nrepetitions = 5\nseed = {seed}\n[truth]\nperturbation = 0.1\nseed = 7\n[controller]\nbandwidth = 10.0\n[noise]\ntorque = {torque}\nposition = {position}\n[reference]\nkind = \"random_fourier\"\nn_h = 4\nfrequency = 0.1\namplitude = 0.6\nseed = {reference_seed}\n{}",
            if loaded { TRUE_PAYLOAD } else { "" }
        );
        let d = design(&text);
        let out = dir.path().join(name);
        simulate(&d).write(&out, &d).unwrap();
        out
    };
    let l = at_1khz("l1k", true, 11, 5);
    let u = at_1khz("u1k", false, 12, 5);
    decimated_copy(&l, &dir.path().join("loaded"), 0, 5, 0);
    decimated_copy(&u, &dir.path().join("aligned"), 0, 5, 0);
    decimated_copy(&u, &dir.path().join("shifted"), 17, 5, 20);
    let ctl = Control::new();
    let run = |unloaded: &str| idexp::payload::identify(&twin_design(dir.path(), "loaded", unloaded), dir.path(), &ctl);
    let a = run("aligned").unwrap();
    let s = run("shifted").unwrap();
    let al = s.runs[0].alignment.clone().expect("the twin's alignment");
    assert!((al.shift_samples + 3.4).abs() < 0.05, "shift {} samples", al.shift_samples);
    assert!((al.shift_s + 0.017).abs() < 2.5e-4, "shift {} s", al.shift_s);
    assert_eq!(al.samples, [2000, 1977]);
    assert!(al.overlap[1] - al.overlap[0] >= 1970, "{:?}", al.overlap);
    let a0 = a.runs[0].alignment.clone().unwrap();
    println!("aligned twins: {a0:?}\nshifted twins: {al:?}");
    println!("aligned: {:?}\nshifted: {:?}\nσ {:?}", a.payload, s.payload, a.payload_std);
    // after alignment the tracking difference is that of the aligned twins (the payload's effect)
    for j in 0..6 {
        assert!(
            al.rms_difference[j] < 1.5 * a0.rms_difference[j] + 2e-5,
            "joint {j}: {:?} vs {:?}",
            al.rms_difference,
            a0.rms_difference
        );
    }
    let (pa, ps) = (a.payload.unwrap(), s.payload.unwrap());
    let sd = a.payload_std.unwrap();
    assert!((ps.mass - pa.mass).abs() < sd.mass, "mass {} vs {} (σ {})", ps.mass, pa.mass, sd.mass);
    for k in 0..3 {
        assert!(
            (ps.com[k] - pa.com[k]).abs() < sd.com[k],
            "centre {:?} vs {:?} (σ {:?})",
            ps.com,
            pa.com,
            sd.com
        );
    }
    let text = s.text();
    assert!(text.contains("twin aligned: unloaded time = loaded time -0.017"), "{text}");
    // another trajectory (another reference seed) is not a twin
    let other = at_1khz("o1k", false, 12, 9);
    decimated_copy(&other, &dir.path().join("other"), 0, 5, 0);
    let err = run("other").unwrap_err().to_string();
    assert!(err.contains("not the same trajectory") && err.contains("allowed ≤ 10 %"), "{err}");
}
