//! `idexp positions designs/<file>.toml [--out DIR]`: optimal measurement
//! positions; the output folder is [`idexp::positions::output`]'s.

use crate::Outcome;
use idexp::optim::Control;
use idexp::positions::output::{report_text, write_outputs};
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
    let run = run_design(&design, &dir, ctl)?;
    write_outputs(&run, &out, Some(started))?;
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
