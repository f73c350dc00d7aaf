//! One entry of a study read and processed ([`load_entry`]): its files (logs
//! or run CSVs, resampled and converted by the drives), its coordinates, its
//! trajectory and filter, and the rows its standstill rule keeps.

use super::{ExperimentKind, ExperimentSpec, FilterName};
use crate::data::{Run, Sampling, SamplingOptions, TorqueSource};
use crate::error::{Error, Result};
use crate::ident::{fourier_filter, in_joint_coordinates, prepare, run_trajectory, Filter, Method, Prepared};
use crate::params::BaseParams;
use crate::robot::Robot;
use crate::trajectory::FourierTrajectory;
use std::path::{Path, PathBuf};

/// One experiment or validation run, read and processed.
#[derive(Debug, Clone)]
pub struct Loaded {
    /// Its name.
    pub name: String,
    /// Its entry.
    pub spec: ExperimentSpec,
    /// The files read.
    pub files: Vec<PathBuf>,
    /// Repetitions.
    pub n_reps: usize,
    /// How the torques were obtained.
    pub torque_source: TorqueSource,
    /// What was done with the time stamps.
    pub sampling: Sampling,
    /// The processed run and its datasets.
    pub prep: Prepared,
    /// What was chosen for the entry that it did not say (in the study file's words).
    pub notes: Vec<String>,
    /// The run as read, in joint coordinates: kept for the projection
    /// method, which needs its references (None otherwise).
    pub run: Option<Run>,
}

impl Loaded {
    /// The entry's warnings: its notes, then the filter's ([`crate::ident::prepare`]).
    pub fn warnings(&self) -> Vec<String> {
        self.notes.iter().cloned().chain(crate::ident::filter_warnings(&self.prep.pr)).collect()
    }
}

/// An entry's data given in memory instead of its `files` (the Python
/// keyword form's arrays and simulated runs).
#[derive(Debug, Clone)]
pub struct Given {
    /// The run (its repetitions).
    pub run: Run,
    /// Its Fourier reference, if known.
    pub trajectory: Option<FourierTrajectory>,
    /// How its torques were obtained.
    pub torque_source: TorqueSource,
}

/// What a study's settings say to every entry ([`load_entry_with`]).
#[derive(Debug, Clone, Copy)]
pub struct EntryOptions<'a> {
    /// The estimator (the projection method keeps every row and the run).
    pub method: Method,
    /// Largest number of samples per repetition.
    pub sample_limit: usize,
    /// Coulomb dead band (rad/s or m/s).
    pub dead_band: f64,
    /// Accept run folders whose status.json is not `complete`.
    pub allow_incomplete: bool,
    /// The entry's data, when given in memory.
    pub given: Option<&'a Given>,
}

/// Reads and processes one entry of a study (paths relative to `dir`) with
/// the default Coulomb dead band ([`crate::ident::DEAD_BAND`]).
pub fn load_entry(robot: &Robot, base: &BaseParams, spec: &ExperimentSpec, dir: &Path, method: Method, sample_limit: usize) -> Result<Loaded> {
    let o = EntryOptions {
        method,
        sample_limit,
        dead_band: crate::ident::DEAD_BAND,
        allow_incomplete: false,
        given: None,
    };
    load_entry_with(robot, base, spec, dir, &o)
}

/// [`load_entry`] with the study's settings `o`.
pub fn load_entry_with(robot: &Robot, base: &BaseParams, spec: &ExperimentSpec, dir: &Path, o: &EntryOptions<'_>) -> Result<Loaded> {
    let (method, dead_band) = (o.method, o.dead_band);
    let Read {
        name,
        run,
        torque_source,
        sampling,
        filter,
        notes,
    } = read_entry(robot, spec, dir, o)?;
    let prep = prepare(robot, base, &run, filter, spec, method, dead_band).map_err(|e| e.map_context(|c| format!("experiment `{name}` ({c})")))?;
    Ok(Loaded {
        name,
        spec: spec.clone(),
        files: run.files.clone(),
        n_reps: run.n_reps(),
        torque_source,
        sampling,
        prep,
        notes,
        run: (method == Method::Projection).then_some(run),
    })
}

/// An entry's data read, in joint coordinates, with the filter its entry
/// says ([`read_entry`]).
pub(super) struct Read {
    /// The entry's name.
    pub name: String,
    /// The run (its repetitions) in joint coordinates.
    pub run: Run,
    /// How the torques were obtained.
    pub torque_source: TorqueSource,
    /// What was done with the time stamps.
    pub sampling: Sampling,
    /// The position filter.
    pub filter: Filter,
    /// What was chosen for the entry that it did not say.
    pub notes: Vec<String>,
}

/// Reads one entry's files (or its data given in memory) and chooses its
/// filter: what every estimator of the study shares before its own rows.
pub(super) fn read_entry(robot: &Robot, spec: &ExperimentSpec, dir: &Path, o: &EntryOptions<'_>) -> Result<Read> {
    let sample_limit = o.sample_limit;
    let name = spec.resolved_name();
    let paths: Vec<PathBuf> = spec.files.iter().map(|f| dir.join(f)).collect();
    for p in &paths {
        crate::io::status::require_complete(p, o.allow_incomplete)?;
    }
    let (run, torque_source, sampling) = match (o.given, &spec.log) {
        (Some(g), _) => (g.run.clone(), g.torque_source.clone(), uniform_sampling(&g.run)),
        (None, Some(l)) => {
            let (run, src, sampling, _) = crate::data::logs::read_run(&paths, robot, l, spec.resample, sample_limit)?;
            (run, src, sampling)
        }
        (None, None) => {
            let (run, src, sampling) = Run::read_drives_sampled(
                &paths,
                robot,
                spec.repetitions,
                spec.torque_from,
                spec.current_tolerance,
                Some(SamplingOptions {
                    rate: spec.resample,
                    limit: sample_limit,
                }),
            )?;
            let sampling = sampling.unwrap_or_else(|| uniform_sampling(&run));
            (run, src, sampling)
        }
    };
    if run.n_joints() != robot.dof() {
        return Err(Error::dim(format!("joints in `{name}`"), robot.dof(), run.n_joints()));
    }
    if let Some(t) = o.given.and_then(|g| g.trajectory.as_ref()) {
        if t.n_joints() != robot.dof() {
            return Err(Error::dim(format!("joints in the trajectory of `{name}`"), robot.dof(), t.n_joints()));
        }
    }
    let run = in_joint_coordinates(robot, &run, spec.coordinates)?.into_owned();
    let traj: Option<FourierTrajectory> = match (&spec.trajectory, o.given) {
        (None, Some(g)) => g.trajectory.clone(),
        (t, _) => match t {
            Some(p) => {
                let p = dir.join(p);
                let t = FourierTrajectory::load(&p)?;
                if t.n_joints() != robot.dof() {
                    return Err(Error::invalid(
                        p.display().to_string(),
                        "trajectory",
                        format!(
                            "{} joints in the trajectory, {} in robot {}: expected the experiment's own trajectory",
                            t.n_joints(),
                            robot.dof(),
                            robot.name
                        ),
                    ));
                }
                Some(t)
            }
            None => run_trajectory(&run)?,
        },
    };
    let lowpass = Filter::LowPass { cutoff: spec.cutoff };
    let mut notes = Vec::new();
    if spec.filter == FilterName::Auto && traj.is_none() && spec.kind == ExperimentKind::Excitation {
        notes.push(format!(
            "no Fourier trajectory (no `trajectory = …` and no trajectory.json beside the run): positions filtered by the zero-phase low-pass at `cutoff = {}` Hz instead of the Fourier filter; give `trajectory = \"…/coefficients.json\"` if the run follows a Fourier trajectory, or set `filter = \"lowpass\"` to say the low-pass is meant",
            spec.cutoff
        ));
    }
    let filter = match (spec.filter, &traj) {
        (FilterName::Auto, Some(t)) if spec.kind == ExperimentKind::Excitation => fourier_filter(t, spec.harmonics),
        (FilterName::Auto | FilterName::Lowpass, _) => lowpass,
        (FilterName::Fourier, Some(t)) => fourier_filter(t, spec.harmonics),
        (FilterName::Fourier, None) => {
            return Err(Error::invalid(
                format!("experiment `{name}`"),
                "filter",
                "\"fourier\" needs the Fourier trajectory: give `trajectory` or put trajectory.json beside the run",
            ))
        }
        (FilterName::None, _) => Filter::None,
    };
    Ok(Read {
        name,
        run,
        torque_source,
        sampling,
        filter,
        notes,
    })
}

/// The sampling record of a run given on a uniform grid (in memory, or read
/// without resampling).
fn uniform_sampling(run: &Run) -> Sampling {
    let (a, m, b) = crate::data::resample::step_stats(&run.reps[0].t);
    Sampling {
        irregular: false,
        min_step: a,
        median_step: m,
        max_step: b,
        resampled_to: None,
        samples: (run.reps[0].len(), run.reps[0].len()),
    }
}
