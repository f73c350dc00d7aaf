use super::crba::{crba_into, Need, Placed};
use super::rnea::{inverse_dynamics_generic, rnea_rigid, Inertials};
use super::*;
use crate::robot::kinematics::{joint_transform, joint_transforms};
use nalgebra::{Matrix3, Matrix6, Vector3};
use num_dual::Dual64;

/// The straightforward kernel: 3n independent scalar dual passes, transforms recomputed.
fn reference(robot: &Robot, q: &[f64], qd: &[f64], qdd: &[f64]) -> Vec<Vec<f64>> {
    let n = robot.dof();
    let mut out = Vec::new();
    let mut yd = vec![Dual64::from(0.0); n * robot.n_params()];
    let mut dual = Kin::new(n);
    let (mut qv, mut qdv, mut qddv) = (vec![Dual64::from(0.0); n], vec![Dual64::from(0.0); n], vec![Dual64::from(0.0); n]);
    for which in 0..3 {
        for k in 0..n {
            for i in 0..n {
                let seed = |x: f64, on: bool| Dual64::new(x, if on { 1.0 } else { 0.0 });
                qv[i] = seed(q[i], which == 0 && i == k);
                qdv[i] = seed(qd[i], which == 1 && i == k);
                qddv[i] = seed(qdd[i], which == 2 && i == k);
            }
            regressor_generic(robot, &qv, &qdv, &qddv, ALL, &mut dual, &mut yd);
            out.push(yd.iter().map(|d| d.eps).collect());
        }
    }
    out
}

/// The f64 tangents of `regressor_derivatives` equal 3n independent scalar
/// dual passes to 1e-12 of each direction's largest entry, and the
/// shared-transform dual passes of the excitation gradient equal them to
/// the last bit (up to the sign of zeros), on robots with and without
/// coupling, rotor inertia and friction.
#[test]
fn regressor_derivatives_equal_independent_dual_passes() {
    let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR"));
    for name in ["ur5", "industrial6", "puma560", "panda"] {
        let r = crate::robot::load(&root.join(format!("designs/robots/{name}.toml"))).unwrap();
        let (n, p) = (r.dof(), r.n_params());
        let mut ws = Workspace::new(&r);
        let mut t = 0.0_f64;
        for _ in 0..5 {
            let mut st = || {
                (0..n)
                    .map(|_| {
                        t += 0.731;
                        2.0 * (3.7 * t).sin()
                    })
                    .collect::<Vec<f64>>()
            };
            let (q, qd, qdd) = (st(), st(), st());
            let mut y = vec![0.0; n * p];
            let mut d = vec![vec![0.0; n * p]; 3 * n];
            let (a, rest) = d.split_at_mut(n);
            let (b, c) = rest.split_at_mut(n);
            regressor_derivatives(&r, &mut ws, &q, &qd, &qdd, &mut y, a, b, c);
            let want = reference(&r, &q, &qd, &qdd);
            for (k, (got, exp)) in d.iter().zip(&want).enumerate() {
                let scale = exp.iter().fold(0.0_f64, |a, e| a.max(e.abs()));
                for (i, (g, e)) in got.iter().zip(exp).enumerate() {
                    assert!(
                        (g - e).abs() <= 1e-12 * scale,
                        "{name}: direction {k}, entry {i}: {g:e} vs {e:e} (scale {scale:e})"
                    );
                }
            }
            // and the excitation gradient's shared-transform dual passes, bit for bit
            let mut qv: Vec<Dual64> = q.iter().map(|&x| Dual64::from(x)).collect();
            let mut qdv: Vec<Dual64> = qd.iter().map(|&x| Dual64::from(x)).collect();
            let mut qddv: Vec<Dual64> = qdd.iter().map(|&x| Dual64::from(x)).collect();
            let mut yd = vec![Dual64::from(0.0); n * p];
            joint_transforms(&r, &q, &mut ws.kin);
            let mut dual = Kin::new(n);
            regressor_dual_directions(&r, &ws.kin, &mut dual, [&mut qv, &mut qdv, &mut qddv], &mut yd, |which, k, yd| {
                for (i, (g, e)) in yd.iter().zip(&want[which * n + k]).enumerate() {
                    assert!(g.eps == *e, "{name}: dual direction {which}/{k}, entry {i}: {:e} vs {e:e}", g.eps);
                }
            });
        }
    }
}

/// The spatial inertia as the dense CRBA built it.
fn dense_spatial_inertia(ine: &Inertial) -> Matrix6<f64> {
    let sh = ine.first_moment.cross_matrix();
    let mut m = Matrix6::zeros();
    m.fixed_view_mut::<3, 3>(0, 0).copy_from(&ine.inertia);
    m.fixed_view_mut::<3, 3>(0, 3).copy_from(&sh);
    m.fixed_view_mut::<3, 3>(3, 0).copy_from(&sh.transpose());
    m.fixed_view_mut::<3, 3>(3, 3).copy_from(&(Matrix3::identity() * ine.mass));
    m
}

/// Motion transform parent → child (6×6) from child orientation `r` and
/// position `p` in parent: the dense form the CRBA had before its block
/// products.
fn dense_motion_x(r: &Matrix3<f64>, p: &Vector3<f64>) -> Matrix6<f64> {
    let rt = r.transpose();
    let mut x = Matrix6::zeros();
    x.fixed_view_mut::<3, 3>(0, 0).copy_from(&rt);
    x.fixed_view_mut::<3, 3>(3, 3).copy_from(&rt);
    x.fixed_view_mut::<3, 3>(3, 0).copy_from(&(-rt * p.cross_matrix()));
    x
}

/// The CRBA with dense 6×6 products (Xᵀ I X, Xᵀ f, I S, S·f), as shipped
/// before the block form: the reference of the bit-identity test.
fn dense_crba(robot: &Robot, inert: &[Inertial], ia: &[Option<f64>], q: &[f64]) -> DMatrix<f64> {
    let n = robot.dof();
    let mut kin = Kin::new(n);
    joint_transforms(robot, q, &mut kin);
    let mut ic: Vec<Matrix6<f64>> = inert.iter().map(dense_spatial_inertia).collect();
    let xs: Vec<Matrix6<f64>> = (0..n).map(|i| dense_motion_x(&kin.rot[i], &kin.pos[i])).collect();
    for i in (0..n).rev() {
        if let Some(p) = robot.joints[i].parent {
            let add = xs[i].transpose() * ic[i] * xs[i];
            ic[p] += add;
        }
    }
    let s = |i: usize| {
        let (a, l) = (robot.s_ang[i], robot.s_lin[i]);
        nalgebra::Vector6::new(a.x, a.y, a.z, l.x, l.y, l.z)
    };
    let mut m = DMatrix::zeros(n, n);
    for i in 0..n {
        let mut f = ic[i] * s(i);
        m[(i, i)] = s(i).dot(&f);
        let mut j = i;
        while let Some(p) = robot.joints[j].parent {
            f = xs[j].transpose() * f;
            j = p;
            m[(i, j)] = s(j).dot(&f);
            m[(j, i)] = m[(i, j)];
        }
    }
    if robot.coupling.is_none() {
        for j in 0..n {
            if let Some(v) = ia[j] {
                m[(j, j)] += v;
            }
        }
    } else {
        for &(j, a, ca) in &robot.c_sparse {
            if let Some(v) = ia[j] {
                for &(jj, b, cb) in &robot.c_sparse {
                    if jj == j {
                        m[(a, b)] += ca * v * cb;
                    }
                }
            }
        }
    }
    m
}

/// Test states: zeros, multiples of π/2 and π/4 (exact zeros and ones in
/// the transforms), then pseudo-random ones in ±2.5.
fn test_configurations(n: usize, count: usize) -> Vec<Vec<f64>> {
    use std::f64::consts::{FRAC_PI_2, FRAC_PI_4};
    let mut out = vec![vec![0.0; n], vec![FRAC_PI_2; n], vec![-FRAC_PI_2; n], vec![FRAC_PI_4; n]];
    out.push((0..n).map(|i| FRAC_PI_2 * i as f64).collect());
    out.push((0..n).map(|i| if i % 2 == 0 { 0.0 } else { -1.0 }).collect());
    let mut x = 0x9e37_79b9_7f4a_7c15_u64;
    for _ in 0..count {
        out.push(
            (0..n)
                .map(|_| {
                    x ^= x << 13;
                    x ^= x >> 7;
                    x ^= x << 17;
                    5.0 * ((x >> 11) as f64 / (1u64 << 53) as f64) - 2.5
                })
                .collect(),
        );
    }
    out
}

/// Every shipped robot model, and the RPR robots of the simulation designs.
fn shipped_robots() -> Vec<(String, Robot)> {
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("designs/robots");
    let mut paths: Vec<_> = std::fs::read_dir(&dir)
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|e| e == "toml"))
        .collect();
    paths.sort();
    // and the RPR robots of the shipped simulation designs
    let data = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/ident");
    paths.extend(["rpr_drives.toml", "rpr_drives_tanh.toml"].map(|f| data.join(f)));
    let out: Vec<(String, Robot)> = paths
        .iter()
        .filter_map(|p| crate::robot::load(p).ok().map(|r| (p.file_stem().unwrap().to_string_lossy().into_owned(), r)))
        .collect();
    for must in ["ur5", "panda", "puma560", "industrial6", "iiwa14", "rpr_drives", "rpr_drives_tanh"] {
        assert!(out.iter().any(|(n, _)| n == must), "{must} not loaded");
    }
    out
}

/// The test robots of tests/data: a coupled wrist, an RPR arm with a
/// prismatic joint, a branching tree.
fn test_robots() -> Vec<(String, Robot)> {
    let data = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data");
    ["coupled6_modified.toml", "rpr_standard.toml", "tree.urdf", "rxz_chain.urdf"]
        .iter()
        .map(|f| (f.to_string(), crate::robot::load(&data.join(f)).unwrap()))
        .collect()
}

/// θ with every parameter changed (non-physical values included).
fn perturbed_params(r: &Robot) -> Vec<f64> {
    r.nominal_params()
        .iter()
        .enumerate()
        .map(|(k, v)| v * (1.0 + 0.37 * (k as f64).sin()) + 1e-3 * (k as f64).cos())
        .collect()
}

/// The ten-parameter CRBA equals the mass matrix of the dense 6×6
/// products (spatial inertias and motion transforms) to 1e-12 of its
/// largest entry, for every shipped and test robot, nominal and
/// perturbed parameters, on exact and random configurations.
#[test]
fn crba_equals_the_dense_products() {
    let mut robots = shipped_robots();
    robots.extend(test_robots());
    let mut checked = 0;
    for (name, r) in robots {
        let n = r.dof();
        let mut ws = Workspace::new(&r);
        let nominal: Vec<Inertial> = r.links.iter().map(|l| l.inertial).collect();
        let perturbed = perturbed_params(&r);
        let pert_inert: Vec<Inertial> = (0..n)
            .map(|i| {
                let o = r.link_param_offset(i);
                Inertial::from_params(&perturbed[o..o + 10])
            })
            .collect();
        let ia_nom: Vec<Option<f64>> = r.drives.iter().map(|d| d.rotor_inertia).collect();
        let ia_pert: Vec<Option<f64>> = (0..n).map(|j| r.drives[j].rotor_inertia.map(|_| perturbed[r.drive_param_offset(j)])).collect();
        let mut m = DMatrix::zeros(n, n);
        for q in test_configurations(n, 300) {
            mass_matrix_into(&r, &mut ws, &q, &mut m);
            let want = dense_crba(&r, &nominal, &ia_nom, &q);
            assert!((&m - &want).amax() <= 1e-12 * want.amax(), "{name}: nominal at q = {q:?}: {m} vs {want}");
            mass_matrix_with_into(&r, &mut ws, &perturbed, &q, &mut m);
            let want = dense_crba(&r, &pert_inert, &ia_pert, &q);
            assert!((&m - &want).amax() <= 1e-12 * want.amax(), "{name}: perturbed at q = {q:?}: {m} vs {want}");
            checked += 1;
        }
    }
    assert!(checked >= 10 * 306, "{checked} configurations");
}

/// The test chain exercises every Rx(α) Rz(θ) case of the CRBA's
/// shortcut (α = 0, π/2, π, −π/2) on a chain walked by index, and the
/// tree the general walk; `crba_equals_the_dense_products` checks them.
#[test]
fn crba_paths_are_exercised_by_the_test_robots() {
    let robots = test_robots();
    let topo = |name: &str| robots.iter().find(|(n, _)| n == name).unwrap().1.topology.clone();
    let chain = topo("rxz_chain.urdf");
    assert!(chain.chain && chain.rxz_crba);
    let alphas: Vec<i8> = chain
        .placed
        .iter()
        .filter_map(|p| if let Placed::RxZ(a) = p { Some(*a) } else { None })
        .collect();
    assert_eq!(alphas, vec![0, 1, 2, -1, 0]);
    let tree = topo("tree.urdf");
    assert!(!tree.chain && !tree.rxz_crba);
    let panda = crate::robot::load(&std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("designs/robots/panda.toml"))
        .unwrap()
        .topology;
    assert!(panda.chain && panda.rxz_crba);
}

/// The CRBA with the Rx(α) Rz(θ) shortcut computes of each joint's
/// transform only what it reads ([`Need`]): M is the same to the bit as
/// with every transform computed in full, and a turn's (cos θ, sin θ)
/// are the bits the full transform holds (signed zeros included), on
/// every shipped and test robot that takes the shortcut.
#[test]
fn crba_reads_of_the_transforms_only_what_it_needs() {
    let mut robots = shipped_robots();
    robots.extend(test_robots());
    let (mut shortcut, mut turns) = (0, 0);
    for (name, r) in robots {
        let n = r.dof();
        let mut ws = Workspace::new(&r);
        if !r.topology.rxz_crba {
            continue;
        }
        shortcut += 1;
        // the same robot with every joint's transform read in full
        let mut full = r.clone();
        full.topology.need.iter_mut().for_each(|x| *x = Need::Full);
        let (mut a, mut b) = (DMatrix::zeros(n, n), DMatrix::zeros(n, n));
        for q in test_configurations(n, 100) {
            mass_matrix_into(&r, &mut ws, &q, &mut a);
            for i in (0..n).filter(|&i| r.topology.need[i] == Need::Turn) {
                let Placed::RxZ(alpha) = r.topology.placed[i] else {
                    panic!("{name}: turn {i} is not RxZ")
                };
                let (c, s) = ws.cs[i];
                let (rc, rs) = Placed::cs(alpha, &joint_transform(&r, i, q[i]).0.column(0).into_owned());
                assert_eq!((c.to_bits(), s.to_bits()), (rc.to_bits(), rs.to_bits()), "{name}: joint {i} at {}", q[i]);
                turns += 1;
            }
            mass_matrix_into(&full, &mut ws, &q, &mut b);
            let bits = |m: &DMatrix<f64>| m.iter().map(|v| v.to_bits()).collect::<Vec<u64>>();
            assert_eq!(bits(&a), bits(&b), "{name}: at q = {q:?}: {a} vs {b}");
        }
    }
    assert!(shortcut >= 2 && turns >= 1000, "{shortcut} robots, {turns} turns");
}

/// ∂τ/∂q and ∂τ/∂q̇ by forward-mode dual numbers: 2n dual passes of the
/// generic inverse dynamics (the computation the recursive derivatives
/// replaced), the oracle of `id_derivatives_equal_the_dual_passes`.
fn dual_id_derivatives(robot: &Robot, theta: &[f64], q: &[f64], qd: &[f64], qdd: &[f64]) -> (DMatrix<f64>, DMatrix<f64>) {
    let n = robot.dof();
    let mut dq = DMatrix::zeros(n, n);
    let mut dqd = DMatrix::zeros(n, n);
    let mut inert: Vec<Inertial> = robot.links.iter().map(|l| l.inertial).collect();
    let mut dual = Kin::new(n);
    let mut tau = vec![Dual64::from(0.0); n];
    for which in 0..2 {
        for k in 0..n {
            let seed = |x: &[f64], on: bool| -> Vec<Dual64> { (0..n).map(|i| Dual64::new(x[i], if on && i == k { 1.0 } else { 0.0 })).collect() };
            let (qv, qdv, qddv) = (seed(q, which == 0), seed(qd, which == 1), seed(qdd, false));
            inverse_dynamics_generic(robot, &mut inert, theta, &qv, &qdv, &qddv, ALL, &mut dual, &mut tau);
            let m = if which == 0 { &mut dq } else { &mut dqd };
            for i in 0..n {
                m[(i, k)] = tau[i].eps;
            }
        }
    }
    (dq, dqd)
}

/// The recursive RNEA derivatives equal the dual-number passes to 1e-11
/// of the largest entry, for every shipped and test robot (coupling,
/// prismatic joints, a branching tree, rotor inertias, sign / tanh /
/// Stribeck friction), nominal and perturbed parameters, at random
/// states and at rest.
#[test]
fn id_derivatives_equal_the_dual_passes() {
    let mut robots = shipped_robots();
    robots.extend(test_robots());
    for (name, r) in robots {
        let n = r.dof();
        let mut ws = Workspace::new(&r);
        let nominal = r.nominal_params();
        let perturbed = perturbed_params(&r);
        let qs = test_configurations(n, 40);
        for (s, q) in qs.iter().enumerate() {
            // |q̇| ≤ 0.3: the dual tanh of num-dual (sinh/cosh) overflows to NaN beyond |w/v_s| ≈ 355 (v_s = 1e-3 in rpr_drives_tanh)
            let qd: Vec<f64> = if s == 0 {
                vec![0.0; n]
            } else {
                (0..n).map(|i| 0.3 * (0.7 * (s * n + i) as f64).cos()).collect()
            };
            let qdd: Vec<f64> = (0..n).map(|i| 3.0 * (1.1 * (s * n + i) as f64 + 0.3).sin()).collect();
            for theta in [nominal.as_slice(), perturbed.as_slice()] {
                let (dq, dqd) = id_derivatives(&r, &mut ws, theta, q, &qd, &qdd);
                let (wq, wqd) = dual_id_derivatives(&r, theta, q, &qd, &qdd);
                for (got, want, what) in [(&dq, &wq, "∂τ/∂q"), (&dqd, &wqd, "∂τ/∂q̇")] {
                    let scale = want.amax().max(1e-300);
                    assert!((got - want).amax() <= 1e-11 * scale, "{name}: {what} at state {s}:{got}{want}");
                }
            }
        }
    }
}

/// The closed-form friction slopes equal central differences of the
/// friction columns (and the dual-number slope where num-dual's tanh
/// does not overflow), are finite at any velocity, for every drive
/// model of the shipped and test robots.
#[test]
fn friction_slopes_equal_differences() {
    let mut robots = shipped_robots();
    robots.extend(test_robots());
    let mut smooth = 0;
    for (name, r) in robots {
        for d in &r.drives {
            for &w in &[-2000.0, -3.0, -0.7, -1e-3, -2e-4, 2.5e-4, 1e-3, 0.013, 0.4, 1.0, 5.0, 1e4] {
                let mut got = [0.0; MAX_FRICTION_COLUMNS];
                let m = friction_slopes(d, w, &mut got);
                let mut cols = [Dual64::from(0.0); MAX_FRICTION_COLUMNS];
                assert_eq!(friction_columns(d, Dual64::new(w, 1.0), &mut cols), m, "{name}");
                let h = 1e-7 * w.abs();
                let (mut a, mut b) = ([0.0; MAX_FRICTION_COLUMNS], [0.0; MAX_FRICTION_COLUMNS]);
                friction_columns(d, w + h, &mut a);
                friction_columns(d, w - h, &mut b);
                for c in 0..m {
                    assert!(got[c].is_finite(), "{name}: slope at {w}");
                    let fd = (a[c] - b[c]) / (2.0 * h);
                    assert!((got[c] - fd).abs() <= 1e-6 * (1.0 + fd.abs()), "{name}: column {c} at {w}: {} vs {fd}", got[c]);
                    if cols[c].eps.is_finite() {
                        assert!((got[c] - cols[c].eps).abs() <= 1e-12 * (1.0 + got[c].abs()), "{name}: column {c} at {w}");
                    }
                }
                if !d.coulomb.is_sign() && m > 0 && w.abs() < 1e-3 {
                    smooth += 1;
                }
            }
        }
    }
    assert!(smooth > 0, "no smooth Coulomb model checked near 0");
}

/// The CRBA equals the mass matrix from n RNEA passes (column k:
/// τ_rb(q, 0, e_k) without gravity) to 1e-12 of its largest entry, for
/// every shipped and test robot, nominal and perturbed parameters.
#[test]
fn crba_equals_rnea_columns() {
    let mut robots = shipped_robots();
    robots.extend(test_robots());
    for (name, r) in robots {
        let n = r.dof();
        let mut ws = Workspace::new(&r);
        let perturbed = perturbed_params(&r);
        let pert: Vec<Inertial> = (0..n)
            .map(|i| {
                let o = r.link_param_offset(i);
                Inertial::from_params(&perturbed[o..o + 10])
            })
            .collect();
        for s in 0..40 {
            let inert = if s % 2 == 0 { Inertials::Nominal } else { Inertials::Of(&pert) };
            let q: Vec<f64> = (0..n).map(|i| 2.5 * (1.3 * (s * n + i) as f64).sin()).collect();
            let mut m = DMatrix::zeros(n, n);
            crba_into(&r, &mut ws, inert, |_| None, &q, &mut m);
            let zero = vec![0.0; n];
            let mut col = vec![0.0; n];
            for k in 0..n {
                let e: Vec<f64> = (0..n).map(|i| if i == k { 1.0 } else { 0.0 }).collect();
                rnea_rigid(&r, inert, &q, &zero, &e, false, &mut ws.kin, &mut col);
                for i in 0..n {
                    assert!((m[(i, k)] - col[i]).abs() <= 1e-12 * m.amax(), "{name}: M[{i},{k}] {} vs {}", m[(i, k)], col[i]);
                }
            }
        }
    }
}

/// The allocation-free forward dynamics inverts inverse dynamics.
#[test]
fn forward_dynamics_into_inverts_rnea() {
    let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR"));
    for name in ["ur5", "industrial6", "panda"] {
        let r = crate::robot::load(&root.join(format!("designs/robots/{name}.toml"))).unwrap();
        let n = r.dof();
        let mut ws = Workspace::new(&r);
        let q: Vec<f64> = (0..n).map(|i| 0.3 * i as f64 - 0.7).collect();
        let qd: Vec<f64> = (0..n).map(|i| 0.2 - 0.1 * i as f64).collect();
        let qdd: Vec<f64> = (0..n).map(|i| 0.5 * (i as f64).sin()).collect();
        let mut tau = vec![0.0; n];
        rnea(&r, &mut ws, &q, &qd, &qdd, &mut tau);
        let mut got = vec![0.0; n];
        forward_dynamics_into(&r, &mut ws, &q, &qd, &tau, &mut got).unwrap();
        for i in 0..n {
            assert!((got[i] - qdd[i]).abs() < 1e-9 * (1.0 + qdd[i].abs()), "{name}: {got:?} vs {qdd:?}");
        }
        let old = forward_dynamics(&r, &mut ws, &q, &qd, &tau).unwrap();
        assert_eq!(old.as_slice(), &got[..]);
    }
}
