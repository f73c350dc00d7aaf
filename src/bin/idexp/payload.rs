//! `idexp payload excite|identify`: a tool's or payload's ten inertial
//! parameters, the robot's own model known (docs/payload.md).

use crate::excite::{run_excite, ExciteArgs};
use crate::Outcome;
use anyhow::bail;
use idexp::excitation::design::ExciteDesign;
use idexp::excitation::objective::Columns;
use idexp::io::status::fingerprint_of;
use idexp::optim::Control;
use idexp::payload::PayloadDesign;
use std::path::{Path, PathBuf};
use std::time::SystemTime;

/// `idexp payload`.
#[derive(clap::Args, Debug)]
pub struct PayloadArgs {
    #[command(subcommand)]
    pub cmd: PayloadCmd,
}

/// The payload subcommands.
#[derive(clap::Subcommand, Debug)]
pub enum PayloadCmd {
    /// Design a payload excitation: an excite design with a [payload] and objective.columns = "payload".
    Excite(ExciteArgs),
    /// Identify a payload from loaded (and unloaded) runs and write it for URScript, Franka, KUKA, URDF, MJCF;
    /// with a [gains] table: calibrate the drive gains with a known mass instead.
    Identify(IdentifyArgs),
}

/// `idexp payload identify`.
#[derive(clap::Args, Debug)]
pub struct IdentifyArgs {
    /// Payload design file (TOML): robot, frame, [[loaded]], [[unloaded]], [guess], export.
    pub design: PathBuf,
    /// Output folder (default: out/<design name>/).
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Print payload.json's contents instead of the report.
    #[arg(long)]
    pub json: bool,
}

/// Runs `idexp payload ...`.
pub fn run(a: &PayloadArgs, ctl: &Control) -> anyhow::Result<Outcome> {
    match &a.cmd {
        PayloadCmd::Excite(e) => {
            let d = ExciteDesign::load(&e.design)?;
            if d.payload.is_none() || !matches!(d.objective.columns, Columns::Payload | Columns::Gains) {
                bail!(
                    "payload excite {}: a payload excitation needs a [payload] section (frame, nominal mass, com, inertia) and objective.columns = \"payload\" (or \"gains\": a drive-gain calibration with that known mass); for the robot's own parameters use idexp excite",
                    e.design.display()
                );
            }
            run_excite(e, ctl)
        }
        PayloadCmd::Identify(i) => identify(i, ctl),
    }
}

fn identify(a: &IdentifyArgs, ctl: &Control) -> anyhow::Result<Outcome> {
    let started = SystemTime::now();
    let design = PayloadDesign::read(&a.design)?;
    let dir = a.design.parent().map(Path::to_path_buf).unwrap_or_default();
    let out = a.out.clone().unwrap_or_else(|| PathBuf::from("out").join(&design.name));
    idexp::io::folder::check_out_dir(&out)?;
    if design.gains.is_some() {
        let g = idexp::payload::gains::calibrate(&design, &dir, ctl)?;
        return crate::write_folder(
            &out,
            "payload identify",
            &fingerprint_of(&design)?,
            || g.write(&design, &out, Some(started)),
            a.json.then_some(&g),
            &g.text(),
            g.unusable_reason(),
        );
    }
    let res = idexp::payload::run(&design, &dir, ctl)?;
    crate::write_folder(
        &out,
        "payload identify",
        &fingerprint_of(&design)?,
        || res.write(&out, Some(started)),
        a.json.then_some(&res.estimate),
        &res.estimate.text(),
        res.estimate.unusable_reason(),
    )
}
