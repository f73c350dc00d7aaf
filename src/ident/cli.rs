//! `idexp identify`: identification from measured (or simulated) runs, and the
//! dedicated gravity and friction experiments (`--experiment`).

use super::experiments::{friction_experiment, gravity_experiment, FrictionFit, GravityFit, GravityTerm};
use super::{identify, run_trajectory, Essential, Filter, FilterChoice, IdentOptions, Method, ReduceOptions, Run, Weights};
use crate::error::{Error, Result};
use crate::params::{BaseOptions, BaseParams};
use crate::trajectory::FourierTrajectory;
use serde::Serialize;
use std::path::{Path, PathBuf};

/// Position filter choice on the command line.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum FilterKind {
    /// Fourier filtering when the run's trajectory is known (`trajectory.json` next to the run or `--trajectory`), else low-pass.
    Auto,
    /// Fourier filtering (needs the trajectory).
    Fourier,
    /// Zero-phase low-pass (`--cutoff`) + central differences.
    Lowpass,
    /// Central differences only.
    None,
}

/// Dedicated experiments of paper 002 §3.2.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Experiment {
    /// Gravity slopes: fit τ = k sin(q + q_off) + c± (eq. 23).
    Gravity,
    /// Bang-bang acceleration: fit inertia and asymmetric Coulomb + viscous friction (eq. 2).
    Friction,
}

/// `idexp identify <robot> <run>...`
#[derive(clap::Args, Debug, Serialize)]
pub struct IdentifyArgs {
    /// Robot file (.toml or .urdf).
    pub robot: PathBuf,
    /// The run: a folder of repetition CSVs, or the files themselves.
    #[arg(required = true)]
    pub run: Vec<PathBuf>,
    /// Validation run (folder or files).
    #[arg(long, num_args = 1..)]
    pub validate: Vec<PathBuf>,
    /// Estimator.
    #[arg(long, value_enum, default_value_t = Method::Wls)]
    pub method: Method,
    /// WLS weights: per sample (paper 000 eq. 7–9) or per joint.
    #[arg(long, value_enum, default_value_t = Weights::Sample)]
    pub weights: Weights,
    /// Position filter.
    #[arg(long, value_enum, default_value_t = FilterKind::Auto)]
    pub filter: FilterKind,
    /// Low-pass cut-off (Hz).
    #[arg(long, default_value_t = 10.0)]
    pub cutoff: f64,
    /// Fourier trajectory of the run (coefficients.json); default: trajectory.json in the run folder.
    #[arg(long)]
    pub trajectory: Option<PathBuf>,
    /// Fourier trajectory of the validation run; default: trajectory.json in its folder.
    #[arg(long)]
    pub validate_trajectory: Option<PathBuf>,
    /// Harmonics kept by Fourier filtering (default: the trajectory's n_h).
    #[arg(long)]
    pub harmonics: Option<usize>,
    /// Keep every k-th sample after filtering.
    #[arg(long, default_value_t = 1)]
    pub decimate: usize,
    /// Sensitivity-based model reduction (paper 000 Algorithm 1).
    #[arg(long)]
    pub reduce: bool,
    /// Reduction tolerance e_tol on the relative growth of e*_j.
    #[arg(long, default_value_t = 0.05)]
    pub tol: f64,
    /// Essential parameters: auto (friction if every joint moves), none, friction, or a comma-separated list of base names.
    #[arg(long, default_value = "auto")]
    pub essential: String,
    /// Projection method FIR lags "M1,M2" (default: chosen by cross-validation over repetitions).
    #[arg(long)]
    pub fir_lags: Option<String>,
    /// truth.json of a simulated run: compare the estimates with the true base parameters.
    #[arg(long)]
    pub truth: Option<PathBuf>,
    /// Dedicated experiment instead of the full identification.
    #[arg(long, value_enum)]
    pub experiment: Option<Experiment>,
    /// Joint (1-based) of the dedicated experiment.
    #[arg(long)]
    pub joint: Option<usize>,
    /// gravity.json of a gravity experiment on the same joint (friction experiment; else gravity is fitted alongside).
    #[arg(long)]
    pub gravity_fit: Option<PathBuf>,
    /// Friction experiment on a joint without gravity torque (vertical axis): no gravity term.
    #[arg(long)]
    pub no_gravity: bool,
    /// Rows of a joint slower than this fraction of its largest speed are left out of the identification.
    #[arg(long, default_value_t = 0.1)]
    pub slow_ratio: f64,
    /// Speed below which rows are left out: of the identification (default 0.01) and of the friction experiment (default 0.05) (rad/s or m/s).
    #[arg(long)]
    pub min_speed: Option<f64>,
    /// Output folder (default: out/identify_<run folder name>).
    #[arg(long)]
    pub out: Option<PathBuf>,
}

fn default_out(run: &[PathBuf], suffix: &str) -> PathBuf {
    let stem = run
        .first()
        .map(|p| {
            let p = if p.is_dir() {
                p.clone()
            } else {
                p.parent().map(Path::to_path_buf).unwrap_or_default()
            };
            p.file_name().map(|s| s.to_string_lossy().into_owned()).unwrap_or_else(|| "run".into())
        })
        .unwrap_or_else(|| "run".into());
    PathBuf::from("out").join(format!("identify_{stem}{suffix}"))
}

fn filter_choice(a: &IdentifyArgs, traj: Option<&FourierTrajectory>) -> Result<FilterChoice> {
    Ok(match a.filter {
        FilterKind::Auto if traj.is_none() => FilterChoice::Given(Filter::LowPass { cutoff: a.cutoff }),
        FilterKind::Auto => FilterChoice::Auto,
        FilterKind::Fourier => match traj {
            Some(t) => FilterChoice::Given(Filter::Fourier {
                omega: t.omega,
                n_h: t.n_harmonics(),
            }),
            None => {
                return Err(Error::invalid(
                    "identify",
                    "--filter fourier",
                    "needs the run's Fourier trajectory: pass --trajectory coefficients.json or put trajectory.json in the run folder",
                ))
            }
        },
        FilterKind::Lowpass => FilterChoice::Given(Filter::LowPass { cutoff: a.cutoff }),
        FilterKind::None => FilterChoice::Given(Filter::None),
    })
}

fn parse_lags(s: &str) -> Result<(usize, usize)> {
    let parts: Vec<&str> = s.split(',').map(str::trim).collect();
    let bad = || Error::invalid("identify", "--fir-lags", format!("expected two non-negative integers \"M1,M2\", got {s:?}"));
    if parts.len() != 2 {
        return Err(bad());
    }
    Ok((parts[0].parse().map_err(|_| bad())?, parts[1].parse().map_err(|_| bad())?))
}

#[derive(Serialize)]
struct Status<'a> {
    status: &'a str,
    what: &'a str,
}

/// Runs `idexp identify`, stopped by `ctl`.
pub fn run(a: &IdentifyArgs, ctl: &crate::optim::Control) -> Result<()> {
    let robot = crate::robot::load(&a.robot)?;
    let run = Run::read(&a.run, robot.dof())?;
    let traj = match &a.trajectory {
        Some(p) => Some(FourierTrajectory::load(p)?),
        None => run_trajectory(&run)?,
    };
    if let Some(exp) = a.experiment {
        return run_experiment(a, exp, &run);
    }
    if !(a.tol > 0.0 && a.tol.is_finite()) {
        return Err(Error::invalid("identify", "--tol", format!("expected a positive tolerance, got {}", a.tol)));
    }
    let essential = match a.essential.as_str() {
        "auto" => Essential::Auto,
        "none" => Essential::None,
        "friction" => Essential::Friction,
        s => Essential::Names(s.split(',').map(|x| x.trim().to_string()).filter(|x| !x.is_empty()).collect()),
    };
    let mut opts = IdentOptions {
        method: a.method,
        weights: a.weights,
        filter: filter_choice(a, traj.as_ref())?,
        harmonics: a.harmonics,
        decimate: a.decimate,
        slow_ratio: a.slow_ratio,
        min_speed: a.min_speed.unwrap_or(0.01),
        reduce: a.reduce.then(|| ReduceOptions {
            tol: a.tol,
            essential,
            weights: a.weights,
            ..Default::default()
        }),
        ..Default::default()
    };
    if let Some(l) = &a.fir_lags {
        opts.projection.lags = Some(parse_lags(l)?);
    }
    let vrun = if a.validate.is_empty() {
        None
    } else {
        Some(Run::read(&a.validate, robot.dof())?)
    };
    let vtraj = match (&a.validate_trajectory, &vrun) {
        (Some(p), _) => Some(FourierTrajectory::load(p)?),
        (None, Some(v)) => run_trajectory(v)?,
        _ => None,
    };
    let base = BaseParams::compute(&robot, &BaseOptions::default())?;
    let mut id = identify(&robot, &base, &run, traj.as_ref(), vrun.as_ref().map(|v| (v, vtraj.as_ref())), &opts, ctl)?;
    if let Some(t) = &a.truth {
        let truth = crate::sim::Truth::read(t)?;
        id.estimate.compare_truth(&truth.base_names, &truth.base)?;
    }
    let out = a.out.clone().unwrap_or_else(|| default_out(&a.run, ""));
    id.write(&out)?;
    crate::io::write_json(&out.join("options.json"), &serde_json::json!({ "arguments": a, "options": opts }))?;
    crate::io::write_json(
        &out.join("status.json"),
        &Status {
            status: if ctl.interrupted() { "interrupted" } else { "complete" },
            what: &id.estimate.status,
        },
    )?;
    print!("{}", id.estimate.text());
    println!("\nwritten to {}", out.display());
    Ok(())
}

fn run_experiment(a: &IdentifyArgs, exp: Experiment, run: &Run) -> Result<()> {
    use crate::io::plot::{write_svg, Panel, Series};
    let joint = a
        .joint
        .ok_or_else(|| Error::invalid("identify --experiment", "--joint", "name the joint (1-based) of the dedicated experiment"))?;
    let pr = super::process(run, &Filter::LowPass { cutoff: a.cutoff })?;
    let j = joint.saturating_sub(1);
    let out = a.out.clone().unwrap_or_else(|| default_out(&a.run, &format!("_{exp:?}").to_lowercase()));
    std::fs::create_dir_all(&out).map_err(|e| Error::io(&out, e))?;
    let text = match exp {
        Experiment::Gravity => {
            let g = gravity_experiment(&pr, joint)?;
            crate::io::write_json(&out.join("gravity.json"), &g)?;
            let q: Vec<f64> = pr.q.iter().map(|v| v[j]).collect();
            let tau: Vec<f64> = pr.tau.iter().map(|v| v[j]).collect();
            let fit: Vec<f64> = q.iter().map(|&x| g.torque(x)).collect();
            write_svg(
                &out.join("gravity.svg"),
                &format!("gravity experiment, joint {joint}"),
                &[Panel {
                    title: "measured torque and fitted gravity k sin(q + q_off)".into(),
                    x_label: "q (rad)".into(),
                    y_label: "torque (N·m)".into(),
                    series: vec![Series::points("measured", q.clone(), tau), Series::line("gravity fit", q, fit)],
                    ..Default::default()
                }],
                1,
            )?;
            format!(
                "gravity experiment, joint {joint}: k = {:.6} N·m, q_off = {:.6} rad ({:.3}°), c+ = {:.6}, c- = {:.6} N·m at {:.4} rad/s, {} samples, rms {:.4e} N·m\n",
                g.k,
                g.q_off,
                g.q_off.to_degrees(),
                g.offset_pos,
                g.offset_neg,
                g.speed,
                g.samples,
                g.rms
            )
        }
        Experiment::Friction => {
            let grav: Option<GravityFit> = match &a.gravity_fit {
                Some(p) => {
                    let text = crate::io::read_to_string(p)?;
                    Some(serde_json::from_str(&text).map_err(|e| Error::parse(p, e.to_string()))?)
                }
                None => None,
            };
            let term = match (&grav, a.no_gravity) {
                (Some(g), _) => GravityTerm::Given(g),
                (None, true) => GravityTerm::Zero,
                (None, false) => GravityTerm::Fit,
            };
            let f: FrictionFit = friction_experiment(&pr, joint, term, a.min_speed.unwrap_or(0.05))?;
            crate::io::write_json(&out.join("friction.json"), &f)?;
            let v: Vec<f64> = pr.qd.iter().map(|s| s[j]).collect();
            let tf: Vec<f64> = (0..pr.len())
                .map(|p| pr.tau[p][j] - f.inertia * pr.qdd[p][j] - f.gravity_k * (pr.q[p][j] + f.gravity_q_off).sin())
                .collect();
            let mut vs: Vec<f64> = v.iter().copied().filter(|x| x.abs() > a.min_speed.unwrap_or(0.05)).collect();
            vs.sort_by(f64::total_cmp);
            let model: Vec<f64> = vs
                .iter()
                .map(|&x| if x > 0.0 { f.fc_pos + f.fv_pos * x } else { f.fc_neg + f.fv_neg * x })
                .collect();
            write_svg(
                &out.join("friction.svg"),
                &format!("friction experiment, joint {joint}"),
                &[Panel {
                    title: "τ − J q̈ − τ_g against q̇, and the fitted friction (eq. 2)".into(),
                    x_label: "q̇ (rad/s)".into(),
                    y_label: "torque (N·m)".into(),
                    series: vec![Series::points("measured", v, tf), Series::line("fit", vs, model)],
                    ..Default::default()
                }],
                1,
            )?;
            format!(
                "friction experiment, joint {joint}: J = {:.6} kg·m², Fc+ = {:.6}, Fv+ = {:.6}, Fc- = {:.6}, Fv- = {:.6} (std {:?}), gravity k = {:.6}, q_off = {:.6} ({}), {} samples, rms {:.4e} N·m\n",
                f.inertia,
                f.fc_pos,
                f.fv_pos,
                f.fc_neg,
                f.fv_neg,
                f.std.iter().map(|s| format!("{s:.2e}")).collect::<Vec<_>>(),
                f.gravity_k,
                f.gravity_q_off,
                if f.gravity_given { "from the gravity experiment" } else if a.no_gravity { "none" } else { "fitted alongside" },
                f.samples,
                f.rms
            )
        }
    };
    crate::io::write_atomic(&out.join("report.txt"), text.as_bytes())?;
    crate::io::write_json(&out.join("options.json"), a)?;
    crate::io::write_json(
        &out.join("status.json"),
        &Status {
            status: "complete",
            what: "ok",
        },
    )?;
    print!("{text}");
    println!("written to {}", out.display());
    Ok(())
}
