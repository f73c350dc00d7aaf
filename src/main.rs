//! The `idexp` command line: parse, load the design, call the library, write
//! the outputs. Errors are reported with their context and a non-zero exit.

use clap::{Parser, Subcommand};

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
    let _ = ctrlc::set_handler(|| {
        if idexp::io::stop::requested() {
            std::process::exit(130);
        }
        eprintln!("\nstopping: finishing the current step and writing results (Ctrl-C again to abort)");
        idexp::io::stop::request();
    });
    match &cli.cmd {
        Cmd::Robot(a) => idexp::robot::cli::run(a)?,
        Cmd::Simulate(a) => idexp::sim::cli::run(a)?,
        Cmd::Identify(a) => idexp::ident::cli::run(a)?,
        Cmd::Multisine(a) => idexp::frf::cli::run_multisine(a)?,
        Cmd::Frf(a) => idexp::frf::cli::run_frf(a)?,
        Cmd::Fit(a) => idexp::frf::cli::run_fit(a)?,
        Cmd::Merge(a) => idexp::frf::cli::run_merge(a)?,
        Cmd::Positions(a) => idexp::positions::cli::run(a)?,
        Cmd::Excite(a) => idexp::excitation::cli::run_excite(a)?,
        Cmd::Assess(a) => idexp::excitation::cli::run_assess(a)?,
    }
    Ok(())
}
