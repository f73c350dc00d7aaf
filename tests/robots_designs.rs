//! The robots shipped in designs/robots/: each loads, has the expected joint
//! count, limits, frames and number of base inertial parameters, and its
//! regressor reproduces its inverse dynamics.

use idexp::params::{BaseOptions, BaseParams};
use idexp::robot::{self, Robot, Workspace};
use std::path::PathBuf;

fn load(file: &str) -> Robot {
    let p = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("designs/robots").join(file);
    robot::load(&p).unwrap_or_else(|e| panic!("{file}: {e}"))
}

fn n_base(r: &Robot, inertial_only: bool) -> usize {
    let opts = BaseOptions {
        inertial_only,
        ..BaseOptions::default()
    };
    BaseParams::compute(r, &opts).expect("base parameters").n_base()
}

fn check_regressor(r: &Robot) {
    let n = r.dof();
    let p = r.n_params();
    let theta = r.nominal_params();
    let mut ws = Workspace::new(r);
    let mut y = nalgebra::DMatrix::zeros(n, p);
    let mut tau = vec![0.0; n];
    for k in 0..20 {
        let f = k as f64;
        let q: Vec<f64> = (0..n).map(|j| 0.3 * (f + j as f64).sin()).collect();
        let qd: Vec<f64> = (0..n).map(|j| 0.8 * (0.7 * f + j as f64).cos()).collect();
        let qdd: Vec<f64> = (0..n).map(|j| 2.0 * (1.3 * f - j as f64).sin()).collect();
        robot::regressor(r, &mut ws, &q, &qd, &qdd, &mut y);
        robot::rnea(r, &mut ws, &q, &qd, &qdd, &mut tau);
        let yt = &y * &theta;
        let scale = tau.iter().fold(1.0f64, |m, t| m.max(t.abs()));
        for j in 0..n {
            assert!(
                (yt[j] - tau[j]).abs() <= 1e-9 * scale,
                "{}: joint {j}: Y·θ {} vs RNEA {}",
                r.name,
                yt[j],
                tau[j]
            );
        }
    }
}

fn tool_position(r: &Robot, q: &[f64]) -> nalgebra::Vector3<f64> {
    let f = r.frames.iter().find(|f| f.name == "tool0").expect("frame tool0");
    let mut ws = Workspace::new(r);
    robot::frame_pose(r, &mut ws, q, f).translation.vector
}

#[test]
fn ur5_loads_with_36_base_inertial_parameters() {
    let r = load("ur5.toml");
    assert_eq!(r.dof(), 6);
    assert_eq!(n_base(&r, true), 36);
    // the URDF's own velocity and effort limits are kept
    assert_eq!(r.joints[0].limits.velocity, 3.15);
    assert_eq!(r.joints[5].limits.velocity, 3.2);
    assert_eq!(r.joints[1].limits.effort, 150.0);
    assert_eq!(r.joints[3].limits.acceleration, 12.0);
    // tool0 at the zero pose from UR's DH data (ROS base_link, arm stretched):
    // x = a2 + a3, y = d4 + d6, z = d1 - d5
    let t = tool_position(&r, &[0.0; 6]);
    let expected = nalgebra::Vector3::new(0.425 + 0.39225, 0.10915 + 0.0823, 0.089159 - 0.09465);
    assert!((t - expected).norm() < 1e-9, "{t}");
    check_regressor(&r);
}

#[test]
fn ur10_loads_with_36_base_inertial_parameters() {
    let r = load("ur10.toml");
    assert_eq!(r.dof(), 6);
    assert_eq!(n_base(&r, true), 36);
    // tool0 at the zero pose from UR's published UR10 (CB) DH data:
    // x = a2 + a3, y = d4 + d6, z = d1 - d5
    let t = tool_position(&r, &[0.0; 6]);
    let expected = nalgebra::Vector3::new(0.612 + 0.5723, 0.163941 + 0.0922, 0.1273 - 0.1157);
    assert!((t - expected).norm() < 1e-9, "{t}");
    check_regressor(&r);
}

#[test]
fn panda_loads_with_43_base_inertial_parameters() {
    let r = load("panda.toml");
    assert_eq!(r.dof(), 7);
    assert_eq!(n_base(&r, true), 43);
    let acc = [15.0, 7.5, 10.0, 12.5, 15.0, 20.0, 20.0];
    for (j, a) in acc.iter().enumerate() {
        assert_eq!(r.joints[j].limits.acceleration, *a);
    }
    assert_eq!(r.joints[4].limits.effort, 12.0);
    // The Panda as delivered: hand (0.73 kg) and both fingers, closed
    // (0.015 kg each; their prismatic joints fixed at 0), are
    // lumped on link 7. Mass, first moment and Izz about the link-7 origin
    // recomputed here from the URDF values: link 7, then panda_link8 at
    // z = 0.107, the hand yawed by -pi/4 with its COM at (-0.01, 0, 0.03), the
    // finger frames 0.0584 above the hand with their COM at their origin.
    let ir = &r.links[6].inertial;
    let (m7, mh, mf) = (0.735522, 0.73, 0.015);
    assert!((ir.mass - (m7 + mh + 2.0 * mf)).abs() < 1e-12, "m7 = {}", ir.mass);
    let c7 = nalgebra::Vector3::new(1.0517e-2, -4.252e-3, 6.1597e-2);
    let (sy, cy) = (-std::f64::consts::FRAC_PI_4).sin_cos();
    let ch = nalgebra::Vector3::new(-0.01 * cy, -0.01 * sy, 0.107 + 0.03);
    let cf = nalgebra::Vector3::new(0.0, 0.0, 0.107 + 0.0584);
    let h = c7 * m7 + ch * mh + cf * (2.0 * mf);
    assert!((ir.first_moment - h).norm() < 1e-12, "first moment {} vs {h}", ir.first_moment);
    // Izz: own Izz about each COM (rotations about z keep it) + m (x^2 + y^2)
    let izz = 0.004815 + m7 * (c7.x * c7.x + c7.y * c7.y) + 0.0017 + mh * (ch.x * ch.x + ch.y * ch.y) + 2.0 * 7.5e-7;
    assert!((ir.inertia[(2, 2)] - izz).abs() < 1e-12, "Izz {} vs {izz}", ir.inertia[(2, 2)]);
    check_regressor(&r);
}

#[test]
fn iiwa14_loads_with_43_base_inertial_parameters() {
    let r = load("iiwa14.toml");
    assert_eq!(r.dof(), 7);
    assert_eq!(n_base(&r, true), 43);
    assert_eq!(r.joints[0].limits.effort, 320.0);
    assert_eq!(r.joints[6].limits.acceleration, 15.72);
    check_regressor(&r);
}

#[test]
fn puma560_loads_with_36_base_inertial_parameters() {
    let r = load("puma560.toml");
    assert_eq!(r.dof(), 6);
    assert_eq!(n_base(&r, true), 36);
    // Corke's fkine(qz) = [0.4521, -0.15005, 0.4318]
    let t = tool_position(&r, &[0.0; 6]);
    assert!((t - nalgebra::Vector3::new(0.4521, -0.15005, 0.4318)).norm() < 1e-9, "{t}");
    check_regressor(&r);
}

#[test]
fn industrial6_loads_with_coupled_wrist_and_36_base_inertial_parameters() {
    let r = load("industrial6.toml");
    assert_eq!(r.dof(), 6);
    let c = r.coupling.as_ref().expect("coupling");
    assert_eq!(c[(5, 4)], 0.5);
    assert_eq!(n_base(&r, true), 36);
    // KR 16-2 geometry at the zero pose: flange at x = 0.26 + 0.68 + 0.67 + 0.158, z = 0.675 - 0.035
    let t = tool_position(&r, &[0.0; 6]);
    assert!((t - nalgebra::Vector3::new(1.768, 0.0, 0.64)).norm() < 1e-9, "{t}");
    check_regressor(&r);
}

#[test]
fn shipped_robots_base_counts_with_drive_parameters() {
    // inertial base parameters + Ia + Fc + Fv, with Ia1 merged into ZZ1R etc.
    for (f, n) in [
        ("ur5.toml", 48),
        ("panda.toml", 62),
        ("iiwa14.toml", 62),
        ("puma560.toml", 52),
        ("industrial6.toml", 52),
    ] {
        let r = load(f);
        assert_eq!(n_base(&r, false), n, "{f}");
    }
}
