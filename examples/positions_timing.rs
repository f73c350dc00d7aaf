//! Timing of the two dense kernels of the first-order methods (M(w) and tr(XF_i) for all i).
use idexp::positions::Problem;
use nalgebra::DMatrix;
fn main() {
    let (n, p) = (5000, 26);
    let factors: Vec<DMatrix<f64>> = (0..n).map(|i| DMatrix::from_fn(p, 3, |a, b| ((i * 7 + a * 3 + b) % 11) as f64 - 5.0)).collect();
    let pb = Problem::from_factors(p, &factors, None).unwrap();
    let w = vec![1.0 / n as f64; n];
    let t = std::time::Instant::now();
    let m = pb.information(&w);
    println!("information {:.4}s", t.elapsed().as_secs_f64());
    let t = std::time::Instant::now();
    let s = pb.traces(&m);
    println!("traces {:.4}s {}", t.elapsed().as_secs_f64(), s[0]);
}
