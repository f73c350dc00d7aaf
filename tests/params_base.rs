//! Base parameters: they reproduce the full model's torques, their counts
//! match the known values for the shipped robots, and the groupings follow
//! the classical regrouping rules.

mod common;
use common::*;
use idexp::params::{BaseOptions, BaseParams};
use idexp::robot::{self, Workspace};

#[test]
fn base_parameters_reproduce_the_torques() {
    for r in all_robots() {
        let (n, p) = (r.dof(), r.n_params());
        let bp = BaseParams::compute(&r, &BaseOptions::default()).unwrap();
        assert_eq!(bp.rank_qr, bp.n_base(), "{}: greedy and pivoted-QR ranks differ", r.name);
        let theta = r.nominal_params();
        let tb = bp.base_values(theta.as_slice());
        let mut ws = Workspace::new(&r);
        let mut g = rng(21);
        let mut y = vec![0.0; n * p];
        let mut yb = vec![0.0; n * bp.n_base()];
        let mut tau = vec![0.0; n];
        for _ in 0..1000 {
            let (q, qd, qdd) = random_state(&r, &mut g);
            robot::regressor_rows(&r, &mut ws, &q, &qd, &qdd, &mut y);
            robot::rnea(&r, &mut ws, &q, &qd, &qdd, &mut tau);
            bp.select_rows(&y, n, &mut yb);
            let scale = tau.iter().fold(1.0f64, |m, v| m.max(v.abs()));
            for j in 0..n {
                let t: f64 = (0..bp.n_base()).map(|k| yb[j * bp.n_base() + k] * tb[k]).sum();
                assert!((t - tau[j]).abs() < 1e-9 * scale, "{}: base model torque {t} vs {}", r.name, tau[j]);
            }
        }
        // a standard vector rebuilt from the base values has the same base values
        let back = bp.base_values(bp.standard_from_base(tb.as_slice()).as_slice());
        assert!((back - &tb).amax() < 1e-12 * tb.amax().max(1.0));
    }
}

#[test]
fn base_parameter_counts_of_the_shipped_robots() {
    let expected = [("ur5", 36), ("puma560", 36), ("panda", 43), ("iiwa14", 43)];
    let shipped = shipped_robots();
    for (name, count) in expected {
        let Some((_, r)) = shipped.iter().find(|(n, _)| n == name) else {
            panic!("designs/robots/{name}.toml is missing");
        };
        let bp = BaseParams::compute(
            r,
            &BaseOptions {
                inertial_only: true,
                ..Default::default()
            },
        )
        .unwrap();
        assert_eq!(bp.n_base(), count, "{name}: inertial base parameters");
    }
    // the iiwa URDF on its own (no robot file) gives the same count
    let r = robot::load(&root("designs/robots/iiwa14_no_collision.urdf")).unwrap();
    let bp = BaseParams::compute(
        &r,
        &BaseOptions {
            inertial_only: true,
            ..Default::default()
        },
    )
    .unwrap();
    assert_eq!(bp.n_base(), 43);
}

/// Classical regrouping on a 6R arm (Khalil & Dombre): the first link keeps
/// only ZZ1 (plus what is regrouped into it), XXj − YYj appear, and the masses
/// of the distal links are regrouped into proximal first moments.
#[test]
fn groupings_follow_the_regrouping_rules() {
    let r = robot::load(&root("tests/data/coupled6_modified.toml")).unwrap();
    let bp = BaseParams::compute(
        &r,
        &BaseOptions {
            inertial_only: true,
            ..Default::default()
        },
    )
    .unwrap();
    assert_eq!(bp.n_base(), 36);
    let g = |name: &str| {
        bp.names
            .iter()
            .position(|n| n == name)
            .map(|i| bp.groupings[i].clone())
            .unwrap_or_else(|| panic!("no base parameter {name}: {:?}", bp.names))
    };
    assert!(g("ZZ1R").starts_with("ZZ1 + YY2"), "{}", g("ZZ1R"));
    assert!(g("XX2R").starts_with("XX2 - YY2"), "{}", g("XX2R"));
    assert!(g("MX2R").contains("0.6*M3"), "{}", g("MX2R"));
    for k in ["XX1", "YY1", "M1", "MX1", "MY1"] {
        assert!(bp.unidentifiable.iter().any(|&i| r.params()[i].name == k), "{k} should have no effect");
    }
}

#[test]
fn rank_tolerance_is_validated() {
    let r = robot::load(&root("tests/data/rpr_standard.toml")).unwrap();
    assert!(BaseParams::compute(
        &r,
        &BaseOptions {
            tol: 0.0,
            ..Default::default()
        }
    )
    .is_err());
    assert!(BaseParams::compute(
        &r,
        &BaseOptions {
            samples: 1,
            ..Default::default()
        }
    )
    .is_err());
}
