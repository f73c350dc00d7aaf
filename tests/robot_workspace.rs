//! A [`Workspace`] holds buffers only: after a kernel that takes a parameter
//! vector θ (`inverse_dynamics`, `id_derivatives`, `mass_matrix_with`,
//! `motor_inertia`) ran with a perturbed θ, every nominal kernel (`rnea`,
//! `gravity`, `bias_forces`, `mass_matrix`, `forward_dynamics`) on the same
//! workspace must give bit for bit what it gives on a fresh workspace.
//!
//! (Before the fix the workspace kept a copy of the link inertials that the θ
//! kernels overwrote and the nominal kernels then read as if nominal; this
//! test failed on that code: "coupled6-test: rnea after inverse_dynamics(θ) differs
//! from a fresh workspace".)

mod common;
use common::*;
use idexp::robot::{self, Robot, Workspace};

/// The nominal kernels' outputs at one state, as raw bits.
fn nominal_outputs(r: &Robot, ws: &mut Workspace, q: &[f64], qd: &[f64], qdd: &[f64]) -> Vec<(&'static str, Vec<u64>)> {
    let n = r.dof();
    let bits = |v: &[f64]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
    let mut tau = vec![0.0; n];
    robot::rnea(r, ws, q, qd, qdd, &mut tau);
    let g = robot::gravity(r, ws, q);
    let c = robot::bias_forces(r, ws, q, qd);
    let m = robot::mass_matrix(r, ws, q);
    let a = robot::forward_dynamics(r, ws, q, qd, &tau).expect("nominal mass matrix is positive definite");
    vec![
        ("rnea", bits(&tau)),
        ("gravity", bits(g.as_slice())),
        ("bias_forces", bits(c.as_slice())),
        ("mass_matrix", bits(m.as_slice())),
        ("forward_dynamics", bits(a.as_slice())),
    ]
}

/// θ with every parameter scaled by 1.5 and shifted, far from nominal.
fn perturbed(r: &Robot) -> Vec<f64> {
    r.nominal_params().iter().enumerate().map(|(i, v)| 1.5 * v + 0.1 * (i as f64 + 1.0)).collect()
}

type ThetaKernel = fn(&Robot, &mut Workspace, &[f64], &[f64], &[f64], &[f64]);

const THETA_KERNELS: &[(&str, ThetaKernel)] = &[
    ("inverse_dynamics(θ)", |r, ws, th, q, qd, qdd| {
        let mut tau = vec![0.0; r.dof()];
        robot::inverse_dynamics(r, ws, th, q, qd, qdd, &mut tau);
    }),
    ("id_derivatives(θ)", |r, ws, th, q, qd, qdd| {
        let _ = robot::id_derivatives(r, ws, th, q, qd, qdd);
    }),
    ("mass_matrix_with(θ)", |r, ws, th, q, _, _| {
        let _ = robot::mass_matrix_with(r, ws, th, q);
    }),
    ("motor_inertia(θ)", |r, ws, th, q, _, _| {
        let _ = robot::motor_inertia(r, ws, th, q);
    }),
];

#[test]
fn theta_kernels_leave_the_nominal_kernels_nominal() {
    let mut g = rng(11);
    for r in all_robots() {
        let theta = perturbed(&r);
        for _ in 0..5 {
            let (q, qd, qdd) = random_state(&r, &mut g);
            let fresh = nominal_outputs(&r, &mut Workspace::new(&r), &q, &qd, &qdd);
            for (kernel, run) in THETA_KERNELS {
                let mut ws = Workspace::new(&r);
                run(&r, &mut ws, &theta, &q, &qd, &qdd);
                let after = nominal_outputs(&r, &mut ws, &q, &qd, &qdd);
                for ((name, a), (_, b)) in after.iter().zip(&fresh) {
                    assert_eq!(a, b, "{}: {name} after {kernel} differs from a fresh workspace", r.name);
                }
            }
        }
    }
}

#[test]
fn the_perturbation_changes_the_theta_kernels() {
    // guards the test above against a θ equal to nominal
    let mut g = rng(12);
    for r in all_robots() {
        let (q, qd, qdd) = random_state(&r, &mut g);
        let mut ws = Workspace::new(&r);
        let mut a = vec![0.0; r.dof()];
        let mut b = vec![0.0; r.dof()];
        robot::inverse_dynamics(&r, &mut ws, &perturbed(&r), &q, &qd, &qdd, &mut a);
        robot::inverse_dynamics(&r, &mut ws, r.nominal_params().as_slice(), &q, &qd, &qdd, &mut b);
        assert_ne!(a, b, "{}: the perturbed θ gives the nominal torques", r.name);
    }
}
