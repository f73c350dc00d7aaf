//! `idexp multisine`, `idexp frf`, `idexp fit`, `idexp merge`: arguments and
//! printing over [`idexp::frf::pipeline`].
//!
//! `--out` names the study folder of the design: each command writes its own
//! subfolder there (`multisine/`, `frf/`, `fit_<method>_<weights>/`), and `fit`
//! finds the FRF data of `frf` in the same study folder. `frf` on a runs
//! manifest and `merge` write into `--out` itself.

use crate::Outcome;
use anyhow::Context;
use idexp::elastic::Estimator;
use idexp::frf::pipeline::{fit, frf, merge, multisine, FitOptions};
use idexp::frf::{Shard, WeightKind};
use idexp::optim::Control;
use std::path::PathBuf;

/// `idexp multisine <design>`.
#[derive(clap::Args, Debug)]
pub struct MultisineArgs {
    /// Design file (TOML).
    pub design: PathBuf,
    /// Study folder: writes `<out>/multisine/` (default out/<name>).
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Print multisine.json's contents instead of the summary.
    #[arg(long)]
    pub json: bool,
}

/// `idexp frf <design | runs.json>`.
#[derive(clap::Args, Debug)]
pub struct FrfArgs {
    /// A design file with a [simulate] section, or a runs manifest `runs.json`.
    pub input: PathBuf,
    /// Study folder: writes `<out>/frf/` for a design (default out/<name>); for a manifest, the folder receiving frf.json (default: the manifest's).
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Print the folder's status.json (positions, lines, distortion flags) instead of text.
    #[arg(long)]
    pub json: bool,
}

/// `idexp fit <design>`.
#[derive(clap::Args, Debug)]
pub struct FitArgs {
    /// Design file (TOML).
    pub design: PathBuf,
    /// FRF data (default <out>/frf/frf.json, written by `idexp frf`).
    #[arg(long)]
    pub data: Option<PathBuf>,
    /// Estimator override: lls, lls_magnitude or nls.
    #[arg(long, alias = "estimator")]
    pub method: Option<Estimator>,
    /// Weights of the fit residuals override: user or optimal.
    #[arg(long)]
    pub weights: Option<WeightKind>,
    /// Number of starts override.
    #[arg(long)]
    pub starts: Option<usize>,
    /// Seed override (the perturbed starts θ·10^φ).
    #[arg(long)]
    pub seed: Option<u64>,
    /// Run only starts l with l mod N = i (0-based `i/N`), for batch jobs.
    #[arg(long)]
    pub shard: Option<String>,
    /// Study folder: writes `<out>/fit_<method>_<weights>/` (default out/<name>).
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Print fit.json's contents instead of the text report.
    #[arg(long)]
    pub json: bool,
}

/// `idexp merge <shard files...>`.
#[derive(clap::Args, Debug)]
pub struct MergeArgs {
    /// Shard logs `starts.shard-<i>-of-<N>.jsonl` (with the `run.json` of their run beside them).
    #[arg(required = true)]
    pub shards: Vec<PathBuf>,
    /// Folder receiving the merged result (default: the folder of the first shard).
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Print fit.json's contents instead of the text report.
    #[arg(long)]
    pub json: bool,
}

/// Runs `idexp multisine`.
pub fn run_multisine(a: &MultisineArgs, _ctl: &Control) -> anyhow::Result<Outcome> {
    let (s, dir) = multisine(&a.design, a.out.as_deref())?;
    if a.json {
        crate::print_json(&s)?;
        return Ok(Outcome::Done);
    }
    println!(
        "{} lines from {:.3} to {:.3} Hz, {} samples per period at {} Hz; crest factor max {:.2}\nwritten to {}",
        s.freqs_hz.len(),
        s.freqs_hz.first().copied().unwrap_or(0.0),
        s.freqs_hz.last().copied().unwrap_or(0.0),
        s.samples,
        s.rate,
        s.max_crest_factor,
        dir.display()
    );
    Ok(Outcome::Done)
}

/// Runs `idexp frf`.
pub fn run_frf(a: &FrfArgs, ctl: &Control) -> anyhow::Result<Outcome> {
    let (d, dir) = frf(&a.input, a.out.as_deref(), ctl)?;
    if a.json {
        print!("{}", idexp::io::read_to_string(&dir.join("status.json"))?);
    } else {
        println!(
            "FRF at {} positions × {} lines ({} output) written to {}",
            d.positions.len(),
            d.freqs_hz.len(),
            format!("{:?}", d.output).to_lowercase(),
            dir.join("frf.json").display()
        );
        for (i, p) in d.positions.iter().enumerate() {
            if let Some(x) = &p.distortion {
                let evn = x
                    .even_vs_noise_db
                    .as_ref()
                    .map(|v| format!("{:.1}", v.iter().copied().fold(f64::NEG_INFINITY, f64::max)))
                    .unwrap_or("-".into());
                println!(
                    "  position {}: even lines {:.1} dB below the odd ones, {} dB above noise{}",
                    i + 1,
                    -x.even_vs_odd_db.iter().copied().fold(f64::NEG_INFINITY, f64::max),
                    evn,
                    if x.flagged { "  → NONLINEAR DISTORTION" } else { "" }
                );
            }
        }
    }
    Ok(if crate::interrupted(ctl) { Outcome::Interrupted } else { Outcome::Done })
}

/// Runs `idexp fit`.
pub fn run_fit(a: &FitArgs, ctl: &Control) -> anyhow::Result<Outcome> {
    let o = FitOptions {
        data: a.data.clone(),
        estimator: a.method,
        weights: a.weights,
        starts: a.starts,
        seed: a.seed,
        shard: a.shard.as_deref().map(Shard::parse).transpose().context("--shard")?,
        out: a.out.clone(),
    };
    let r = fit(&a.design, &o, ctl).map_err(|e| match e {
        idexp::Error::Invalid { ref field, .. } if field == "data" && a.data.is_none() => anyhow::Error::new(e).context(format!(
            "fit: run `idexp frf {}` (with the same --out) first, or pass --data",
            a.design.display()
        )),
        idexp::Error::Invalid { ref field, .. } if field == "starts" && a.starts.is_some() => anyhow::Error::new(e).context("--starts"),
        e => e.into(),
    })?;
    match &r.report {
        Some(rep) if a.json => crate::print_json(rep)?,
        Some(rep) => {
            print!("{}", rep.text());
            println!("written to {}", r.dir.display());
        }
        None => println!(
            "{} starts in {}{}",
            r.records.len(),
            r.log.display(),
            if r.interrupted {
                " (interrupted: run the same command again to resume)"
            } else {
                " (shard complete: merge the shards with `idexp merge`)"
            }
        ),
    }
    if r.interrupted || crate::interrupted(ctl) {
        return Ok(Outcome::Interrupted);
    }
    Ok(match &r.report {
        Some(rep) if rep.best_index.is_none() => Outcome::Unusable("no start of the fit converged to a usable model".into()),
        _ => Outcome::Done,
    })
}

/// Runs `idexp merge`.
pub fn run_merge(a: &MergeArgs, _ctl: &Control) -> anyhow::Result<Outcome> {
    let (r, dir) = merge(&a.shards, a.out.as_deref())?;
    if a.json {
        crate::print_json(&r)?;
    } else {
        print!("{}", r.text());
        println!("written to {}", dir.display());
    }
    Ok(if r.best_index.is_none() {
        Outcome::Unusable("no start of the fit converged to a usable model".into())
    } else {
        Outcome::Done
    })
}
