//! `idexp view OUT_FOLDER` and `idexp view --robot ROBOT --trajectory traj.csv
//! [--design design.toml]`: the interactive 3D preview page (`preview.html`).

use crate::Outcome;
use anyhow::bail;
use idexp::excitation::design::ExciteDesign;
use idexp::optim::Control;
use idexp::preview::{read_rows, write, write_for_folder, PreviewOptions, Setup};
use std::path::{Path, PathBuf};

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
    let out_file = |default_dir: &Path| -> anyhow::Result<PathBuf> {
        let dir = a.out.clone().unwrap_or_else(|| default_dir.to_path_buf());
        idexp::io::folder::check_out_dir(&dir)?;
        std::fs::create_dir_all(&dir).map_err(|e| idexp::Error::io(&dir, e))?;
        Ok(dir.join("preview.html"))
    };
    let written = match (&a.folder, &a.robot, &a.trajectory) {
        (Some(folder), _, _) => {
            if !folder.is_dir() {
                bail!("{}: not a folder (expected the output folder of `idexp excite`)", folder.display());
            }
            write_for_folder(folder, Some(&out_file(folder)?), &opts)?
        }
        (None, Some(robot_path), Some(csv)) => {
            let robot = idexp::robot::load(robot_path)?;
            let title = csv.display().to_string();
            let setup = match &a.design {
                Some(dp) => {
                    let d = ExciteDesign::load(dp)?;
                    let mut s = Setup::from_design(&d, robot, &dp.display().to_string())?;
                    s.title = format!("{} ({})", d.name, title);
                    s
                }
                None => Setup::from_robot(robot, &title)?,
            };
            let motion = read_rows(csv, setup.robot.dof())?;
            let dir = csv.parent().filter(|p| !p.as_os_str().is_empty()).unwrap_or(Path::new("."));
            write(&setup, &motion, &opts, &out_file(dir)?)?
        }
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
