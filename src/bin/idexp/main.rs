//! The `idexp` command line: parse, load the design, call the library, print,
//! and map the outcome to the exit code.
//!
//! Exit codes: 0 success; 1 error in the input (bad file, bad value); 2 usage
//! (clap); 3 the run finished but its result is not usable (INFEASIBLE design,
//! failed solver or estimator, rank-deficient identification); 130
//! interrupted (the files written so far are valid and `status.json` says
//! `interrupted`).
//!
//! Every command runner has the shape `fn run(args, &Control) ->
//! anyhow::Result<Outcome>`; the [`Control`] carries the Ctrl-C stop flag and
//! the progress observer ([`progress::Bars`]).

mod elastic;
mod excite;
mod export;
mod identify;
mod log;
mod payload;
mod plan;
mod positions;
mod progress;
mod robot;
mod simulate;
mod view;

use clap::{Parser, Subcommand};
use idexp::optim::{Control, StopFlag};
use std::sync::Arc;

/// Design and evaluate identification experiments for industrial robots.
#[derive(Parser, Debug)]
#[command(name = "idexp", version, about, long_about = None)]
struct Cli {
    #[command(subcommand)]
    cmd: Cmd,
    /// Worker threads (default: all cores). Results do not depend on it.
    #[arg(long, global = true)]
    threads: Option<usize>,
}

#[derive(Subcommand, Debug)]
enum Cmd {
    /// Inspect a robot and evaluate its dynamics (info, torques, regressor).
    Robot(robot::RobotArgs),
    /// Closed-loop rigid-body simulation of identification runs (writes runs for `identify`).
    Simulate(simulate::SimulateArgs),
    /// Identify base parameters from runs (OLS/WLS/projection/ML, reduction, gravity/friction experiments).
    Identify(Box<identify::IdentifyArgs>),
    /// Write odd random-phase orthogonal multisine references and their crest factors.
    Multisine(elastic::MultisineArgs),
    /// Estimate FRFs G = Y U⁻¹ with covariance (from runs.json, or simulated from a design).
    Frf(elastic::FrfArgs),
    /// Fit the elastic gray-box model from many starts (resumable, shardable).
    Fit(elastic::FitArgs),
    /// Merge multistart shard logs into the single-run result.
    Merge(elastic::MergeArgs),
    /// The cheapest repetitions of candidate experiments meeting accuracy targets (SDP relaxation + rounding; --rehearse).
    Plan(plan::PlanArgs),
    /// Optimal measurement positions by convex relaxed experiment design (D/A/E, Clarabel).
    Positions(positions::PositionsArgs),
    /// Design an optimal excitation trajectory (GA + gradient refinement) from a design file.
    Excite(excite::ExciteArgs),
    /// Identifiability of a given trajectory CSV: rank, condition number, unexcited parameters.
    Assess(excite::AssessArgs),
    /// Write a designed excitation trajectory (coefficients.json) as URScript, ROS 2 JointTrajectory YAML or CSV.
    Export(export::ExportArgs),
    /// Robot logs (RTDE recorder CSV, CSV with a column map, headerless CSV, ROS 2 bags): convert to a run, inspect a bag.
    Log(log::LogArgs),
    /// Write the interactive 3D preview page (preview.html) of an excite output folder or a trajectory CSV.
    View(view::ViewArgs),
    /// A tool's or payload's mass, centre of mass and inertia: excitation design, identification, controller exports.
    Payload(payload::PayloadArgs),
}

/// How a command ended (errors are the `Err` of the runner).
#[derive(Debug, Clone, PartialEq)]
pub enum Outcome {
    /// Finished with a usable result: exit 0.
    Done,
    /// Finished, but the result is not usable (the reason): exit 3.
    Unusable(String),
    /// Stopped early; what was written is valid and marked so: exit 130.
    Interrupted,
}

/// The end of a command that runs a library job and writes its folder:
/// prepares `out` (`io::folder::begin`), writes it with `write` (files and
/// state), prints `json` with `--json` or else the text report and the file
/// count, and maps the state and `unusable` reason to the outcome.
pub fn write_folder<T: serde::Serialize + ?Sized>(
    out: &std::path::Path,
    command: &str,
    fingerprint: &str,
    write: impl FnOnce() -> idexp::Result<(Vec<std::path::PathBuf>, idexp::io::status::RunState)>,
    json: Option<&T>,
    text: &str,
    unusable: Option<String>,
) -> anyhow::Result<Outcome> {
    idexp::io::folder::begin(out, command, fingerprint)?;
    let (files, state) = write()?;
    match json {
        Some(v) => print_json(v)?,
        None => {
            print!("{text}");
            println!("\n{} files written to {}", files.len(), out.display());
        }
    }
    Ok(match (state, unusable) {
        (idexp::io::status::RunState::Interrupted, _) => Outcome::Interrupted,
        (_, Some(why)) => Outcome::Unusable(why),
        _ => Outcome::Done,
    })
}

/// Exit code of an error in the input (files, values).
const EXIT_INPUT: i32 = 1;
/// Exit code of a run whose result is not usable.
const EXIT_UNUSABLE: i32 = 3;
/// Exit code of an interrupted run (128 + SIGINT).
const EXIT_INTERRUPTED: i32 = 130;

fn main() {
    restore_default_sigpipe();
    let cli = Cli::parse();
    let code = match run(cli) {
        Ok(Outcome::Done) => 0,
        Ok(Outcome::Unusable(why)) => {
            eprintln!("result not usable: {why}");
            EXIT_UNUSABLE
        }
        Ok(Outcome::Interrupted) => {
            eprintln!("interrupted: the files written so far are valid (their status.json says \"interrupted\")");
            EXIT_INTERRUPTED
        }
        Err(e) if matches!(e.downcast_ref::<idexp::Error>(), Some(idexp::Error::Interrupted)) => {
            eprintln!("interrupted before any result existed: nothing was written");
            EXIT_INTERRUPTED
        }
        Err(e) => {
            eprintln!("error: {e:#}");
            EXIT_INPUT
        }
    };
    std::process::exit(code);
}

/// Rust ignores SIGPIPE, so `idexp ... | head` would panic in `println!` once
/// the reader closes the pipe; restore the default (quiet exit) as other
/// command-line tools behave.
fn restore_default_sigpipe() {
    #[cfg(unix)]
    // SAFETY: called once at start-up, before any thread exists; only resets a
    // signal disposition to its default.
    unsafe {
        libc::signal(libc::SIGPIPE, libc::SIG_DFL);
    }
}

/// The stop flag set by Ctrl-C: first Ctrl-C asks the run to stop and write
/// what it has; a second one exits with 130 at once.
fn install_ctrlc() -> StopFlag {
    let flag = StopFlag::new();
    let f = flag.clone();
    let _ = ctrlc::set_handler(move || {
        if f.requested() {
            idexp::io::folder::remove_live_temps();
            std::process::exit(EXIT_INTERRUPTED);
        }
        eprintln!("\nstopping: finishing the current step and writing results (Ctrl-C again to abort)");
        f.request();
    });
    flag
}

fn run(cli: Cli) -> anyhow::Result<Outcome> {
    if let Some(t) = cli.threads {
        rayon::ThreadPoolBuilder::new().num_threads(t.max(1)).build_global()?;
    }
    // the library's faer calls use a fixed split count (idexp::linalg::par);
    // the global setting covers any faer call made with faer's default
    faer::set_global_parallelism(idexp::linalg::par());
    let stop = install_ctrlc();
    let ctl = Control::new().with_stop(stop).with_observer(Arc::new(progress::Bars::new()));
    match &cli.cmd {
        Cmd::Robot(a) => robot::run(a, &ctl),
        Cmd::Simulate(a) => simulate::run(a, &ctl),
        Cmd::Identify(a) => identify::run(a, &ctl),
        Cmd::Multisine(a) => elastic::run_multisine(a, &ctl),
        Cmd::Frf(a) => elastic::run_frf(a, &ctl),
        Cmd::Fit(a) => elastic::run_fit(a, &ctl),
        Cmd::Merge(a) => elastic::run_merge(a, &ctl),
        Cmd::Plan(a) => plan::run(a, &ctl),
        Cmd::Positions(a) => positions::run(a, &ctl),
        Cmd::Excite(a) => excite::run_excite(a, &ctl),
        Cmd::Payload(a) => payload::run(a, &ctl),
        Cmd::Assess(a) => excite::run_assess(a, &ctl),
        Cmd::Export(a) => export::run(a, &ctl),
        Cmd::Log(a) => log::run(a, &ctl),
        Cmd::View(a) => view::run(a, &ctl),
    }
}

/// True once the user pressed Ctrl-C.
pub fn interrupted(ctl: &Control) -> bool {
    ctl.interrupted()
}

/// Prints `value` as pretty JSON on standard output.
pub fn print_json<T: serde::Serialize + ?Sized>(value: &T) -> anyhow::Result<()> {
    println!("{}", serde_json::to_string_pretty(value)?);
    Ok(())
}
