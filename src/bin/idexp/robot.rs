//! `idexp robot info|torques|regressor|mjcf`: inspect a robot, evaluate its
//! dynamics on a states CSV (the tables are [`idexp::params::info`]'s) and
//! write it as MJCF for MuJoCo.

use crate::Outcome;
use anyhow::Context;
use idexp::optim::Control;
use idexp::params::info::RobotInfo;
use idexp::params::stream::{stream_table, stream_table_to_file, TableKind};
use idexp::params::{BaseOptions, BaseParams};
use std::io::Write;
use std::path::{Path, PathBuf};

/// `idexp robot ...`
#[derive(clap::Args, Debug)]
pub struct RobotArgs {
    /// What to do with the robot.
    #[command(subcommand)]
    pub cmd: RobotCmd,
}

/// Robot subcommands.
#[derive(clap::Subcommand, Debug)]
pub enum RobotCmd {
    /// Joints, limits, drives, standard and base parameters (with their groupings); what of a URDF is left out of the model and the file each collision shape was read from.
    Info {
        /// Robot file (.toml robot file or .urdf).
        robot: PathBuf,
        /// Machine-readable JSON instead of text.
        #[arg(long)]
        json: bool,
        /// Rank tolerance of the base-parameter computation (relative residual).
        #[arg(long, alias = "tol", default_value_t = 1e-6)]
        rank_tol: f64,
        /// Number of random states stacked for the base parameters.
        #[arg(long, default_value_t = 200)]
        samples: usize,
    },
    /// Inverse-dynamics torques (rigid body + drives + friction) for each row of a states CSV.
    Torques {
        /// Robot file.
        robot: PathBuf,
        /// States CSV with columns q1..qn, qd1..qdn, qdd1..qddn (other columns ignored).
        #[arg(long)]
        states: PathBuf,
        /// Output folder: writes `torques.csv` there (default: the CSV on standard output).
        #[arg(long)]
        out: Option<PathBuf>,
    },
    /// Regressor rows (n per state) in standard or base parameters.
    Regressor {
        /// Robot file.
        robot: PathBuf,
        /// States CSV with columns q1..qn, qd1..qdn, qdd1..qddn.
        #[arg(long)]
        states: PathBuf,
        /// Base-parameter regressor instead of the standard one.
        #[arg(long)]
        base: bool,
        /// Output folder: writes `regressor.csv` there (default: the CSV on standard output).
        #[arg(long)]
        out: Option<PathBuf>,
    },
    /// The robot with its nominal parameters as MJCF for MuJoCo (bodies, inertials, joints, armature = Ia, damping = Fv, frictionloss = Fc).
    Mjcf {
        /// Robot file.
        robot: PathBuf,
        /// Output folder: writes `robot.xml` there (default: the MJCF on standard output).
        #[arg(long)]
        out: Option<PathBuf>,
    },
}

/// Loads a robot for a command that needs no collision geometry: geometry
/// that could not be loaded (a mesh not found) is a warning, not an error.
pub fn load_warn(path: &Path) -> anyhow::Result<idexp::robot::Robot> {
    let r = idexp::robot::load(path)?;
    if let Some(why) = &r.geometry_error {
        eprintln!("warning: {}: {why} (not needed here: only collision checks use it)", path.display());
    }
    Ok(r)
}

/// Runs a robot subcommand (nothing long-running: the control is unused).
pub fn run(args: &RobotArgs, _ctl: &Control) -> anyhow::Result<Outcome> {
    match &args.cmd {
        RobotCmd::Info {
            robot,
            json,
            rank_tol,
            samples,
        } => {
            if !(rank_tol.is_finite() && *rank_tol > 0.0) {
                anyhow::bail!("--rank-tol: expected a positive tolerance, got {rank_tol}");
            }
            let r = load_warn(robot)?;
            let info = RobotInfo::new(&r, *rank_tol, *samples)?;
            // what of the URDF was left out, and where each collision shape came from
            let prov = idexp::robot::provenance::provenance(robot)?;
            if *json {
                let mut v = serde_json::to_value(&info)?;
                if let Some(o) = v.as_object_mut() {
                    o.insert("left_out".into(), serde_json::to_value(&prov.left_out)?);
                    o.insert("collision_geometry".into(), serde_json::to_value(&prov.collision)?);
                }
                crate::print_json(&v)?;
            } else {
                print!("{}{}", info.text(), prov.text());
            }
        }
        RobotCmd::Torques { robot, states, out } => {
            let r = load_warn(robot)?;
            stream(&r, states, TableKind::Torques, out.as_deref(), "torques.csv")?;
        }
        RobotCmd::Regressor { robot, states, base, out } => {
            let r = load_warn(robot)?;
            let bp = if *base {
                Some(BaseParams::compute(&r, &BaseOptions::default())?)
            } else {
                None
            };
            stream(&r, states, TableKind::Regressor(bp.as_ref()), out.as_deref(), "regressor.csv")?;
        }
        RobotCmd::Mjcf { robot, out } => {
            let r = load_warn(robot)?;
            match out {
                Some(dir) => println!("written to {}", idexp::robot::export::write_mjcf(&r, dir)?.display()),
                None => print!("{}", idexp::robot::export::mjcf_string(&r)),
            }
        }
    }
    Ok(Outcome::Done)
}

/// Streams the table to `<out>/<file>` (atomically, and says where), or to
/// standard output: read, computed and written block by block.
fn stream(r: &idexp::robot::Robot, states: &Path, kind: TableKind<'_>, out: Option<&Path>, file: &str) -> anyhow::Result<()> {
    match out {
        Some(dir) => {
            let path = dir.join(file);
            stream_table_to_file(r, states, kind, &path)?;
            println!("written to {}", path.display());
        }
        None => {
            let stdout = std::io::stdout();
            let mut w = std::io::BufWriter::with_capacity(1 << 20, stdout.lock());
            stream_table(r, states, kind, &mut w)?;
            w.flush().context("writing to standard output")?;
        }
    }
    Ok(())
}
