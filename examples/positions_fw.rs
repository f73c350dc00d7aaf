//! Convergence trace of Frank–Wolfe with away steps on a random D-optimal instance.
use idexp::positions::{firstorder, Problem};
use nalgebra::DMatrix;
use rand::{RngExt, SeedableRng};
use rand_distr::{Distribution, StandardNormal};
fn main() -> idexp::Result<()> {
    let args: Vec<String> = std::env::args().collect();
    let n: usize = args.get(1).and_then(|s| s.parse().ok()).unwrap_or(200);
    let p: usize = args.get(2).and_then(|s| s.parse().ok()).unwrap_or(8);
    let mut g = rand_chacha::ChaCha8Rng::seed_from_u64(7);
    let factors: Vec<DMatrix<f64>> = (0..n)
        .map(|_| {
            let r = g.random_range(1..=3);
            DMatrix::from_fn(p, r, |_, _| <StandardNormal as Distribution<f64>>::sample(&StandardNormal, &mut g))
        })
        .collect();
    let pb = Problem::from_factors(p, &factors, None)?;
    let mut w = vec![1.0 / n as f64; n];
    for k in 0..20 {
        let lg = firstorder::fw_away_d(&pb, &mut w, 100, 1e-9, &idexp::optim::Control::new())?;
        let supp = w.iter().filter(|&&v| v > 0.0).count();
        println!("{} eps {:.3e} support {supp}", (k + 1) * 100, lg.eps);
    }
    Ok(())
}
