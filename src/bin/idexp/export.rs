//! `idexp export <coefficients.json> --format ur,ros2,csv` (a trajectory
//! designed earlier) and the `--export` options of `idexp excite`.

use crate::Outcome;
use anyhow::{bail, Context};
use idexp::optim::Control;
use idexp::trajectory::export::{program_name, write_exports, CsvOptions, Designed, ExportOptions, Format, UrController};
use idexp::trajectory::lead::Delivered;
use std::path::{Path, PathBuf};

/// UR controller generation on the command line.
#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum UrArg {
    /// CB3: servoj at 125 Hz.
    Cb3,
    /// e-Series: servoj at 500 Hz.
    ESeries,
}

/// Angle unit of the CSV export.
#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum UnitArg {
    /// Degrees (prismatic joints stay in m).
    Deg,
    /// Radians.
    Rad,
}

/// Options shared by `idexp excite --export` and `idexp export`.
#[derive(clap::Args, Debug, Clone)]
pub struct ExportOpts {
    /// Rate of the ROS 2 and CSV exports (Hz; default: the design's controller_rate). URScript uses the controller's rate.
    #[arg(long)]
    pub rate: Option<f64>,
    /// UR controller: cb3 (125 Hz) or e-series (500 Hz).
    #[arg(long, value_enum, default_value = "e-series")]
    pub ur: UrArg,
    /// Angle unit of the CSV export.
    #[arg(long, value_enum, default_value = "rad")]
    pub csv_units: UnitArg,
    /// CSV export with velocities and accelerations (default: positions only).
    #[arg(long)]
    pub csv_derivatives: bool,
    /// URScript movej to the start pose: joint speed (rad/s).
    #[arg(long, default_value_t = 0.5)]
    pub approach_speed: f64,
    /// URScript movej to the start pose: joint acceleration (rad/s²).
    #[arg(long, default_value_t = 1.0)]
    pub approach_acceleration: f64,
}

/// `idexp export`: a designed trajectory in controller formats.
#[derive(clap::Args, Debug)]
pub struct ExportArgs {
    /// coefficients.json written by `idexp excite`.
    pub coefficients: PathBuf,
    /// Formats, comma separated: ur, ros2, csv.
    #[arg(long, value_delimiter = ',', required = true)]
    pub format: Vec<String>,
    /// Output folder (default: the folder of coefficients.json).
    #[arg(long)]
    pub out: Option<PathBuf>,
    #[command(flatten)]
    pub opts: ExportOpts,
}

/// Parses the format list.
pub fn formats(list: &[String]) -> anyhow::Result<Vec<Format>> {
    let mut out = Vec::new();
    for s in list {
        out.push(Format::parse(s)?);
    }
    if out.is_empty() {
        bail!("--export/--format: expected at least one of ur, ros2, csv");
    }
    Ok(out)
}

/// Writes the exports of `d` into `dir`; returns the paths written.
#[allow(clippy::too_many_arguments)] // the pieces of one export, from two commands
pub fn export(
    dir: &Path,
    design: &str,
    names: &[String],
    revolute: &[bool],
    d: &Delivered,
    formats: Vec<Format>,
    default_rate: f64,
    o: &ExportOpts,
) -> anyhow::Result<Vec<PathBuf>> {
    let rate = o.rate.unwrap_or(default_rate);
    if !(rate.is_finite() && rate > 0.0 && rate <= 100_000.0) {
        bail!("--rate: expected a rate in (0, 100000] Hz, got {rate}");
    }
    let opts = ExportOptions {
        formats,
        rate,
        ur: match o.ur {
            UrArg::Cb3 => UrController::Cb3,
            UrArg::ESeries => UrController::ESeries,
        },
        csv: CsvOptions {
            derivatives: o.csv_derivatives,
            degrees: o.csv_units == UnitArg::Deg,
        },
        stem: program_name(design),
        approach: (o.approach_acceleration, o.approach_speed),
    };
    Ok(write_exports(dir, names, revolute, d, &opts)?)
}

/// Runs `idexp export`.
pub fn run(a: &ExportArgs, _ctl: &Control) -> anyhow::Result<Outcome> {
    let f = formats(&a.format)?;
    let des = Designed::load(&a.coefficients).with_context(|| format!("idexp export {}", a.coefficients.display()))?;
    let dir = a
        .out
        .clone()
        .unwrap_or_else(|| a.coefficients.parent().map(Path::to_path_buf).unwrap_or_else(|| PathBuf::from(".")));
    println!(
        "export `{}`: {:.2} s from home at rest to home at rest ({} {} of {} s)",
        des.design,
        des.delivered.duration(),
        des.delivered.periods,
        match idexp::trajectory::Motion::ends(&des.delivered.periodic) {
            idexp::trajectory::Ends::Periodic => "period(s)",
            idexp::trajectory::Ends::RestToRest => "rest-to-rest motion(s)",
        },
        des.delivered.periodic.duration_text()
    );
    for p in export(&dir, &des.design, &des.names, &des.revolute, &des.delivered, f, des.controller_rate, &a.opts)? {
        println!("  wrote {}", p.display());
    }
    Ok(Outcome::Done)
}
