//! `idexp positions designs/<file>.toml [--out DIR]`: optimal measurement
//! positions; the output folder is [`idexp::positions::output`]'s.

use crate::Outcome;
use idexp::optim::Control;
use idexp::positions::output::{report_text, write_outputs, write_plan_exports, PlanMotion};
use idexp::positions::{run_design, PositionsDesign, Status};
use std::path::{Path, PathBuf};
use std::time::SystemTime;

/// `idexp positions ...`
#[derive(clap::Args, Debug)]
pub struct PositionsArgs {
    /// Design file (TOML).
    pub design: PathBuf,
    /// Output folder (default: out/<design name>).
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Override the design's seed (random candidate sample).
    #[arg(long)]
    pub seed: Option<u64>,
    /// Print report.json's contents instead of the text report.
    #[arg(long)]
    pub json: bool,
    /// Also write the plan's poses for a controller: ur (movej sequence), ros2 (JointTrajectory waypoints), csv.
    #[arg(long, value_delimiter = ',')]
    pub export: Vec<String>,
    /// Dwell per measurement at each pose (s).
    #[arg(long, default_value_t = 2.0)]
    pub dwell: f64,
    /// Joint speed of the moves between poses (rad/s).
    #[arg(long, default_value_t = 0.5)]
    pub move_speed: f64,
    /// Joint acceleration of the moves between poses (rad/s²).
    #[arg(long, default_value_t = 1.0)]
    pub move_acceleration: f64,
}

/// Runs `idexp positions`.
pub fn run(args: &PositionsArgs, ctl: &Control) -> anyhow::Result<Outcome> {
    let started = SystemTime::now();
    let mut design = PositionsDesign::read(&args.design)?;
    if let Some(s) = args.seed {
        design.seed = s;
    }
    let dir = args.design.parent().map(Path::to_path_buf).unwrap_or_else(|| PathBuf::from("."));
    let out = args.out.clone().unwrap_or_else(|| PathBuf::from("out").join(&design.name));
    idexp::io::folder::check_out_dir(&out)?;
    let formats = if args.export.is_empty() {
        None
    } else {
        Some(crate::export::formats(&args.export)?)
    };
    let run = run_design(&design, &dir, ctl)?;
    write_outputs(&run, &out, Some(started))?;
    if let Some(f) = formats {
        let motion = PlanMotion {
            speed: args.move_speed,
            acceleration: args.move_acceleration,
            dwell: args.dwell,
            approach: 5.0,
        };
        for p in write_plan_exports(&run, &out, &f, &motion)? {
            eprintln!("  wrote {}", p.display());
        }
    }
    if args.json {
        let text = idexp::io::read_to_string(&out.join("report.json"))?;
        print!("{text}");
    } else {
        print!("{}", report_text(&run));
        println!("outputs: {}", out.display());
    }
    Ok(if run.relaxed.status == Status::Interrupted || crate::interrupted(ctl) {
        Outcome::Interrupted
    } else {
        Outcome::Done
    })
}
