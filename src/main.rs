//! The `idexp` command line: parse, load the design, call the library, write
//! the outputs. Errors are reported with their context and a non-zero exit.

use clap::{Parser, Subcommand};
use idexp::optim::{Control, Observer, StopFlag};
use std::sync::{Arc, Mutex};

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
    Robot(idexp::robot::cli::RobotArgs),
    /// Closed-loop rigid-body simulation of identification runs (writes runs for `identify`).
    Simulate(idexp::sim::cli::SimulateArgs),
    /// Identify base parameters from runs (OLS/WLS/projection/ML, reduction, gravity/friction experiments).
    Identify(Box<idexp::ident::cli::IdentifyArgs>),
    /// Write odd random-phase orthogonal multisine references and their crest factors.
    Multisine(idexp::frf::cli::MultisineArgs),
    /// Estimate FRFs G = Y U⁻¹ with covariance (from runs.json, or simulated from a design).
    Frf(idexp::frf::cli::FrfArgs),
    /// Fit the elastic gray-box model from many starts (resumable, shardable).
    Fit(idexp::frf::cli::FitArgs),
    /// Merge multistart shard logs into the single-run result.
    Merge(idexp::frf::cli::MergeArgs),
    /// Optimal measurement positions by convex relaxed experiment design (D/A/E, Clarabel).
    Positions(idexp::positions::cli::PositionsArgs),
    /// Design an optimal excitation trajectory (GA + gradient refinement) from a design file.
    Excite(idexp::excitation::cli::ExciteArgs),
    /// Identifiability of a given trajectory CSV: rank, condition number, unexcited parameters.
    Assess(idexp::excitation::cli::AssessArgs),
}

fn main() {
    restore_default_sigpipe();
    let cli = Cli::parse();
    if let Err(e) = run(cli) {
        eprintln!("error: {e:#}");
        std::process::exit(1);
    }
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

fn run(cli: Cli) -> anyhow::Result<()> {
    if let Some(t) = cli.threads {
        rayon::ThreadPoolBuilder::new().num_threads(t.max(1)).build_global()?;
    }
    // First Ctrl-C: ask long jobs to stop and write what they have; second: exit now.
    let stop = StopFlag::new();
    let handler_stop = stop.clone();
    let _ = ctrlc::set_handler(move || {
        if handler_stop.requested() {
            std::process::exit(130);
        }
        eprintln!("\nstopping: finishing the current step and writing results (Ctrl-C again to abort)");
        handler_stop.request();
    });
    let ctl = Control::new().with_stop(stop).with_observer(Arc::new(IndicatifObserver::default()));
    let ctl = &ctl;
    match &cli.cmd {
        Cmd::Robot(a) => idexp::robot::cli::run(a)?,
        Cmd::Simulate(a) => idexp::sim::cli::run(a, ctl)?,
        Cmd::Identify(a) => idexp::ident::cli::run(a, ctl)?,
        Cmd::Multisine(a) => idexp::frf::cli::run_multisine(a)?,
        Cmd::Frf(a) => idexp::frf::cli::run_frf(a, ctl)?,
        Cmd::Fit(a) => idexp::frf::cli::run_fit(a, ctl)?,
        Cmd::Merge(a) => idexp::frf::cli::run_merge(a)?,
        Cmd::Positions(a) => idexp::positions::cli::run(a, ctl)?,
        Cmd::Excite(a) => idexp::excitation::cli::run_excite(a, ctl)?,
        Cmd::Assess(a) => idexp::excitation::cli::run_assess(a)?,
    }
    Ok(())
}

/// Progress bars on stderr for the run-control observer (temporary home
/// until the front end moves to `src/bin/idexp/`): one bar per phase,
/// hidden when `IDEXP_NO_PROGRESS` is set.
#[derive(Default)]
struct IndicatifObserver {
    bar: Mutex<Option<indicatif::ProgressBar>>,
}

impl Observer for IndicatifObserver {
    fn phase(&self, name: &str, total: Option<u64>) {
        use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};
        let pb = ProgressBar::new(total.unwrap_or(0));
        if std::env::var_os("IDEXP_NO_PROGRESS").is_some() {
            pb.set_draw_target(ProgressDrawTarget::hidden());
        }
        if let Ok(style) = ProgressStyle::with_template("{prefix} [{elapsed_precise}] {bar:30} {pos}/{len} {msg}") {
            pb.set_style(style);
        }
        pb.set_prefix(name.to_string());
        if let Ok(mut b) = self.bar.lock() {
            if let Some(old) = b.replace(pb) {
                old.finish_and_clear();
            }
        }
    }
    fn progress(&self, done: u64, msg: &str) {
        if let Ok(b) = self.bar.lock() {
            if let Some(pb) = b.as_ref() {
                if pb.length().is_some_and(|l| done > l) {
                    pb.set_length(done);
                }
                pb.set_position(done);
                if !msg.is_empty() {
                    pb.set_message(msg.to_string());
                }
            }
        }
    }
    fn phase_done(&self) {
        if let Ok(mut b) = self.bar.lock() {
            if let Some(pb) = b.take() {
                pb.finish_and_clear();
            }
        }
    }
    fn note(&self, msg: &str) {
        if let Ok(b) = self.bar.lock() {
            match b.as_ref() {
                Some(pb) => pb.set_message(msg.to_string()),
                None => eprintln!("{msg}"),
            }
        }
    }
}
