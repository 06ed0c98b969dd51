//! `lineflow bench layers`: linefit's depth layers applied again, in this process, to a finished run's final lines
//! (`lines3d.csv`, with its `lines2d.csv` and `poses.csv`) of a synthetic building, and scored before and after
//! as `bench buildings` scores a run (the moved lines are written to `lines3d_layers.csv` in the run folder). For trying the layers' settings in seconds on tuning buildings.
use std::process::ExitCode;

use anyhow::{Context, Result};
use lineflow_eval::lines3d::evaluate;
use lineflow_eval::Truth;
use lineflow_formats::{read_lines3d, read_poses, Line3Row};
use lineflow_linefit::{line_elements, snap, snap_layers, FitParams, Merged};
use lineflow_linegeom::SlaveSegments;

use crate::buildings::{print_header, print_kinds, print_row, row};
use crate::linemap::{frame_segments, run_segments, FinishedRun};

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
    let run = args.of.run.as_path();
    let scene = args.of.scene()?;
    let camera = *scene.camera();
    let truth = Truth::from_scene(scene);
    let poses = read_poses(&run.join("poses.csv")).with_context(|| format!("{}: the run's poses", run.display()))?;
    let lines = read_lines3d(&run.join("lines3d.csv")).with_context(|| format!("{}: the run's lines", run.display()))?;
    let segments = run_segments(run)?;
    let frames = frame_segments(&camera, &poses, &segments);
    let views: Vec<SlaveSegments> = frames
        .iter()
        .map(|(pose, segments)| SlaveSegments { pose: *pose, segments })
        .collect();
    let mut merged: Vec<Merged> = lines.iter().map(Merged::from_row).collect();
    let start = std::time::Instant::now();
    let stats = snap_layers(&camera, &mut merged, &views, &fit);
    snap(&mut merged, &fit);
    let seconds = start.elapsed().as_secs_f64();
    let pose_list: Vec<lineflow_photogrammetry::Pose> = poses.iter().map(|p| p.pose).collect();
    let after: Vec<Line3Row> = line_elements(&merged, &fit, Some(&camera), &pose_list)
        .iter()
        .map(Line3Row::from)
        .collect();
    println!(
        "layers on {} ({} lines, {} views), {seconds:.2} s: {stats:?}\n",
        args.of.building,
        lines.len(),
        views.len()
    );
    print_header();
    let before = row(
        format!("{} the run's lines3d.csv", args.of.building),
        &evaluate(&truth, &lines),
        f64::NAN,
    );
    let moved = row(format!("{} on the layers", args.of.building), &evaluate(&truth, &after), seconds);
    print_row(&before);
    print_row(&moved);
    print_kinds([&before, &moved].into_iter());
    lineflow_formats::write_lines3d(&run.join("lines3d_layers.csv"), &after)?;
    Ok(ExitCode::SUCCESS)
}
