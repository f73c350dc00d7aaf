//! Elastic model: analytic FRF Jacobian = finite differences (springs,
//! dampers, rotor inertia, viscous friction, rigid inertial parameters),
//! static equilibrium, information matrix properties, bad input.

use idexp::elastic::{self, ElasticModel, Estimator, NoiseModel, Output};
use std::path::{Path, PathBuf};

fn root(p: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join(p)
}

fn model_with(extra_unknowns: &str) -> ElasticModel {
    let text = std::fs::read_to_string(root("designs/elastic_industrial6.toml")).unwrap();
    let text = text.replace(
        "unknowns = [\"springs\", \"dampers\"]",
        &format!("unknowns = [\"springs\", \"dampers\"{extra_unknowns}]"),
    );
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("d.toml");
    std::fs::write(
        &p,
        text.replace("robots/industrial6.toml", root("designs/robots/industrial6.toml").to_str().unwrap()),
    )
    .unwrap();
    ElasticModel::load(&p).unwrap()
}

#[test]
fn shipped_model_has_26_unknowns() {
    let m = ElasticModel::load(&root("designs/elastic_industrial6.toml")).unwrap();
    assert_eq!(m.n_unknowns(), 26);
    assert_eq!(m.n_motors(), 6);
    assert_eq!(m.n_elastic(), 7);
    assert_eq!(m.n_coords(), 19);
    assert_eq!(m.unknown_names()[0], "k_a1");
}

#[test]
fn jacobian_equals_finite_differences() {
    let m = model_with(", \"Ia2\", \"Fv3\", \"M6\", \"MZ3\", \"ZZ1\"");
    assert_eq!(m.n_unknowns(), 31);
    let theta = m.nominal_unknowns();
    let vals = m.full_values(&theta).unwrap();
    let q0 = [0.3, -0.7, 0.5, 0.4, 0.8, -0.2];
    let op = m.operating_point(&q0, &vals).unwrap();
    let omegas: Vec<f64> = [3.0, 17.0, 41.0, 77.0, 150.0].iter().map(|f| 2.0 * std::f64::consts::PI * f).collect();
    for output in [Output::Acceleration, Output::Velocity, Output::Position] {
        let (g, dg) = elastic::frf_jacobian(&m, &op, &theta, &omegas, output).unwrap();
        for i in 0..theta.len() {
            let h = 1e-6 * theta[i].abs().max(1e-3);
            let mut tp = theta.clone();
            tp[i] += h;
            let mut tm = theta.clone();
            tm[i] -= h;
            let gp = elastic::frf(&m, &op, &tp, &omegas, output).unwrap();
            let gm = elastic::frf(&m, &op, &tm, &omegas, output).unwrap();
            for k in 0..omegas.len() {
                let fd = (&gp[k] - &gm[k]) / num_complex::Complex::new(2.0 * h, 0.0);
                let scale = g[k].iter().map(|v| v.norm()).fold(0.0, f64::max) / theta[i].abs().max(1e-3);
                let err = (&fd - &dg[k][i]).iter().map(|v| v.norm()).fold(0.0, f64::max);
                assert!(
                    err <= 1e-5 * scale + 1e-12,
                    "param {} ({}), ω {}: |fd − analytic| = {err:e}, scale {scale:e}",
                    i,
                    m.unknown_names()[i],
                    omegas[k]
                );
            }
        }
    }
}

#[test]
fn equilibrium_balances_gravity() {
    let m = ElasticModel::load(&root("designs/elastic_industrial6.toml")).unwrap();
    let vals = m.full_values(&m.nominal_unknowns()).unwrap();
    let op = m.operating_point(&[0.0, -0.5, 0.3, 0.0, 1.0, 0.0], &vals).unwrap();
    // gravity torque at the elastic joints = −k q_e
    let mut ws = idexp::robot::Workspace::new(&m.ext);
    let z = vec![0.0; m.ext.dof()];
    let mut tau = vec![0.0; m.ext.dof()];
    idexp::robot::inverse_dynamics(&m.ext, &mut ws, &op.pi0, &op.q_ext, &z, &z, &mut tau);
    let mut any = false;
    for e in 0..m.n_elastic() {
        let x = m.elastic_index[e];
        let k = m.value_of(&vals, idexp::elastic::ParamRole::ArmSpring(e));
        assert!((k * op.q_ext[x] + tau[x]).abs() < 1e-8 * tau[x].abs().max(1.0), "elastic joint {e}");
        any |= op.q_ext[x].abs() > 1e-6;
    }
    assert!(any, "gravity should deflect some elastic joint");
    // the gearbox carries the gravity torque: Cᵀ τ0 = g_a
    for j in 0..6 {
        let mut s = 0.0;
        for i in 0..6 {
            s += m.coupling[(i, j)] * op.tau0[i];
        }
        assert!((s - tau[m.act_index[j]]).abs() < 1e-8 * s.abs().max(1.0));
    }
}

#[test]
fn frf_is_symmetric_and_has_rigid_low_frequency_limit() {
    // reciprocity: A symmetric and B = [I; 0] ⇒ G = Gᵀ
    let m = ElasticModel::load(&root("designs/elastic_industrial6.toml")).unwrap();
    let theta = m.nominal_unknowns();
    let vals = m.full_values(&theta).unwrap();
    let q0 = [0.2, -0.4, 0.6, 0.1, 0.7, 0.3];
    let op = m.operating_point(&q0, &vals).unwrap();
    let g = elastic::frf(&m, &op, &theta, &[2.0 * std::f64::consts::PI * 23.0], Output::Acceleration).unwrap();
    let asym = (&g[0] - g[0].transpose()).iter().map(|v| v.norm()).fold(0.0, f64::max);
    assert!(asym < 1e-10 * g[0].iter().map(|v| v.norm()).fold(0.0, f64::max));
}

#[test]
fn stiff_springs_give_the_rigid_robot_frf() {
    // independent computation: with springs ×1e5 the elastic FRF must equal the rigid robot's linearisation
    // G = s² C (s² M_t + s Cᵀ Fv C + ∂g/∂q)⁻¹ Cᵀ built from the foundation (mass_matrix, id_derivatives).
    let m = ElasticModel::load(&root("designs/elastic_industrial6.toml")).unwrap();
    let mut theta = m.nominal_unknowns();
    for (t, n) in theta.iter_mut().zip(m.unknown_names()) {
        if n.starts_with("k_") {
            *t *= 1e5;
        }
    }
    let vals = m.full_values(&theta).unwrap();
    let q0 = [0.2, -0.4, 0.6, 0.1, 0.7, 0.3];
    let op = m.operating_point(&q0, &vals).unwrap();
    let mut ws = idexp::robot::Workspace::new(&m.rigid);
    let mt = idexp::robot::mass_matrix(&m.rigid, &mut ws, &q0);
    let pr = m.rigid.nominal_params();
    let (dtau, _) = idexp::robot::id_derivatives(&m.rigid, &mut ws, pr.as_slice(), &q0, &[0.0; 6], &[0.0; 6]);
    let c = m.coupling.clone();
    let kg = c.transpose() * dtau; // motor-side ∂τ/∂q = C⁻ᵀ ∂g/∂q
    let fv = nalgebra::DMatrix::from_fn(6, 6, |i, j| {
        if i == j {
            m.value_of(&vals, idexp::elastic::ParamRole::MotorViscous(i))
        } else {
            0.0
        }
    });
    let cfc = c.transpose() * fv * &c;
    for f in [4.0, 30.0, 90.0] {
        let w = 2.0 * std::f64::consts::PI * f;
        let s = num_complex::Complex::new(0.0, w);
        let g = elastic::frf(&m, &op, &theta, &[w], Output::Acceleration).unwrap();
        let a = mt.map(|v| s * s * v) + cfc.map(|v| s * v) + kg.map(|v| num_complex::Complex::new(v, 0.0));
        let cc = c.map(|v| num_complex::Complex::new(v, 0.0));
        let gr = (&cc * a.try_inverse().unwrap() * cc.transpose()).map(|v| v * s * s);
        let rel = (&g[0] - &gr).iter().map(|v| v.norm()).fold(0.0, f64::max) / gr.iter().map(|v| v.norm()).fold(0.0, f64::max);
        assert!(rel < 1e-3, "{f} Hz: stiff elastic vs rigid FRF relative difference {rel}");
    }
}

#[test]
fn information_matrix_properties() {
    let m = ElasticModel::load(&root("designs/elastic_industrial6.toml")).unwrap();
    let q0 = [0.0, -0.6, 0.4, 0.0, 0.9, 0.0];
    let omegas: Vec<f64> = (1..60).map(|k| 2.0 * std::f64::consts::PI * (2 * k + 1) as f64).collect();
    let noise = NoiseModel::Relative { rel: 0.02 };
    let f_lls = elastic::information_matrix(&m, &q0, &omegas, &noise, Estimator::Lls).unwrap();
    let f_nls = elastic::information_matrix(&m, &q0, &omegas, &noise, Estimator::Nls).unwrap();
    let f_mag = elastic::information_matrix(&m, &q0, &omegas, &noise, Estimator::LlsMagnitude).unwrap();
    assert_eq!(f_lls.nrows(), 26);
    // optimal weights: LLS and NLS information coincide (eq. 8)
    let d = (&f_lls - &f_nls).abs().max() / f_lls.abs().max();
    assert!(d < 1e-9, "LLS vs NLS information with optimal weights differ by {d}");
    // symmetric positive semidefinite; magnitude-only has less information
    assert!((&f_lls - f_lls.transpose()).abs().max() <= 1e-12 * f_lls.abs().max());
    let ev = f_lls.clone().symmetric_eigen().eigenvalues;
    assert!(ev.min() > -1e-9 * ev.max());
    let diff = (&f_lls - &f_mag).symmetric_eigen().eigenvalues;
    assert!(diff.min() > -1e-9 * ev.max(), "F_lls − F_mag must be PSD");
    // information scales as 1/σ²
    let f2 = elastic::information_matrix(&m, &q0, &omegas, &NoiseModel::Relative { rel: 0.04 }, Estimator::Lls).unwrap();
    assert!(((&f_lls - &f2 * 4.0).abs().max()) < 1e-9 * f_lls.abs().max());
}

#[test]
fn bad_model_input_is_an_error() {
    let cases = [
        ("k = 3.0e5", "k = -3.0e5", "gearbox[0].k"),
        ("after = \"a2\"", "after = \"a9\"", "elastic[2].after"),
        ("unknowns = [\"springs\", \"dampers\"]", "unknowns = [\"springs\", \"k_a7\"]", "unknowns[1]"),
        ("axis = [1.0, 0.0, 0.0]", "axis = [0.0, 0.0, 0.0]", "elastic[0].axis"),
    ];
    let text = std::fs::read_to_string(root("designs/elastic_industrial6.toml")).unwrap();
    let text = text.replace("robots/industrial6.toml", root("designs/robots/industrial6.toml").to_str().unwrap());
    for (from, to, field) in cases {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("bad.toml");
        std::fs::write(&p, text.replacen(from, to, 1)).unwrap();
        let e = ElasticModel::load(&p).unwrap_err().to_string();
        assert!(e.contains(field) && e.contains("bad.toml"), "{e}");
    }
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("typo.toml");
    std::fs::write(&p, text.replacen("payload =", "paylod =", 1)).unwrap();
    assert!(ElasticModel::load(&p).unwrap_err().to_string().contains("paylod"));
}

/// The fast FRF kernel (motor coordinates eliminated first) equals the
/// reference full pivoted N×N solve to 1e-10 relative, G and every ∂G/∂θ_i,
/// at every position and line of the shipped design (with rigid, rotor and
/// friction unknowns too), for each output, and across a motor's undamped
/// local resonance where the kernel must fall back to pivoting.
#[test]
fn fast_kernel_equals_full_solve() {
    use elastic::FrfKernel;
    let m = model_with(", \"Ia2\", \"Fv3\", \"M6\", \"MZ3\", \"ZZ1\"");
    let fast = FrfKernel::new(&m);
    let full = FrfKernel::new(&m).with_full_solve();
    let (d, _) = idexp::frf::Design::load(&root("designs/elastic_industrial6.toml")).unwrap();
    let theta: Vec<f64> = m
        .nominal_unknowns()
        .iter()
        .enumerate()
        .map(|(i, t)| t * (1.0 + 0.1 * ((i % 5) as f64 - 2.0)))
        .collect();
    let vals = m.full_values(&theta).unwrap();
    let omegas: Vec<f64> = (1..=75).map(|k| 2.0 * std::f64::consts::PI * (2 * k + 1) as f64).collect();
    let (mut dg1, mut dg2) = (Vec::new(), Vec::new());
    let mut checked = 0;
    for q0 in &d.positions {
        let op = m.operating_point(q0, &vals).unwrap();
        let lin = m.linear_model(&op, &vals);
        for output in [Output::Acceleration, Output::Velocity, Output::Position] {
            for &w in &omegas {
                let g1 = fast.eval(&lin, &op, w, output, true, &mut dg1).unwrap();
                let g2 = full.eval(&lin, &op, w, output, true, &mut dg2).unwrap();
                let rel = |a: &nalgebra::DMatrix<elastic::C64>, b: &nalgebra::DMatrix<elastic::C64>| {
                    let s = b.iter().map(|v| v.norm()).fold(0.0, f64::max);
                    (a - b).iter().map(|v| v.norm()).fold(0.0, f64::max) / s.max(1e-300)
                };
                assert!(rel(&g1, &g2) < 1e-10, "G at ω {w}: {:e}", rel(&g1, &g2));
                for i in 0..theta.len() {
                    assert!(
                        rel(&dg1[i], &dg2[i]) < 1e-10,
                        "∂G/∂{} at ω {w}: {:e}",
                        m.unknown_names()[i],
                        rel(&dg1[i], &dg2[i])
                    );
                }
                checked += 1;
            }
        }
    }
    assert_eq!(checked, d.positions.len() * 3 * omegas.len());
    // an undamped motor: A_mm(j, j) = k − ω² Ia vanishes at ω = √(k/Ia)
    let mut lin = m.linear_model(&m.operating_point(&d.positions[0], &vals).unwrap(), &vals);
    let op = m.operating_point(&d.positions[0], &vals).unwrap();
    lin.d[(0, 0)] = 0.0;
    let wres = (lin.k[(0, 0)] / lin.m[(0, 0)]).sqrt();
    for w in [wres, wres * (1.0 + 1e-9)] {
        let g1 = fast.eval(&lin, &op, w, Output::Acceleration, true, &mut dg1).unwrap();
        let g2 = full.eval(&lin, &op, w, Output::Acceleration, true, &mut dg2).unwrap();
        let s = g2.iter().map(|v| v.norm()).fold(0.0, f64::max);
        let e = (&g1 - &g2).iter().map(|v| v.norm()).fold(0.0, f64::max);
        assert!(e < 1e-10 * s, "at the motor resonance: {e:e} vs {s:e}");
    }
}
