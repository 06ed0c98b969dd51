//! `lineflow bench layers`: linefit's depth layers applied again, in this process, to a finished run's final lines
//! (`lines3d.csv`, with its `lines2d.csv` and `poses.csv`) of a synthetic building, and scored before and after
//! as `bench buildings` scores a run (the moved lines are written to `lines3d_layers.csv` in the run folder). For trying the layers' settings in seconds on tuning buildings.
use std::process::ExitCode;

use anyhow::Result;
use lineflow_eval::lines3d::evaluate;
use lineflow_linefit::{snap, snap_layers, FitParams};

use crate::buildings::{print_header, print_kinds, print_row, row};
use crate::final_lines::FinalLines;
use crate::linemap::FinishedRun;

/// What `lineflow bench layers` is asked.
#[derive(Debug, clap::Args)]
pub struct LayersBench {
    #[command(flatten)]
    pub of: FinishedRun,
    /// Parameter override KEY=VALUE of the linefit stage (repeatable); `layer_k_sigma` defaults to 3 here.
    #[arg(long)]
    pub set: Vec<String>,
}

/// `lineflow bench layers RUN --building B [--scale S] [--seed N] [--set KEY=VALUE]...`
pub fn bench_layers(args: &LayersBench) -> Result<ExitCode> {
    let mut set = vec!["layer_k_sigma=3".to_owned()];
    set.extend(args.set.iter().cloned());
    let fit: FitParams = lineflow_runtime::launch::params_from_overrides(&set)?;
    lineflow_runtime::StageParams::validate(&fit)?;
    let run = FinalLines::load(&args.of, false)?;
    let views = run.views();
    let mut merged = run.merged();
    let start = std::time::Instant::now();
    let stats = snap_layers(&run.camera, &mut merged, &views, &fit);
    snap(&mut merged, &fit);
    let seconds = start.elapsed().as_secs_f64();
    let after = run.rows(&merged, &fit);
    println!(
        "layers on {} ({} lines, {} views), {seconds:.2} s: {stats:?}\n",
        args.of.building,
        run.lines.len(),
        views.len()
    );
    print_header();
    let before = row(
        format!("{} the run's lines3d.csv", args.of.building),
        &evaluate(&run.truth, &run.lines),
        f64::NAN,
    );
    let moved = row(
        format!("{} on the layers", args.of.building),
        &evaluate(&run.truth, &after),
        seconds,
    );
    print_row(&before);
    print_row(&moved);
    print_kinds([&before, &moved].into_iter());
    lineflow_formats::write_lines3d(&args.of.run.join("lines3d_layers.csv"), &after)?;
    Ok(ExitCode::SUCCESS)
}
