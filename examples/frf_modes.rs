//! Prints the modes of the elastic model of a design at its positions.
use idexp::elastic::{self, ElasticModel};

fn main() -> Result<(), idexp::Error> {
    let path = std::env::args().nth(1).unwrap_or_else(|| "designs/elastic_industrial6.toml".into());
    let m = ElasticModel::load(std::path::Path::new(&path))?;
    println!("{} unknowns: {:?}", m.n_unknowns(), m.unknown_names());
    let theta = m.nominal_unknowns();
    let vals = m.full_values(&theta)?;
    for q0 in [vec![0.0, -0.6, 0.4, 0.0, 0.9, 0.0], vec![0.5, -1.2, 1.0, 0.8, -0.5, 0.3]] {
        let op = m.operating_point(&q0, &vals)?;
        let lin = m.linear_model(&op, &vals);
        let modes = elastic::modes(&lin)?;
        println!("q0 = {q0:?}");
        for md in modes {
            println!("  {:8.2} Hz  zeta {:.3}", md.freq_hz, md.zeta);
        }
    }
    Ok(())
}
