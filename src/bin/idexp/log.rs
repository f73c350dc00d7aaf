//! `idexp log convert|info`: robot logs (RTDE recorder CSV, CSV with a
//! column map, headerless CSV, ROS 2 bags) into idexp's run CSV, and what a
//! bag holds. The readers are [`idexp::data::logs`]'s.

use crate::Outcome;
use idexp::data::logs::{bag_info, read_log, LogFormat, LogSpec};
use idexp::io::status::{fingerprint_of, summary_of, write_status, RunState};
use idexp::optim::Control;
use std::path::{Path, PathBuf};
use std::time::SystemTime;

/// `idexp log ...`
#[derive(clap::Args, Debug)]
pub struct LogArgs {
    /// What to do with the log.
    #[command(subcommand)]
    pub cmd: LogCmd,
}

/// Log subcommands.
#[derive(clap::Subcommand, Debug)]
pub enum LogCmd {
    /// Convert a robot log into idexp's run CSV (`<out>/run.csv`, a run folder for `identify`).
    Convert {
        /// The log: a CSV file, or a ROS 2 bag (its folder, .mcap or .db3 file).
        log: PathBuf,
        /// Robot file (joint names, joint count, drives for currents).
        #[arg(long)]
        robot: PathBuf,
        /// The log's form (default: bag for a folder, .mcap or .db3; else the map file's).
        #[arg(long, value_parser = ["rtde", "csv", "headerless", "bag"])]
        format: Option<String>,
        /// Map file (TOML, a log spec: column map, column list, topic, …).
        #[arg(long)]
        map: Option<PathBuf>,
        /// The JointState topic of a bag (default: the only one).
        #[arg(long)]
        topic: Option<String>,
        /// Output folder: writes `run.csv`, `log.json` (what was read) and `status.json`.
        #[arg(long)]
        out: PathBuf,
        /// Print the report as JSON instead of text.
        #[arg(long)]
        json: bool,
    },
    /// Topics, message counts, joint names, time span and rate of a ROS 2 bag.
    Info {
        /// The bag (its folder, .mcap or .db3 file).
        log: PathBuf,
        /// Print the report as JSON instead of text.
        #[arg(long)]
        json: bool,
    },
}

/// The spec from `--map`, `--format` and `--topic`.
fn spec_of(log: &Path, format: Option<&str>, map: Option<&Path>, topic: Option<&str>) -> anyhow::Result<LogSpec> {
    let m = map.map(LogSpec::read).transpose()?;
    let name = map.map_or_else(|| "command line".to_string(), |m| m.display().to_string());
    let f = format.map(str::parse::<LogFormat>).transpose()?;
    Ok(LogSpec::resolve(m, &name, f, topic.map(String::from), Some(log))?)
}

/// Runs a log subcommand (nothing long-running: the control is unused).
pub fn run(args: &LogArgs, _ctl: &Control) -> anyhow::Result<Outcome> {
    match &args.cmd {
        LogCmd::Convert {
            log,
            robot,
            format,
            map,
            topic,
            out,
            json,
        } => {
            let started = SystemTime::now();
            let spec = spec_of(log, format.as_deref(), map.as_deref(), topic.as_deref())?;
            let r = idexp::robot::load(robot)?;
            let read = read_log(log, &r, &spec)?;
            let fp = fingerprint_of(&(&spec, log, robot))?;
            idexp::io::folder::begin(out, "log convert", &fp)?;
            read.rep.write(&out.join("run.csv"))?;
            idexp::io::write_json(&out.join("log.json"), &serde_json::json!({ "spec": &spec, "report": &read.report }))?;
            let uniform = read.report.steps.is_none_or(|s| s.uniform);
            write_status(
                out,
                "log convert",
                RunState::Complete,
                format!("{} samples from {}", read.report.samples, log.display()),
                Some(started),
                fp,
                summary_of(&read.report)?,
            )?;
            if *json {
                crate::print_json(&read.report)?;
            } else {
                println!("{}", read.report.text());
                println!("written to {}", out.join("run.csv").display());
                if !uniform {
                    println!(
                        "note: the steps are irregular; `idexp identify` reads run CSVs with uniform steps (the identification study resamples irregular logs)"
                    );
                }
            }
            Ok(Outcome::Done)
        }
        LogCmd::Info { log, json } => {
            let info = bag_info(log)?;
            if *json {
                crate::print_json(&info)?;
            } else {
                print!("{}", info.text());
            }
            Ok(Outcome::Done)
        }
    }
}
