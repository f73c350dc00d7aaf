//! The dedicated one-joint fits of paper 002 §3.2 as a study: a study whose
//! every `[[experiment]]` names its `joint` (kind `gravity` or `friction`)
//! fits each entry on its own ([`crate::ident::experiments`]) instead of
//! stacking base-parameter rows. The entries are read and filtered as every
//! study entry is (`load.rs`: files or logs, coordinates, filter,
//! velocities); the gravity fits come first, so that a friction entry can
//! take its joint's gravity from one of them (`gravity = "<entry>"`), from a
//! gravity.json (`gravity = "….json"`), fit it alongside (`"fit"`) or leave
//! it out (`"none"`: a vertical axis). The one-run command line
//! (`idexp identify ROBOT RUN --experiment gravity|friction --joint J`) is a
//! one-entry study of this kind.
//!
//! The output folder: `study.json`, `report.txt` (a line per entry), and per
//! entry `gravity.json` + `gravity.svg` or `friction.json` + `friction.svg`
//! (with its own `report.txt`): in the folder itself for a study of one
//! entry, else in `<entry name>/`; `status.json` last.

use super::load::{read_entry, EntryOptions, Read};
use super::{ExperimentKind, GravityChoice, Inputs, StudyDesign};
use crate::error::{Error, Result};
use crate::ident::experiments::{friction_experiment, gravity_experiment, FrictionFit, GravityFit, GravityTerm};
use crate::ident::{process_with, Method, Processed};
use crate::io::status::RunState;
use crate::optim::Control;
use std::path::{Path, PathBuf};

/// One entry's fit.
#[derive(Debug, Clone)]
pub enum JointFit {
    /// The gravity fit (§3.2.1).
    Gravity(GravityFit),
    /// The friction fit (§3.2.2), the speed below which samples were left
    /// out and where its gravity term came from (in words).
    Friction {
        /// The fit.
        fit: FrictionFit,
        /// |q̇| below it left out (the entry's `min_speed`).
        min_speed: f64,
        /// "fitted alongside", "none" or the source of the gravity fit.
        gravity_source: String,
    },
}

/// One dedicated entry, fitted.
#[derive(Debug, Clone)]
pub struct DedicatedEntry {
    /// The entry's name.
    pub name: String,
    /// The joint (1-based).
    pub joint: usize,
    /// The files read.
    pub files: Vec<PathBuf>,
    /// The processed run (filtered, its derivatives).
    pub pr: Processed,
    /// The fit.
    pub fit: JointFit,
}

/// A study of dedicated one-joint fits ([`run_dedicated`]).
#[derive(Debug, Clone)]
pub struct DedicatedResult {
    /// The design.
    pub design: StudyDesign,
    /// The entries in the design's order.
    pub entries: Vec<DedicatedEntry>,
}

/// Runs a study of dedicated one-joint fits ([`StudyDesign::is_dedicated`];
/// paths relative to `dir`, data in `inputs` taken from memory).
pub fn run_dedicated(design: &StudyDesign, dir: &Path, inputs: &Inputs, ctl: &Control) -> Result<DedicatedResult> {
    design.validate_with("study", &inputs.entries)?;
    if !design.is_dedicated() {
        return Err(Error::invalid(
            "study",
            "joint",
            "no [[experiment]] names a `joint`: this study identifies the model (run_study), it has no dedicated one-joint fit",
        ));
    }
    let robot = match &inputs.robot {
        Some(r) => r.clone(),
        None => crate::robot::load(&dir.join(&design.robot))?,
    };
    let obs = ctl.observer();
    obs.phase("identify read", Some(design.experiment.len() as u64));
    // gravity entries first: a friction entry may take its joint's gravity from one
    let mut order: Vec<usize> = (0..design.experiment.len()).collect();
    order.sort_by_key(|&i| design.experiment[i].kind != ExperimentKind::Gravity);
    let mut done: Vec<Option<DedicatedEntry>> = vec![None; design.experiment.len()];
    for (k, &i) in order.iter().enumerate() {
        if ctl.interrupted() {
            return Err(Error::Interrupted);
        }
        let spec = &design.experiment[i];
        let ctx = format!("experiment {} ({})", i + 1, spec.resolved_name());
        let joint = spec.joint.unwrap_or(0);
        if joint > robot.dof() {
            return Err(Error::invalid(
                &ctx,
                "joint",
                format!("{joint}: robot `{}` has {} joints", robot.name, robot.dof()),
            ));
        }
        let o = EntryOptions {
            method: Method::Wls,
            sample_limit: design.sample_limit,
            dead_band: design.dead_band,
            allow_incomplete: design.allow_incomplete,
            given: inputs.entries.get(&spec.resolved_name()),
        };
        let Read { name, run, filter, .. } = read_entry(&robot, spec, dir, &o)?;
        let pr = process_with(&run, &filter, spec.velocity_from)?.decimated(spec.decimate);
        let files: Vec<String> = run.files.iter().map(|f| f.display().to_string()).collect();
        let in_entry = |e: Error| e.map_context(|c| format!("{} (experiment `{name}`, {c})", files.join(", ")));
        let fit = match spec.kind {
            ExperimentKind::Gravity => JointFit::Gravity(gravity_experiment(&pr, joint).map_err(in_entry)?),
            _ => {
                let from_file;
                let (term, gravity_source) = match spec.gravity_choice() {
                    GravityChoice::Fit => (GravityTerm::Fit, "fitted alongside".to_string()),
                    GravityChoice::Zero => (GravityTerm::Zero, "none".to_string()),
                    GravityChoice::File(f) => {
                        let p = dir.join(&f);
                        let text = crate::io::read_to_string(&p)?;
                        from_file = serde_json::from_str::<GravityFit>(&text).map_err(|e| Error::parse(&p, e.to_string()))?;
                        if from_file.joint != joint {
                            return Err(Error::invalid(
                                &ctx,
                                "gravity",
                                format!("{}: a gravity fit of joint {}, this entry is joint {joint}", p.display(), from_file.joint),
                            ));
                        }
                        (GravityTerm::Given(&from_file), format!("from the gravity experiment {}", p.display()))
                    }
                    GravityChoice::Entry(g) => {
                        let fit = done.iter().flatten().find_map(|d| match &d.fit {
                            JointFit::Gravity(f) if d.name == g => Some(f),
                            _ => None,
                        });
                        // the design checked that the entry exists, is a gravity entry and has this joint
                        let fit = fit.ok_or_else(|| Error::invalid(&ctx, "gravity", format!("`{g}`: no gravity fit of that name")))?;
                        (GravityTerm::Given(fit), format!("from the gravity experiment `{g}`"))
                    }
                };
                let fit = friction_experiment(&pr, joint, term, spec.min_speed).map_err(in_entry)?;
                JointFit::Friction {
                    fit,
                    min_speed: spec.min_speed,
                    gravity_source,
                }
            }
        };
        obs.progress(k as u64 + 1, &name);
        done[i] = Some(DedicatedEntry {
            name,
            joint,
            files: run.files.clone(),
            pr,
            fit,
        });
    }
    obs.phase_done();
    Ok(DedicatedResult {
        design: design.clone(),
        entries: done.into_iter().flatten().collect(),
    })
}

impl DedicatedEntry {
    /// The entry's JSON (the fit: gravity.json or friction.json).
    pub fn json(&self) -> serde_json::Value {
        match &self.fit {
            JointFit::Gravity(g) => serde_json::to_value(g),
            JointFit::Friction { fit, .. } => serde_json::to_value(fit),
        }
        .unwrap_or_default()
    }

    /// Writes the entry's files into `dir` (see the module documentation)
    /// and returns its report line.
    fn write(&self, dir: &Path) -> Result<String> {
        crate::ident::output::write_joint_fit(dir, self.joint, &self.pr, &self.fit)
    }

    /// "gravity" or "friction".
    pub fn kind_name(&self) -> &'static str {
        match self.fit {
            JointFit::Gravity(_) => "gravity",
            JointFit::Friction { .. } => "friction",
        }
    }

    /// The entry's report line (what its report.txt says).
    pub fn text(&self) -> String {
        crate::ident::output::fit_text(self.joint, &self.fit)
    }
}

impl DedicatedResult {
    /// The report: a line per entry.
    pub fn text(&self) -> String {
        self.entries.iter().map(|e| e.text()).collect()
    }

    /// The fits as JSON: the fit itself for one entry, else `{name: fit}`.
    pub fn json(&self) -> serde_json::Value {
        match self.entries.as_slice() {
            [e] => e.json(),
            es => serde_json::Value::Object(es.iter().map(|e| (e.name.clone(), e.json())).collect()),
        }
    }

    /// Writes the folder of the module documentation into `dir`, status.json
    /// last; returns the files written and the state.
    pub fn write(&self, dir: &Path, started: Option<std::time::SystemTime>) -> Result<(Vec<PathBuf>, RunState)> {
        std::fs::create_dir_all(dir).map_err(|e| Error::io(dir, e))?;
        let mut files = Vec::new();
        let design = serde_json::to_string_pretty(&self.design).map_err(|x| Error::Numerical(x.to_string()))?;
        crate::io::write_atomic(&dir.join("study.json"), design.as_bytes())?;
        files.push(dir.join("study.json"));
        let one = self.entries.len() == 1;
        let mut text = String::new();
        for e in &self.entries {
            let sub = if one { dir.to_path_buf() } else { dir.join(&e.name) };
            text.push_str(&e.write(&sub)?);
            let stem = e.kind_name();
            files.extend([sub.join(format!("{stem}.json")), sub.join(format!("{stem}.svg")), sub.join("report.txt")]);
        }
        if !one {
            crate::io::write_atomic(&dir.join("report.txt"), text.as_bytes())?;
            files.push(dir.join("report.txt"));
        }
        let detail = self
            .entries
            .iter()
            .map(|e| format!("{} experiment, joint {}", e.kind_name(), e.joint))
            .collect::<Vec<_>>()
            .join("; ");
        let summary = serde_json::json!({
            "dedicated": self.entries.iter().map(|e| serde_json::json!({ "name": e.name, "experiment": e.kind_name(), "joint": e.joint })).collect::<Vec<_>>()
        });
        let fp = crate::io::status::fingerprint_of(&self.design)?;
        crate::io::status::write_status(dir, "identify", RunState::Complete, detail, started, fp, summary)?;
        files.push(dir.join("status.json"));
        Ok((files, RunState::Complete))
    }
}
