//! The elastic study pipelines behind `idexp multisine`, `idexp frf`,
//! `idexp fit` and `idexp merge`, each usable on its own: [`multisine`]
//! (reference files), [`frf`] (FRF estimates from runs or a simulated design),
//! [`fit`] (multistart gray-box fit, resumable and shardable) and [`merge`]
//! (shard logs into the single-run result). Each writes its output folder,
//! including the common `status.json` ([`crate::io::status`]).

use super::design::{Design, WeightKind};
use super::estimate::{estimate_from_manifest, FrfData};
use super::fit::{weights, FitProblem};
use super::multisine::Multisine;
use super::multistart::{merge_logs, read_log, sorted_lines, MultistartRun, Shard, StartRecord};
use super::report::{self, Report};
use crate::elastic::{ElasticModel, Estimator};
use crate::error::{Error, Result};
use crate::io::status::{fingerprint_of, RunState};
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};
use std::str::FromStr;
use std::time::SystemTime;

/// Writes the folder's `status.json` ([`crate::io::status`]).
fn write_status(
    dir: &Path,
    command: &str,
    state: RunState,
    detail: String,
    started: SystemTime,
    fingerprint: String,
    summary: serde_json::Value,
) -> Result<()> {
    crate::io::status::write_status(dir, command, state, detail, Some(started), fingerprint, summary)
}

/// Summary of a multisine design (`multisine.json`).
#[derive(Debug, Clone, Serialize)]
pub struct MultisineSummary {
    /// Excited line frequencies (Hz).
    pub freqs_hz: Vec<f64>,
    /// Even detection lines (Hz).
    pub even_freqs_hz: Vec<f64>,
    /// Samples per period.
    pub samples: usize,
    /// Sample rate (Hz).
    pub rate: f64,
    /// Crest factors `[block][experiment][motor]` of the speed references.
    pub crest_factors: Vec<Vec<Vec<f64>>>,
    /// Largest crest factor.
    pub max_crest_factor: f64,
    /// Reference files written.
    pub files: Vec<String>,
}

/// Writes one period of the speed and position references of every block
/// and experiment (`ref_block<b>_exp<e>.csv`: t, r1..rn (rad/s), p1..pn (rad))
/// and `multisine.json` with the crest factors, into `<out>/multisine`.
pub fn multisine(design: &Path, out: Option<&Path>) -> Result<(MultisineSummary, PathBuf)> {
    let started = SystemTime::now();
    let (d, model) = Design::load(design)?;
    let n = model.n_motors();
    let dir = d.out_dir(out).join("multisine");
    crate::io::folder::begin(&dir, "multisine", &fingerprint_of(&d)?)?;
    let ms = Multisine::new(&d, n);
    let mut crest = Vec::new();
    let mut files = Vec::new();
    let mut header = vec!["t".to_string()];
    header.extend((1..=n).map(|i| format!("r{i}")));
    header.extend((1..=n).map(|i| format!("p{i}")));
    for b in 0..d.multisine.blocks {
        let mut cb = Vec::new();
        for e in 0..n {
            let r = ms.speed_and_position(b, e);
            cb.push(r.speed.iter().map(|s| Multisine::crest_factor(s)).collect::<Vec<f64>>());
            let name = format!("ref_block{}_exp{}.csv", b + 1, e + 1);
            let rows = (0..ms.samples).map(|t| {
                let mut row = vec![t as f64 / ms.rate];
                row.extend(r.speed.iter().map(|s| s[t]));
                row.extend(r.position.iter().map(|s| s[t]));
                row
            });
            crate::io::write_csv(&dir.join(&name), &header, rows)?;
            files.push(name);
        }
        crest.push(cb);
    }
    let max_cf = crest.iter().flatten().flatten().copied().fold(0.0, f64::max);
    let s = MultisineSummary {
        freqs_hz: ms.freqs_hz(),
        even_freqs_hz: ms.even_lines.iter().map(|&k| k as f64 * ms.rate / ms.samples as f64).collect(),
        samples: ms.samples,
        rate: ms.rate,
        crest_factors: crest,
        max_crest_factor: max_cf,
        files,
    };
    crate::io::write_json(&dir.join("multisine.json"), &s)?;
    crate::io::write_json(&dir.join("design.json"), &d)?;
    write_status(
        &dir,
        "multisine",
        RunState::Complete,
        format!("{} blocks × {} experiments, {} lines", d.multisine.blocks, n, s.freqs_hz.len()),
        started,
        fingerprint_of(&d)?,
        serde_json::json!({ "max_crest_factor": s.max_crest_factor, "lines": s.freqs_hz.len() }),
    )?;
    Ok((s, dir))
}

/// Measured FRF magnitudes (diagonal, with σ̂) per position as SVG.
fn frf_svg(path: &Path, data: &FrfData) -> Result<()> {
    use crate::io::plot::{Panel, Series};
    let n = data.n;
    let mut panels = Vec::new();
    for (pi, p) in data.positions.iter().enumerate() {
        for a in 0..n {
            panels.push(Panel {
                title: format!("pos {} |G{}{}|", pi + 1, a + 1, a + 1),
                x_label: "f (Hz)".into(),
                y_label: format!("|G{}{}| ({})", a + 1, a + 1, super::report::g_unit(data.output)),
                series: vec![
                    Series::line("Ĝ", data.freqs_hz.clone(), p.g.iter().map(|g| g.to_mat(n)[(a, a)].norm()).collect()),
                    Series::line("σ̂", data.freqs_hz.clone(), p.var.iter().map(|v| v[a * n + a].sqrt()).collect()),
                ],
                hlines: vec![],
                log_y: true,
                log_x: true,
                x_names: vec![],
            });
        }
    }
    crate::io::plot::write_svg(path, "FRF estimates (diagonal) and their standard deviations", &panels, n)
}

/// FRF estimation: from a runs manifest (`*.json`) or by simulating a design's
/// experiments. Writes `frf.json` (+ `truth.json` for simulated data, runs in
/// `runs/` for the time method), `frf.svg`, `design.json`, `status.json`.
pub fn frf(input: &Path, out: Option<&Path>, ctl: &crate::optim::Control) -> Result<(FrfData, PathBuf)> {
    let started = SystemTime::now();
    let is_json = input.extension().is_some_and(|e| e.eq_ignore_ascii_case("json"));
    let (data, dir, hash) = if is_json {
        let data = estimate_from_manifest(input)?;
        let dir = out
            .map(Path::to_path_buf)
            .unwrap_or_else(|| input.parent().unwrap_or(Path::new(".")).to_path_buf());
        // the resolved input of this estimate, beside it
        let manifest: serde_json::Value = serde_json::from_str(&crate::io::read_to_string(input)?).map_err(|e| Error::parse(input, e.to_string()))?;
        // the folder may hold the runs themselves: nothing is moved aside
        crate::io::folder::begin_in_place(&dir, "frf", &fingerprint_of(&manifest)?)?;
        crate::io::write_json(
            &dir.join("input_runs.json"),
            &serde_json::json!({ "manifest": abs(input), "contents": manifest }),
        )?;
        let hash = fingerprint_of(&manifest)?;
        (data, dir, hash)
    } else {
        let (d, model) = Design::load(input)?;
        let dir = d.out_dir(out).join("frf");
        crate::io::folder::begin(&dir, "frf", &fingerprint_of(&d)?)?;
        let (data, truth) = super::simulate::simulate(&d, &model, &dir.join("runs"), ctl)?;
        crate::io::write_json(&dir.join("truth.json"), &truth)?;
        crate::io::write_json(&dir.join("design.json"), &d)?;
        (data, dir, fingerprint_of(&d)?)
    };
    crate::io::write_json(&dir.join("frf.json"), &data)?;
    frf_svg(&dir.join("frf.svg"), &data)?;
    let flagged: Vec<usize> = data
        .positions
        .iter()
        .enumerate()
        .filter(|(_, p)| p.distortion.as_ref().is_some_and(|d| d.flagged))
        .map(|(i, _)| i + 1)
        .collect();
    let detail = format!(
        "{} positions × {} lines; nonlinear distortion flagged at positions {:?}",
        data.positions.len(),
        data.freqs_hz.len(),
        flagged
    );
    let summary = serde_json::json!({ "positions": data.positions.len(), "lines": data.freqs_hz.len(), "distortion_flagged": flagged });
    write_status(&dir, "frf", RunState::Complete, detail, started, hash, summary)?;
    Ok((data, dir))
}

/// What a fit run records about itself (`run.json`), for resume and merge.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct RunInfo {
    /// Design file (absolute).
    pub design: PathBuf,
    /// FRF data file (absolute).
    pub data: PathBuf,
    /// Estimator.
    pub estimator: Estimator,
    /// Weights.
    pub weights: WeightKind,
    /// Starts.
    pub starts: usize,
    /// Seed override of the run (`--seed`; absent: the design's seed).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub seed: Option<u64>,
    /// Fingerprint of design and data.
    pub hash: String,
}

/// Overrides for [`fit`].
#[derive(Debug, Clone, Default)]
pub struct FitOptions {
    /// FRF data file.
    pub data: Option<PathBuf>,
    /// Estimator.
    pub estimator: Option<Estimator>,
    /// Weights.
    pub weights: Option<WeightKind>,
    /// Starts.
    pub starts: Option<usize>,
    /// Shard.
    pub shard: Option<Shard>,
    /// Seed override (the design's `seed`: the perturbed starts θ·10^φ).
    pub seed: Option<u64>,
    /// Output folder root.
    pub out: Option<PathBuf>,
}

/// A finished (or stopped) fit run.
#[derive(Debug, Clone)]
pub struct FitRun {
    /// Output folder.
    pub dir: PathBuf,
    /// The log written (`starts.jsonl` or the shard's).
    pub log: PathBuf,
    /// Records of this run's starts.
    pub records: Vec<StartRecord>,
    /// The report (complete runs only).
    pub report: Option<Report>,
    /// Stopped by the user.
    pub interrupted: bool,
}

/// `lls`, `lls_magnitude` or `nls` (the names of [`Estimator::name`]).
impl FromStr for Estimator {
    type Err = Error;
    fn from_str(s: &str) -> Result<Estimator> {
        match s {
            "lls" => Ok(Estimator::Lls),
            "lls_magnitude" => Ok(Estimator::LlsMagnitude),
            "nls" => Ok(Estimator::Nls),
            _ => Err(Error::invalid("fit", "estimator", format!("expected lls, lls_magnitude or nls, found `{s}`"))),
        }
    }
}

/// The name of [`Estimator::name`] (`lls`, `lls_magnitude`, `nls`).
impl std::fmt::Display for Estimator {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

/// `user` or `optimal`.
impl FromStr for WeightKind {
    type Err = Error;
    fn from_str(s: &str) -> Result<WeightKind> {
        match s {
            "user" => Ok(WeightKind::User),
            "optimal" => Ok(WeightKind::Optimal),
            _ => Err(Error::invalid("fit", "weights", format!("expected user or optimal, found `{s}`"))),
        }
    }
}

/// `user` or `optimal`.
impl std::fmt::Display for WeightKind {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            WeightKind::User => "user",
            WeightKind::Optimal => "optimal",
        })
    }
}

fn abs(p: &Path) -> PathBuf {
    std::fs::canonicalize(p).unwrap_or_else(|_| p.to_path_buf())
}

/// Loaded inputs of a fit: design (with overrides), model, data, problems, fingerprint.
pub struct FitSetup {
    /// The design with the overrides applied.
    pub design: Design,
    /// The model.
    pub model: ElasticModel,
    /// FRF data.
    pub data: FrfData,
    /// The estimator's problem.
    pub problem: FitProblem,
    /// The common evaluation problem (LLS, user weights).
    pub common: FitProblem,
    /// Run description.
    pub info: RunInfo,
    /// θ_true when the data are simulated (truth.json beside the data).
    pub truth: Option<Vec<f64>>,
}

/// Loads a design and its FRF data into fit problems.
///
/// The overrides of `o` (data, estimator, weights, starts, seed, output
/// folder) apply; its shard is not used here.
pub fn setup(design: &Path, o: &FitOptions) -> Result<FitSetup> {
    let (data, out) = (o.data.as_deref(), o.out.as_deref());
    let (mut d, model) = Design::load(design)?;
    if let Some(e) = o.estimator {
        d.fit.estimator = e;
    }
    if let Some(w) = o.weights {
        d.fit.weights = w;
    }
    if let Some(seed) = o.seed {
        d.seed = seed;
    }
    if let Some(s) = o.starts {
        if s == 0 || s > super::design::MAX_STARTS {
            return Err(Error::invalid("fit", "starts", format!("{s}: expected 1..={}", super::design::MAX_STARTS)));
        }
        d.fit.starts = s;
    }
    let data_path = data.map(Path::to_path_buf).unwrap_or_else(|| d.out_dir(out).join("frf").join("frf.json"));
    if !data_path.exists() {
        return Err(Error::invalid(
            design.display().to_string(),
            "data",
            format!(
                "no FRF data at {}: estimate the FRF of {} first, into the same output folder, or give the path of its frf.json",
                data_path.display(),
                design.display()
            ),
        ));
    }
    let fd = FrfData::read(&data_path)?;
    if fd.positions.len() != d.positions.len()
        || fd
            .positions
            .iter()
            .zip(&d.positions)
            .any(|(a, b)| a.q0.len() != b.len() || a.q0.iter().zip(b).any(|(x, y)| (x - y).abs() > 1e-12))
    {
        return Err(Error::invalid(
            data_path.display().to_string(),
            "positions",
            "the data's positions differ from the design's `positions`",
        ));
    }
    let w = weights(&d, &fd, d.fit.estimator, d.fit.weights)?;
    let problem = FitProblem::new(&model, &fd, d.fit.estimator, w)?;
    let wc = weights(&d, &fd, Estimator::Lls, WeightKind::User)?;
    let common = problem.with_estimator(Estimator::Lls, wc);
    // the number of starts is not part of the fingerprint: start l does not depend on it, so a run
    // with more starts resumes one with fewer
    let mut dh = d.clone();
    dh.fit.starts = 0;
    let djson = serde_json::to_string(&dh).map_err(|e| Error::Numerical(e.to_string()))?;
    let fjson = serde_json::to_string(&fd).map_err(|e| Error::Numerical(e.to_string()))?;
    let hash = super::multistart::fingerprint(&[&djson, &fjson]);
    let truth_path = data_path.parent().unwrap_or(Path::new(".")).join("truth.json");
    let truth = std::fs::read_to_string(&truth_path).ok().and_then(|t| {
        let v: serde_json::Value = serde_json::from_str(&t).ok()?;
        let th: Vec<f64> = serde_json::from_value(v.get("theta")?.clone()).ok()?;
        (th.len() == model.n_unknowns()).then_some(th)
    });
    let info = RunInfo {
        design: abs(design),
        data: abs(&data_path),
        estimator: d.fit.estimator,
        weights: d.fit.weights,
        starts: d.fit.starts,
        seed: o.seed,
        hash,
    };
    Ok(FitSetup {
        design: d,
        model,
        data: fd,
        problem,
        common,
        info,
        truth,
    })
}

/// The fit output folder of a design and estimator: `<out>/fit_<estimator>_<weights>`.
pub fn fit_dir(d: &Design, out: Option<&Path>) -> PathBuf {
    let w = if d.fit.weights == WeightKind::User { "user" } else { "optimal" };
    d.out_dir(out).join(format!("fit_{}_{}", d.fit.estimator.name(), w))
}

/// Writes the sorted log and the report of a complete set of records.
fn finish(s: &FitSetup, dir: &Path, records: &[StartRecord], command: &str, started: SystemTime) -> Result<Report> {
    // the shard logs and run.json stay: nothing is moved aside
    crate::io::folder::begin_in_place(dir, command, &s.info.hash)?;
    crate::io::write_atomic(&dir.join("starts.jsonl"), sorted_lines(records)?.as_bytes())?;
    let w = if s.info.weights == WeightKind::User { "user" } else { "optimal" };
    let r = report::build(&s.problem, records, s.design.fit.starts, s.design.fit.reasonable, w, s.truth.as_deref());
    crate::io::write_json(&dir.join("fit.json"), &r)?;
    report::params_csv(&dir.join("params.csv"), &r)?;
    report::costs_svg(&dir.join("costs.svg"), &r)?;
    if let Some(b) = r.best_index.and_then(|i| records.iter().find(|x| x.index == i)) {
        report::bode_svgs(dir, &s.common, &s.data, &b.theta)?;
    }
    crate::io::write_json(&dir.join("design.json"), &s.design)?;
    let summary = serde_json::json!({ "starts": records.len(), "estimator": s.info.estimator, "weights": s.info.weights });
    write_status(
        dir,
        command,
        RunState::Complete,
        format!("{} starts", records.len()),
        started,
        s.info.hash.clone(),
        summary,
    )?;
    Ok(r)
}

/// Runs (or resumes) a multistart fit; with a shard only that shard's starts.
pub fn fit(design: &Path, o: &FitOptions, ctl: &crate::optim::Control) -> Result<FitRun> {
    let started = SystemTime::now();
    let s = setup(design, o)?;
    let dir = fit_dir(&s.design, o.out.as_deref());
    let n = s.design.fit.starts;
    let (indices, log) = match o.shard {
        Some(sh) => (sh.indices(n), dir.join(format!("starts.shard-{}-of-{}.jsonl", sh.index, sh.count))),
        None => ((0..n).collect::<Vec<_>>(), dir.join("starts.jsonl")),
    };
    crate::io::write_json(&dir.join("run.json"), &s.info)?;
    crate::io::write_json(&dir.join("design.json"), &s.design)?;
    let ms = MultistartRun {
        problem: &s.problem,
        common: &s.common,
        spec: &s.design.fit,
        seed: s.design.seed,
        hash: s.info.hash.clone(),
    };
    let (records, stopped) = ms.run(&indices, &log, ctl)?;
    let complete = records.len() == indices.len();
    let report = if complete && o.shard.is_none() {
        Some(finish(&s, &dir, &records, "fit", started)?)
    } else {
        if complete {
            crate::io::write_atomic(&log, sorted_lines(&records)?.as_bytes())?;
        }
        let what = if complete { RunState::ShardComplete } else { RunState::Interrupted };
        if o.shard.is_none() || !complete {
            let summary = serde_json::json!({ "starts": records.len(), "of": indices.len(), "log": log });
            write_status(
                &dir,
                "fit",
                what,
                format!(
                    "{} of {} starts in {}; run the same command again to resume",
                    records.len(),
                    indices.len(),
                    log.display()
                ),
                started,
                s.info.hash.clone(),
                summary,
            )?;
        }
        None
    };
    Ok(FitRun {
        dir,
        log,
        records,
        report,
        interrupted: stopped || !complete,
    })
}

/// Merges shard logs into exactly what a single run writes (sorted
/// `starts.jsonl`, report, plots, `run.json`, and `status.json` with command
/// `fit`: only its `started` and `finished` times are the merge's own),
/// using the `run.json` beside the first shard.
pub fn merge(shards: &[PathBuf], out: Option<&Path>) -> Result<(Report, PathBuf)> {
    let started = SystemTime::now();
    let first = shards
        .first()
        .ok_or_else(|| Error::invalid("merge", "shards", "give at least one shard file"))?;
    let src = first.parent().unwrap_or(Path::new(".")).to_path_buf();
    let run_path = src.join("run.json");
    let text = crate::io::read_to_string(&run_path)?;
    let info: RunInfo = serde_json::from_str(&text).map_err(|e| Error::parse(&run_path, e.to_string()))?;
    let paths: Vec<&Path> = shards.iter().map(PathBuf::as_path).collect();
    let records = merge_logs(&paths)?;
    if let Some(r) = records.iter().find(|r| r.hash != info.hash) {
        return Err(Error::invalid(
            first.display().to_string(),
            "hash",
            format!("start {} does not belong to the run in {}", r.index, run_path.display()),
        ));
    }
    let missing: Vec<usize> = (0..info.starts).filter(|i| !records.iter().any(|r| r.index == *i)).collect();
    if !missing.is_empty() {
        let show: Vec<String> = missing.iter().take(10).map(|i| i.to_string()).collect();
        // the shard files that should hold the missing starts (truncated or
        // interrupted shards), from their names starts.shard-<i>-of-<N>.jsonl
        let owner = |p: &Path| -> Option<super::multistart::Shard> {
            let name = p.file_name()?.to_str()?;
            let (i, n) = name.strip_prefix("starts.shard-")?.strip_suffix(".jsonl")?.split_once("-of-")?;
            super::multistart::Shard::parse(&format!("{i}/{n}")).ok()
        };
        let culprits: Vec<String> = shards
            .iter()
            .filter(|p| owner(p).is_some_and(|sh| sh.indices(info.starts).iter().any(|i| missing.contains(i))))
            .map(|p| p.display().to_string())
            .collect();
        let named = if culprits.is_empty() {
            first.display().to_string()
        } else {
            culprits.join(", ")
        };
        return Err(Error::invalid(
            named,
            "shards",
            format!(
                "{} of {} starts missing (e.g. {}): run the missing shards (they resume) and merge again",
                missing.len(),
                info.starts,
                show.join(", ")
            ),
        ));
    }
    let s = setup(
        &info.design,
        &FitOptions {
            data: Some(info.data.clone()),
            estimator: Some(info.estimator),
            weights: Some(info.weights),
            starts: Some(info.starts),
            seed: info.seed,
            ..FitOptions::default()
        },
    )?;
    if s.info.hash != info.hash {
        return Err(Error::invalid(
            run_path.display().to_string(),
            "hash",
            "the design or data changed since the shards ran",
        ));
    }
    let dir = out.map(Path::to_path_buf).unwrap_or(src);
    crate::io::write_json(&dir.join("run.json"), &s.info)?;
    // the folder a single run writes: status.json names the command `fit`
    let r = finish(&s, &dir, &records, "fit", started)?;
    Ok((r, dir))
}

/// Records of a finished log (for tests and scripts).
pub fn read_records(path: &Path) -> Result<Vec<StartRecord>> {
    Ok(read_log(path)?.0)
}
