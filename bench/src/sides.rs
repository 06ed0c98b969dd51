//! `lineflow bench sides`: the half-plane test of `lineflow_linegeom::sides` on a finished run's final lines
//! (`lines3d.csv` and `poses.csv`) of a synthetic building, its images rendered again: each line classed
//! structure whose two sides the images find to be one surface becomes texture. Prints the verdicts against the
//! truth (a line within 2 GSD of a true edge, on average over its length, is on an edge) and the run scored
//! before and after; the lines after are written to `lines3d_sides.csv` in the run folder.
use std::collections::BTreeMap;
use std::process::ExitCode;

use anyhow::{Context, Result};
use lineflow_eval::lines3d::evaluate;
use lineflow_eval::Truth;
use lineflow_formats::{read_lines3d, read_poses};
use lineflow_linegeom::{sides, PhotoView, SideRule, Verdict};
use lineflow_messages::LineClass;
use lineflow_photogrammetry::Vec3;
use rayon::prelude::*;

use crate::buildings::{print_header, print_row, row};
use crate::linemap::{rendered_photo, FinishedRun};

/// What `lineflow bench sides` is asked.
#[derive(Debug, clap::Args)]
pub struct SidesBench {
    #[command(flatten)]
    pub of: FinishedRun,
    /// Setting KEY=VALUE of the test (`lineflow_linegeom::SideRule`, repeatable).
    #[arg(long)]
    pub set: Vec<String>,
}

/// `lineflow bench sides RUN --building B [--scale S] [--seed N] [--set KEY=VALUE]...`
pub fn bench_sides(args: &SidesBench) -> Result<ExitCode> {
    let rule: SideRule = lineflow_runtime::launch::params_from_overrides(&args.set)?;
    if let Err(e) = rule.validate() {
        anyhow::bail!("{} must be {} (got {})", e.name, e.requirement, e.value);
    }
    let run = args.of.run.as_path();
    let scene = args.of.scene()?;
    let camera = *scene.camera();
    let frames: BTreeMap<String, usize> = (0..scene.poses().len()).map(|f| (scene.image_name(f), f)).collect();
    let poses = read_poses(&run.join("poses.csv")).with_context(|| format!("{}: the run's poses", run.display()))?;
    let lines = read_lines3d(&run.join("lines3d.csv")).with_context(|| format!("{}: the run's lines", run.display()))?;
    eprintln!("rendering {} frames...", poses.len());
    let photos: Vec<_> = poses
        .par_iter()
        .filter_map(|p| Some((p.pose, rendered_photo(&scene, *frames.get(&p.image)?)?)))
        .collect();
    let views: Vec<PhotoView> = photos.iter().map(|(pose, photo)| PhotoView { pose, photo }).collect();
    let truth = Truth::from_scene(scene);
    let gsd = truth.gsd_m();
    let edges: Vec<lineflow_eval::geometry::Seg> = truth
        .lines
        .iter()
        .map(|l| lineflow_eval::geometry::Seg::new(Vec3::from(l.start), Vec3::from(l.end)))
        .collect();
    let on_edge = |a: Vec3, b: Vec3| {
        let mean = (0..5)
            .map(|i| {
                let p = a + (b - a) * ((i as f64 + 0.5) / 5.0);
                edges.iter().map(|e| e.distance(&p)).fold(f64::INFINITY, f64::min)
            })
            .sum::<f64>()
            / 5.0;
        mean <= 2.0 * gsd
    };
    let start = std::time::Instant::now();
    let full: Vec<Option<(lineflow_linegeom::SideReport, bool)>> = lines
        .par_iter()
        .map(|l| {
            (l.class == LineClass::Structure).then(|| {
                let (a, b) = (Vec3::from(l.start), Vec3::from(l.end));
                (sides(&camera, &views, &[a, b], &rule), on_edge(a, b))
            })
        })
        .collect();
    let reports: Vec<Option<(Verdict, bool)>> = full.iter().map(|r| r.as_ref().map(|(s, e)| (s.verdict, *e))).collect();
    let mut csv = String::from("id,verdict,on_edge,x0,y0,z0,x1,y1,z1,depth0,corr0,contrast0,depth1,corr1,contrast1,px_per_m\n");
    for (l, r) in lines.iter().zip(&full) {
        let Some((s, e)) = r else { continue };
        let peak = |k: usize| {
            s.peaks[k].map_or("nan,nan,nan".to_owned(), |p| {
                format!("{:.3},{:.3},{:.3}", p.depth_m, p.correlation, p.contrast)
            })
        };
        csv += &format!(
            "{},{:?},{},{:.3},{:.3},{:.3},{:.3},{:.3},{:.3},{},{},{:.1}\n",
            l.id,
            s.verdict,
            e,
            l.start[0],
            l.start[1],
            l.start[2],
            l.end[0],
            l.end[1],
            l.end[2],
            peak(0),
            peak(1),
            s.px_per_m
        );
    }
    std::fs::write(run.join("sides.csv"), csv)?;
    let seconds = start.elapsed().as_secs_f64();
    let mut counts: BTreeMap<(String, bool), usize> = BTreeMap::new();
    for (v, edge) in reports.iter().flatten() {
        *counts.entry((format!("{v:?}"), *edge)).or_default() += 1;
    }
    println!(
        "sides on {} ({} lines, {} structure, {} views), {seconds:.2} s",
        args.of.building,
        lines.len(),
        reports.iter().flatten().count(),
        views.len()
    );
    println!("\n| verdict | on an edge | off every edge |\n|---|---|---|");
    for v in ["Texture", "Step", "Unknown"] {
        let n = |e: bool| counts.get(&(v.to_owned(), e)).copied().unwrap_or(0);
        println!("| {v} | {} | {} |", n(true), n(false));
    }
    let mut after = lines.clone();
    for (l, r) in after.iter_mut().zip(&reports) {
        if matches!(r, Some((Verdict::Texture, _))) {
            l.class = LineClass::Texture;
        }
    }
    println!();
    print_header();
    let (before_report, after_report) = (evaluate(&truth, &lines), evaluate(&truth, &after));
    print_row(&row(
        format!("{} the run's lines3d.csv", args.of.building),
        &before_report,
        f64::NAN,
    ));
    print_row(&row(format!("{} after the sides", args.of.building), &after_report, seconds));
    let structure = |r: &lineflow_eval::lines3d::Lines3dReport| {
        r.classes
            .iter()
            .find(|c| c.class == "structure lines")
            .and_then(|c| c.at.iter().find(|a| a.label == "2 GSD"))
            .map_or((f64::NAN, f64::NAN), |a| (a.segment_precision, a.length_recall))
    };
    let (b, a) = (structure(&before_report), structure(&after_report));
    println!(
        "\nstructure lines at 2 GSD: precision {:.1} -> {:.1} %, length recall {:.1} -> {:.1} %",
        100.0 * b.0,
        100.0 * a.0,
        100.0 * b.1,
        100.0 * a.1
    );
    lineflow_formats::write_lines3d(&run.join("lines3d_sides.csv"), &after)?;
    Ok(ExitCode::SUCCESS)
}
