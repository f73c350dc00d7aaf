//! `idexp view OUT_FOLDER` and `idexp view --robot ROBOT --trajectory traj.csv
//! [--design design.toml]`: the interactive 3D preview page (`preview.html`).

use crate::Outcome;
use anyhow::bail;
use idexp::optim::Control;
use idexp::preview::{write_for_folder, write_for_trajectory, PreviewOptions};
use std::path::PathBuf;

/// `idexp view`: write the 3D preview page of a trajectory.
#[derive(clap::Args, Debug)]
pub struct ViewArgs {
    /// Output folder of `idexp excite` (design.json, coefficients.json, report.json).
    #[arg(required_unless_present = "trajectory", conflicts_with_all = ["robot", "trajectory", "design"])]
    pub folder: Option<PathBuf>,
    /// Robot file (.toml or .urdf), with --trajectory.
    #[arg(long, requires = "trajectory")]
    pub robot: Option<PathBuf>,
    /// Trajectory CSV: t, q1..qn, qd1..qdn (segment used when present), e.g. an excite trajectory.csv.
    #[arg(long, requires = "robot")]
    pub trajectory: Option<PathBuf>,
    /// Excitation design (TOML) whose obstacles, workspace and limits to show, with --trajectory.
    #[arg(long, requires = "trajectory")]
    pub design: Option<PathBuf>,
    /// Folder that receives preview.html (default: the output folder, or the trajectory's folder).
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Display frames per second of trajectory time.
    #[arg(long, default_value_t = 30.0)]
    pub fps: f64,
}

/// Runs `idexp view`.
pub fn run(a: &ViewArgs, _ctl: &Control) -> anyhow::Result<Outcome> {
    if !(a.fps.is_finite() && a.fps > 0.0 && a.fps <= 1000.0) {
        bail!("--fps: expected frames per second in (0, 1000], got {}", a.fps);
    }
    let opts = PreviewOptions { fps: a.fps };
    let written = match (&a.folder, &a.robot, &a.trajectory) {
        (Some(folder), _, _) => {
            if !folder.is_dir() {
                bail!("{}: not a folder (expected the output folder of `idexp excite`)", folder.display());
            }
            write_for_folder(folder, a.out.as_deref(), &opts)?
        }
        (None, Some(robot), Some(csv)) => write_for_trajectory(robot, csv, a.design.as_deref(), a.out.as_deref(), &opts)?,
        _ => bail!("give an output folder of `idexp excite`, or --robot and --trajectory"),
    };
    println!(
        "{}: {} frames of {} trajectory rows, {:.1} MB; open it in a browser",
        written.path.display(),
        written.frames,
        written.rows,
        written.bytes as f64 / 1e6
    );
    Ok(Outcome::Done)
}
