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
    /// Design an optimal excitation trajectory (GA + gradient refinement) from a design file.
    Excite(idexp::excitation::cli::ExciteArgs),
    /// Identifiability of a given trajectory CSV: rank, condition number, unexcited parameters.
    Assess(idexp::excitation::cli::AssessArgs),
}

fn main() {
    let cli = Cli::parse();
    if let Err(e) = run(cli) {
        eprintln!("error: {e:#}");
        std::process::exit(1);
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
        Cmd::Excite(a) => idexp::excitation::cli::run_excite(a)?,
        Cmd::Assess(a) => idexp::excitation::cli::run_assess(a)?,
    }
    Ok(())
}
