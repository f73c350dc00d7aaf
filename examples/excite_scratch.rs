use idexp::excitation::objective::*;
use idexp::params::{BaseOptions, BaseParams};
use idexp::trajectory::{period_grid, FourierLayout};
use rand::{RngExt, SeedableRng};
fn main() {
    let r = idexp::robot::load(std::path::Path::new("designs/robots/ur5.toml")).unwrap();
    let b = BaseParams::compute(&r, &BaseOptions::default()).unwrap();
    let th = r.nominal_params();
    let nom: Vec<f64> = b.independent.iter().map(|&c| th[c]).collect();
    let lay = FourierLayout::new(vec![0.0; 6], 5, std::f64::consts::TAU * 0.1, false, false).unwrap();
    let times = period_grid(10.0, 10.0).unwrap();
    let obj = Objective::new(
        r.clone(),
        lay.clone(),
        b.independent.clone(),
        b.names.clone(),
        &nom,
        times,
        Criterion::Cond,
        Scaling::UnitColumn,
        &[1.0; 6],
    )
    .unwrap();
    let mut w = obj.workspace();
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(3);
    let x: Vec<f64> = (0..lay.n_vars()).map(|_| rng.random_range(-0.5..0.5)).collect();
    let t0 = std::time::Instant::now();
    let mut v = 0.0;
    for _ in 0..200 {
        v = obj.value(&x, &mut w);
    }
    println!("value {v}: {:?} per eval", t0.elapsed() / 200);
    let mut g = vec![0.0; x.len()];
    let t0 = std::time::Instant::now();
    for _ in 0..20 {
        v = obj.value_grad(&x, &mut w, &mut g);
    }
    println!("grad {v}: {:?} per eval", t0.elapsed() / 20);
    // FD check
    let h = 1e-6;
    let mut maxe: f64 = 0.0;
    for i in 0..x.len() {
        let (mut xp, mut xm) = (x.clone(), x.clone());
        xp[i] += h;
        xm[i] -= h;
        let fd = (obj.value(&xp, &mut w) - obj.value(&xm, &mut w)) / (2.0 * h);
        maxe = maxe.max((fd - g[i]).abs() / (1.0 + g[i].abs()));
    }
    println!("max rel fd err {maxe}");
    let mut ws = idexp::robot::Workspace::new(&r);
    let mut y = vec![0.0; 6 * r.n_params()];
    let t0 = std::time::Instant::now();
    for i in 0..10000 {
        let q = vec![0.01 * (i % 7) as f64; 6];
        idexp::robot::regressor_rows(&r, &mut ws, &q, &q, &q, &mut y);
    }
    println!("regressor_rows {:?}", t0.elapsed() / 10000);
    let m = nalgebra::DMatrix::<f64>::from_fn(600, 48, |i, j| ((i * 31 + j * 17) % 97) as f64 / 97.0 + if i == j { 1.0 } else { 0.0 });
    let f = idexp::linalg::to_faer(&m);
    let t0 = std::time::Instant::now();
    for _ in 0..100 {
        let _ = f.singular_values();
    }
    println!("sv 600x48 {:?}", t0.elapsed() / 100);
    faer::set_global_parallelism(faer::Par::Seq);
    let t0 = std::time::Instant::now();
    for _ in 0..100 {
        let _ = f.singular_values();
    }
    println!("sv seq 600x48 {:?}", t0.elapsed() / 100);
    let t0 = std::time::Instant::now();
    for _ in 0..100 {
        let g = f.transpose() * &f;
        let _ = g.self_adjoint_eigenvalues(faer::Side::Lower);
    }
    println!("gram eig {:?}", t0.elapsed() / 100);
}
#[allow(dead_code)]
fn _unused() {}
