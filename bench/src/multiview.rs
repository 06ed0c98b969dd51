//! `lineflow bench multiview`: linefit's multi-view re-estimate applied again, in this process, to a finished run's
//! final lines of a synthetic building, with the stage's defaults and with the given settings, each scored as
//! `bench buildings` scores a run (the variant's lines are written to `lines3d_multiview.csv` in the run folder).
//! For trying the re-estimate's settings in seconds on tuning buildings.
use std::process::ExitCode;

use anyhow::Result;
use lineflow_eval::lines3d::evaluate;
use lineflow_linefit::{refine_multiview, snap, FitParams};

use crate::buildings::{print_header, print_kinds, print_row, row, Row};
use crate::final_lines::FinalLines;
use crate::linemap::FinishedRun;

/// What `lineflow bench multiview` is asked.
#[derive(Debug, clap::Args)]
pub struct MultiviewBench {
    #[command(flatten)]
    pub of: FinishedRun,
    /// Parameter override KEY=VALUE of the linefit stage for the variant (repeatable).
    #[arg(long)]
    pub set: Vec<String>,
    /// Re-estimate with the true poses instead of the run's (how much of the lines' error the orientation leaves).
    #[arg(long)]
    pub truth_poses: bool,
}

/// `lineflow bench multiview RUN --building B [--scale S] [--seed N] [--truth-poses] [--set KEY=VALUE]...`
pub fn bench_multiview(args: &MultiviewBench) -> Result<ExitCode> {
    let defaults = FitParams::default();
    let variant: FitParams = lineflow_runtime::launch::params_from_overrides(&args.set)?;
    lineflow_runtime::StageParams::validate(&variant)?;
    let run = FinalLines::load(&args.of, args.truth_poses)?;
    let views = run.views();
    let refined = |fit: &FitParams, label: &str| -> Row {
        let mut merged = run.merged();
        let start = std::time::Instant::now();
        let (moved, rms_px) = refine_multiview(&run.camera, &mut merged, &views, fit);
        snap(&mut merged, fit);
        let seconds = start.elapsed().as_secs_f64();
        println!(
            "{label}: {moved} of {} lines re-estimated (residual RMS {rms_px:.2} px) in {seconds:.2} s",
            merged.len()
        );
        let rows = run.rows(&merged, fit);
        if !args.set.is_empty() && std::ptr::eq(fit, &variant) {
            if let Err(e) = lineflow_formats::write_lines3d(&args.of.run.join("lines3d_multiview.csv"), &rows) {
                eprintln!("warning: lines3d_multiview.csv not written: {e}");
            }
        }
        row(format!("{} {label}", args.of.building), &evaluate(&run.truth, &rows), seconds)
    };
    let rows = [
        row(
            format!("{} the run's lines3d.csv", args.of.building),
            &evaluate(&run.truth, &run.lines),
            f64::NAN,
        ),
        refined(&defaults, "re-estimated, defaults"),
        refined(
            &variant,
            &format!(
                "re-estimated, {}",
                if args.set.is_empty() {
                    "defaults".to_owned()
                } else {
                    args.set.join(" ")
                }
            ),
        ),
    ];
    println!();
    print_header();
    rows.iter().for_each(print_row);
    print_kinds(rows.iter());
    Ok(ExitCode::SUCCESS)
}
