//! `idexp plan designs/<file>.toml [--out DIR] [--rehearse SEEDS] [--json]`:
//! the cheapest repetitions of the candidate experiments meeting every
//! accuracy target; the folder is [`idexp::plan::output`]'s.

use crate::Outcome;
use idexp::optim::Control;
use idexp::plan::output::{report_text, write_outputs};
use idexp::plan::{rehearse, run_design, PlanDesign, PlanStatus};
use std::path::{Path, PathBuf};
use std::time::SystemTime;

/// `idexp plan ...`
#[derive(clap::Args, Debug)]
pub struct PlanArgs {
    /// Plan design file (TOML).
    pub design: PathBuf,
    /// Output folder (default: out/<design name>).
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Rehearse the plan: simulate it with this many noise seeds, identify each with the study engine, and report the achieved σ beside the prediction.
    #[arg(long, default_value_t = 0)]
    pub rehearse: usize,
    /// Print plan.json's contents instead of the text report.
    #[arg(long)]
    pub json: bool,
}

/// Runs `idexp plan`.
pub fn run(args: &PlanArgs, ctl: &Control) -> anyhow::Result<Outcome> {
    let started = SystemTime::now();
    let design = PlanDesign::read(&args.design)?;
    let dir = args.design.parent().map(Path::to_path_buf).unwrap_or_else(|| PathBuf::from("."));
    let out = args.out.clone().unwrap_or_else(|| PathBuf::from("out").join(&design.name));
    idexp::io::folder::check_out_dir(&out)?;
    let mut run = run_design(&design, &dir, ctl)?;
    if args.rehearse > 0 && run.solution.status == PlanStatus::Planned {
        match rehearse(&run, None, args.rehearse, &dir, ctl) {
            Ok(r) => run.rehearsal = Some(r),
            Err(idexp::Error::Interrupted) => {}
            Err(e) => return Err(e.into()),
        }
    }
    write_outputs(&run, &out, Some(started))?;
    if args.json {
        print!("{}", idexp::io::read_to_string(&out.join("plan.json"))?);
    } else {
        print!("{}", report_text(&run));
        println!("outputs: {}", out.display());
    }
    Ok(match run.solution.status {
        PlanStatus::Planned if crate::interrupted(ctl) => Outcome::Interrupted,
        PlanStatus::Planned => Outcome::Done,
        PlanStatus::Interrupted => Outcome::Interrupted,
        PlanStatus::Unreachable => Outcome::Unusable(format!(
            "unreachable targets: {}",
            run.solution.refused.iter().map(|r| r.label.as_str()).collect::<Vec<_>>().join(", ")
        )),
        PlanStatus::OverBudget => Outcome::Unusable(format!(
            "over budget: the cheapest plan meeting every target needs {:.1} s, the budget is {:.1} s; report.txt gives the best plan within it",
            run.solution.cost,
            run.solution.budget.unwrap_or(f64::NAN)
        )),
        PlanStatus::Failed => Outcome::Unusable(format!("the relaxation ended {}", run.solution.solver_status)),
    })
}
