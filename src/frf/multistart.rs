//! Multistart (paper 001 §6): N local fits from θ_init·10^φ, φ_i ~ U[−s, s]
//! per element, start l drawing φ from its own generator seeded by
//! (design seed, l) — so any subset of starts, in any order, on any number of
//! threads or machines, gives the same records.
//!
//! Every finished start is appended at once as one JSON line to the run's log;
//! a run that finds a log resumes: it keeps the complete lines (a line cut by
//! a kill is dropped) and runs only the missing starts. `--shard i/N` runs the
//! starts l with l mod N = i (0-based, as Slurm array and Kubernetes indexed
//! job indices). When a run or merge holds every start it rewrites the log
//! sorted by start index: a resumed run, a single run and merged shards give
//! byte-identical files.

use super::fit::{FitProblem, FitStatus};
use super::multisine::{streams, sub_seed};
use crate::error::{Error, Result};
use crate::optim::Control;
use rand::{RngExt, SeedableRng};
use serde::{Deserialize, Serialize};
use std::io::Write;
use std::path::Path;

/// One finished start.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct StartRecord {
    /// Start index l.
    pub index: usize,
    /// Fingerprint of the design and data the start belongs to.
    pub hash: String,
    /// Initial parameters θ_init·10^φ.
    pub theta0: Vec<f64>,
    /// Final parameters.
    pub theta: Vec<f64>,
    /// Final cost of the estimator (None when the start failed).
    pub cost: Option<f64>,
    /// Final cost in the common evaluation (LLS, user weights; paper 001 Fig. 3).
    pub common_cost: Option<f64>,
    /// Solver outcome.
    pub status: FitStatus,
    /// LM iterations.
    pub iterations: usize,
    /// Cost evaluations.
    pub evaluations: usize,
}

/// A subset of starts: l mod count = index.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub struct Shard {
    /// 0-based shard index i.
    pub index: usize,
    /// Number of shards N.
    pub count: usize,
}

impl Shard {
    /// Parses `i/N` with 0 ≤ i < N.
    pub fn parse(s: &str) -> Result<Shard> {
        let bad = || Error::invalid("multistart", "shard", format!("expected i/N with 0 ≤ i < N (0-based, e.g. 0/4), found `{s}`"));
        let (a, b) = s.split_once('/').ok_or_else(bad)?;
        let index: usize = a.trim().parse().map_err(|_| bad())?;
        let count: usize = b.trim().parse().map_err(|_| bad())?;
        if count == 0 || index >= count {
            return Err(bad());
        }
        Ok(Shard { index, count })
    }
    /// Start indices of this shard among `n` starts.
    pub fn indices(&self, n: usize) -> Vec<usize> {
        (0..n).filter(|l| l % self.count == self.index).collect()
    }
}

/// The initial point of start `index`: θ_i·10^{φ_i}, φ_i ~ U[−spread, spread].
pub fn start_point(theta_init: &[f64], spread: f64, seed: u64, index: usize) -> Vec<f64> {
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(sub_seed(seed, streams::STARTS, index as u64));
    theta_init
        .iter()
        .map(|t| {
            let phi: f64 = if spread > 0.0 { rng.random_range(-spread..=spread) } else { 0.0 };
            t * 10f64.powf(phi)
        })
        .collect()
}

/// FNV-1a 64-bit fingerprint of some text, as 16 hex digits (the one of `status.json`).
pub use crate::io::status::fingerprint;

/// Reads a JSON Lines log. A last line without its newline that does not
/// parse (a write cut by a kill) is dropped; any other bad line is an error.
/// Returns the records and the byte length of the valid prefix.
pub fn read_log(path: &Path) -> Result<(Vec<StartRecord>, usize)> {
    let text = match std::fs::read_to_string(path) {
        Ok(t) => t,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok((Vec::new(), 0)),
        Err(e) => return Err(Error::io(path, e)),
    };
    let mut out = Vec::new();
    let mut valid = 0usize;
    let mut pos = 0usize;
    for (ln, line) in text.split_inclusive('\n').enumerate() {
        let complete = line.ends_with('\n');
        let body = line.trim_end();
        pos += line.len();
        if body.is_empty() {
            valid = pos;
            continue;
        }
        match (serde_json::from_str::<StartRecord>(body), complete) {
            (Ok(r), true) => {
                out.push(r);
                valid = pos;
            }
            // a last line without its newline: the write was cut; the start is run again
            (_, false) => break,
            (Err(e), true) => return Err(Error::parse(path, format!("line {}: not a start record: {e}", ln + 1))),
        }
    }
    Ok((out, valid))
}

/// Sorted, de-duplicated lines of a set of records (the final log format).
pub fn sorted_lines(records: &[StartRecord]) -> Result<String> {
    let mut r: Vec<&StartRecord> = records.iter().collect();
    r.sort_by_key(|x| x.index);
    r.dedup_by_key(|x| x.index);
    let mut s = String::new();
    for x in r {
        s.push_str(&serde_json::to_string(x).map_err(|e| Error::Numerical(format!("cannot serialise a start record: {e}")))?);
        s.push('\n');
    }
    Ok(s)
}

/// Settings of a multistart run.
#[derive(Debug, Clone)]
pub struct MultistartRun<'a> {
    /// The estimator's problem.
    pub problem: &'a FitProblem,
    /// The common evaluation problem (LLS, user weights).
    pub common: &'a FitProblem,
    /// Fit settings (iterations, tolerances, spread).
    pub spec: &'a super::design::FitSpec,
    /// Design seed.
    pub seed: u64,
    /// Design/data fingerprint.
    pub hash: String,
}

impl MultistartRun<'_> {
    /// One start (Levenberg–Marquardt from start point `index`), stopped by `ctl`.
    pub fn start(&self, index: usize, ctl: &Control) -> StartRecord {
        let theta0 = start_point(&self.problem.theta_nom, self.spec.spread, self.seed, index);
        let o = self.problem.solve(&theta0, self.spec, ctl);
        let ok = o.cost.is_finite();
        let common = if ok {
            self.common.cost(&o.theta).ok().filter(|c| c.is_finite())
        } else {
            None
        };
        StartRecord {
            index,
            hash: self.hash.clone(),
            theta0,
            theta: o.theta,
            cost: if ok { Some(o.cost) } else { None },
            common_cost: common,
            status: o.status,
            iterations: o.iterations,
            evaluations: o.evaluations,
        }
    }

    /// Runs the starts `indices` not yet in the log at `log` (resuming),
    /// appending each as it finishes; returns the records of `indices` found
    /// or computed and whether the user stopped the run.
    ///
    /// The starts run in parallel on rayon's pool, so this loop is not an
    /// argmin `Executor` (one executor runs one solver sequentially); each
    /// start is one Levenberg–Marquardt run and `ctl` is polled before each
    /// start and at every LM iteration. Progress: phase `"multistart"`, one
    /// step per start (finished ones of a resumed log included).
    pub fn run(&self, indices: &[usize], log: &Path, ctl: &Control) -> Result<(Vec<StartRecord>, bool)> {
        use rayon::prelude::*;
        let (mut have, valid) = read_log(log)?;
        if let Some(r) = have.iter().find(|r| r.hash != self.hash) {
            return Err(Error::invalid(
                log.display().to_string(),
                "hash",
                format!(
                    "start {} was written for another design or data ({} ≠ {}): remove the file or write the fit to another output folder",
                    r.index, r.hash, self.hash
                ),
            ));
        }
        if let Some(dir) = log.parent() {
            if !dir.as_os_str().is_empty() {
                std::fs::create_dir_all(dir).map_err(|e| Error::io(dir, e))?;
            }
        }
        // drop a cut last line before appending
        if log.exists() {
            let f = std::fs::OpenOptions::new().write(true).open(log).map_err(|e| Error::io(log, e))?;
            f.set_len(valid as u64).map_err(|e| Error::io(log, e))?;
        }
        have.retain(|r| indices.contains(&r.index));
        let done: std::collections::BTreeSet<usize> = have.iter().map(|r| r.index).collect();
        let pending: Vec<usize> = indices.iter().copied().filter(|i| !done.contains(i)).collect();
        let file = std::fs::OpenOptions::new().create(true).append(true).open(log).map_err(|e| Error::io(log, e))?;
        let file = std::sync::Mutex::new(file);
        let obs = ctl.observer();
        obs.phase("multistart", Some(indices.len() as u64));
        let n_done = std::sync::atomic::AtomicU64::new(done.len() as u64);
        obs.progress(done.len() as u64, "");
        let results: Vec<Result<Option<StartRecord>>> = pending
            .par_iter()
            .map(|&l| {
                if ctl.interrupted() {
                    return Ok(None);
                }
                let rec = self.start(l, ctl);
                if rec.status == FitStatus::Interrupted {
                    return Ok(None);
                }
                let mut line = serde_json::to_string(&rec).map_err(|e| Error::Numerical(format!("cannot serialise a start record: {e}")))?;
                line.push('\n');
                {
                    let mut f = file.lock().map_err(|_| Error::Numerical("log file lock poisoned".into()))?;
                    f.write_all(line.as_bytes()).map_err(|e| Error::io(log, e))?;
                    f.flush().map_err(|e| Error::io(log, e))?;
                }
                obs.progress(n_done.fetch_add(1, std::sync::atomic::Ordering::Relaxed) + 1, "");
                Ok(Some(rec))
            })
            .collect();
        obs.phase_done();
        let mut stopped = false;
        for r in results {
            match r? {
                Some(rec) => have.push(rec),
                None => stopped = true,
            }
        }
        have.sort_by_key(|r| r.index);
        Ok((have, stopped))
    }
}

/// Merges shard logs: every line must carry the same fingerprint; duplicates
/// must agree. Returns the records sorted by index.
pub fn merge_logs(paths: &[&Path]) -> Result<Vec<StartRecord>> {
    let mut all: std::collections::BTreeMap<usize, StartRecord> = std::collections::BTreeMap::new();
    let mut hash: Option<String> = None;
    for p in paths {
        let (recs, _) = read_log(p)?;
        for r in recs {
            match &hash {
                None => hash = Some(r.hash.clone()),
                Some(h) if *h != r.hash => {
                    return Err(Error::invalid(
                        p.display().to_string(),
                        "hash",
                        format!("start {} belongs to another design or data ({} ≠ {h})", r.index, r.hash),
                    ));
                }
                _ => {}
            }
            if let Some(old) = all.get(&r.index) {
                if *old != r {
                    return Err(Error::invalid(
                        p.display().to_string(),
                        "index",
                        format!("start {} appears twice with different results", r.index),
                    ));
                }
            }
            all.insert(r.index, r);
        }
    }
    Ok(all.into_values().collect())
}
