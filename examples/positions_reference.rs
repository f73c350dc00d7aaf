//! The relaxed D- and A-optimal reference instances written to files and
//! solved by idexp, for the CVXPY + Clarabel comparison
//! (scripts/cvxpy-reference.sh reads the same files):
//!
//! `cargo run --release --example positions_reference -- <out dir>`
//!
//! Writes `<out>/d_1000x26.json` and `<out>/a_5000x8.json` (`{"name", "seed",
//! "criterion", "jacobians": [J_1, …]}`, J_i as 3 rows of p numbers, F_i =
//! J_iᵀJ_i) and `<out>/<name>.idexp.json` (idexp's certified value, its
//! efficiency bound and the wall time of `solve_relaxed`).

#[path = "../benches/common/instances.rs"]
mod instances;

use idexp::positions::{solve_relaxed, Criterion, SolverOptions};
use std::io::Write;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let out = std::path::PathBuf::from(std::env::args().nth(1).unwrap_or_else(|| "target/positions-reference".into()));
    std::fs::create_dir_all(&out)?;
    for ((name, seed, n, p), crit, cname) in [(instances::D_INSTANCE, Criterion::D, "d"), (instances::A_INSTANCE, Criterion::A, "a")] {
        let js = instances::jacobians(seed, n, p);
        let rows: Vec<Vec<Vec<f64>>> = js.iter().map(|j| (0..3).map(|r| (0..p).map(|c| j[(r, c)]).collect()).collect()).collect();
        let inst = serde_json::json!({ "name": name, "seed": seed, "criterion": cname, "jacobians": rows });
        let mut f = std::fs::File::create(out.join(format!("{name}.json")))?;
        f.write_all(serde_json::to_string(&inst)?.as_bytes())?;
        let pb = instances::problem(&js);
        let t = std::time::Instant::now();
        let r = solve_relaxed(&pb, crit, &SolverOptions::default(), &idexp::optim::Control::new())?;
        let secs = t.elapsed().as_secs_f64();
        let res = serde_json::json!({
            "name": name,
            "value": r.value,
            "status": format!("{:?}", r.status),
            "efficiency_bound": r.certificate.efficiency_bound,
            "support": r.weights.iter().filter(|&&w| w > 1e-6).count(),
            "first_order_s": r.log.first_order_time,
            "clarabel_s": r.log.clarabel_time,
            "wall_s": secs,
            "pruned_to": r.log.pruned_to,
            "rounds": r.log.rounds.iter().map(|x| serde_json::json!({"working_set": x.working_set, "iterations": x.iterations, "added": x.added, "seconds": x.solve_time})).collect::<Vec<_>>(),
        });
        std::fs::write(out.join(format!("{name}.idexp.json")), res.to_string())?;
        println!(
            "{name}: {} = {:.10} ({:?}, efficiency >= {:.9}), {secs:.3} s (first order {:.3} s, Clarabel {:.3} s, working sets {:?})",
            crit.value_label(),
            r.value,
            r.status,
            r.certificate.efficiency_bound,
            r.log.first_order_time,
            r.log.clarabel_time,
            r.log.rounds.iter().map(|x| x.working_set).collect::<Vec<_>>()
        );
    }
    Ok(())
}
