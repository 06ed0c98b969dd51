//! `lineflow bench multiview`: linefit's multi-view re-estimate applied again, in this process, to a finished run's
//! final lines of a synthetic building, with the stage's defaults and with the given settings, each scored as
//! `bench buildings` scores a run (the variant's lines are written to `lines3d_multiview.csv` in the run folder).
//! For trying the re-estimate's settings in seconds on tuning buildings.
use std::process::ExitCode;

use anyhow::Result;
use lineflow_eval::lines3d::evaluate;
use lineflow_linefit::{refine_multiview, snap, FitParams};
use lineflow_linegeom::line_bundle::{adjust_with_lines, LineBundleParams};
use lineflow_photogrammetry::Pose;

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
    /// Adjust the poses together with the lines on their 2-D segments first (`linegeom::line_bundle`), then
    /// re-estimate the lines with the adjusted poses; prints the poses' error against the truth before and after.
    #[arg(long)]
    pub line_bundle: bool,
    /// The variant's settings re-estimate only the plumb lines (within 1° of the vertical); the others keep the
    /// defaults.
    #[arg(long)]
    pub plumb_only: bool,
    /// Then re-estimate each plumb line from the images on one side of it only (left or right along the façade,
    /// with the variant's settings), keeping by this rule: left, right, front (the estimate nearer the cameras),
    /// back, or fit (the side with the smaller residual RMS).
    #[arg(long)]
    pub one_side: Option<OneSide>,
    /// The line bundle's prior σ of a camera centre, metres.
    #[arg(long, default_value_t = LineBundleParams::default().center_sigma_m)]
    pub bundle_center_sigma: f64,
    /// The line bundle's prior σ of a camera's rotation, radians.
    #[arg(long, default_value_t = LineBundleParams::default().rotation_sigma_rad)]
    pub bundle_rotation_sigma: f64,
    /// The line bundle's σ of a segment's plane, pixels.
    #[arg(long, default_value_t = LineBundleParams::default().sigma_px)]
    pub bundle_sigma_px: f64,
}

/// Which one-sided estimate of a plumb line `--one-side` keeps.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum OneSide {
    Left,
    Right,
    Front,
    Back,
    Fit,
}

/// `lineflow bench multiview RUN --building B [--scale S] [--seed N] [--truth-poses] [--set KEY=VALUE]...`
pub fn bench_multiview(args: &MultiviewBench) -> Result<ExitCode> {
    let defaults = FitParams::default();
    let variant: FitParams = lineflow_runtime::launch::params_from_overrides(&args.set)?;
    lineflow_runtime::StageParams::validate(&variant)?;
    let run = FinalLines::load(&args.of, args.truth_poses)?;
    let mut views = run.views();
    let mut bundled = None;
    if args.line_bundle {
        let p = LineBundleParams {
            center_sigma_m: args.bundle_center_sigma,
            rotation_sigma_rad: args.bundle_rotation_sigma,
            sigma_px: args.bundle_sigma_px,
            ..LineBundleParams::default()
        };
        let ends: Vec<_> = run.merged().iter().map(|l| [l.start, l.end]).collect();
        let start = std::time::Instant::now();
        let b = adjust_with_lines(&run.camera, &views, &ends, &p);
        println!(
            "line bundle: {} lines, {} observations, residual RMS {:.3} → {:.3} px, {} iterations, {:.2} s",
            b.lines.iter().flatten().count(),
            b.observations,
            b.rms_px[0],
            b.rms_px[1],
            b.iterations,
            start.elapsed().as_secs_f64()
        );
        let given: Vec<Pose> = views.iter().map(|v| v.pose).collect();
        print_pose_errors("poses as given", &run, &given);
        print_pose_errors("poses adjusted with the lines", &run, &b.poses);
        views = run.views_with(&b.poses);
        bundled = Some(b);
    }
    let refined = |fit: &FitParams, label: &str| -> Row {
        let mut merged = run.merged();
        let start = std::time::Instant::now();
        let (moved, rms_px) = if args.plumb_only && std::ptr::eq(fit, &variant) {
            // The plumb lines with the variant, the others with the defaults, each back in its place.
            let (a, b) = (
                refine_subset(&run, &mut merged, &views, fit, true),
                refine_subset(&run, &mut merged, &views, &defaults, false),
            );
            (a.0 + b.0, a.1.max(b.1))
        } else {
            refine_multiview(&run.camera, &mut merged, &views, fit)
        };
        if let (Some(rule), true) = (args.one_side, std::ptr::eq(fit, &variant)) {
            let n = one_sided(&run.camera, &mut merged, &views, &fit.multiview(), rule);
            println!("{label}: {n} plumb lines placed from one side's images ({rule:?})");
        }
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
    let bundle_row = bundled.as_ref().map(|b| {
        let mut merged = run.merged();
        for (l, adjusted) in merged.iter_mut().zip(&b.lines) {
            if let Some([s, e]) = adjusted {
                (l.start, l.end) = (*s, *e);
            }
        }
        snap(&mut merged, &defaults);
        row(
            format!("{} the line bundle's lines", args.of.building),
            &evaluate(&run.truth, &run.rows(&merged, &defaults)),
            f64::NAN,
        )
    });
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
    let rows: Vec<Row> = rows.into_iter().chain(bundle_row).collect();
    println!();
    print_header();
    rows.iter().for_each(print_row);
    print_kinds(rows.iter());
    Ok(ExitCode::SUCCESS)
}

/// The camera centres' and rotations' RMS error against the truth (`lineflow eval`'s), printed.
fn print_pose_errors(label: &str, run: &FinalLines, poses: &[Pose]) {
    let r = lineflow_eval::orientation::evaluate(&run.truth, &run.pose_rows(poses), None);
    let n = r.images.len().max(1) as f64;
    let mean = |k: usize| r.images.iter().map(|e| e.center_m[k]).sum::<f64>() / n * 1e3;
    println!(
        "{label}: centres {:.1} mm RMS (mean offset {:.1} / {:.1} / {:.1} mm), rotations {:.3} mrad RMS",
        r.rms_center_m * 1e3,
        mean(0),
        mean(1),
        mean(2),
        r.rms_rotation_deg.to_radians() * 1e3
    );
}

/// Within 1° of the vertical.
fn is_plumb(start: &lineflow_photogrammetry::Vec3, end: &lineflow_photogrammetry::Vec3) -> bool {
    (end - start)
        .try_normalize(1e-12)
        .is_some_and(|d| d.z.abs() > 1f64.to_radians().cos())
}

/// The multi-view re-estimate with `fit` of the plumb lines of `lines` (`plumb`) or of the others, in place.
fn refine_subset(
    run: &FinalLines,
    lines: &mut [lineflow_linefit::Merged],
    views: &[lineflow_linegeom::SlaveSegments],
    fit: &FitParams,
    plumb: bool,
) -> (usize, f64) {
    let at: Vec<usize> = (0..lines.len())
        .filter(|&i| is_plumb(&lines[i].start, &lines[i].end) == plumb)
        .collect();
    let mut subset: Vec<_> = at.iter().map(|&i| lines[i].clone()).collect();
    let result = refine_multiview(&run.camera, &mut subset, views, fit);
    for (i, l) in at.into_iter().zip(subset) {
        lines[i] = l;
    }
    result
}

/// Each plumb line of `lines` re-estimated from the images on each side of it along the façade (their centres'
/// side of the vertical plane through the line square to the mean viewing direction), the estimate `rule` keeps
/// replacing it where both sides give one; returns how many moved.
fn one_sided(
    camera: &lineflow_photogrammetry::Camera,
    lines: &mut [lineflow_linefit::Merged],
    views: &[lineflow_linegeom::SlaveSegments],
    p: &lineflow_linegeom::MultiviewParams,
    rule: OneSide,
) -> usize {
    use lineflow_photogrammetry::Vec3;
    let axis: Vec3 = views.iter().map(|v| v.pose.axis()).sum::<Vec3>();
    let Some(across) = Vec3::z().cross(&axis).try_normalize(1e-12) else {
        return 0;
    };
    let toward = Vec3::new(axis.x, axis.y, 0.0).normalize();
    let mut moved = 0;
    for l in lines.iter_mut() {
        if !is_plumb(&l.start, &l.end) {
            continue;
        }
        let mid = (l.start + l.end) * 0.5;
        let side = |left: bool| -> Vec<lineflow_linegeom::SlaveSegments> {
            views
                .iter()
                .filter(|v| ((v.pose.center - mid).dot(&across) < 0.0) == left)
                .map(|v| lineflow_linegeom::SlaveSegments {
                    pose: v.pose,
                    segments: v.segments,
                })
                .collect()
        };
        let estimate = |left: bool| lineflow_linegeom::refine_line(camera, l.start, l.end, &side(left), p);
        let (Some(a), Some(b)) = (estimate(true), estimate(false)) else {
            continue;
        };
        // Depth along the viewing direction: larger is further from the cameras.
        let depth = |x: &lineflow_linegeom::MultiviewLine| ((x.start + x.end) * 0.5).dot(&toward);
        let keep = match rule {
            OneSide::Left => a,
            OneSide::Right => b,
            OneSide::Front => {
                if depth(&a) <= depth(&b) {
                    a
                } else {
                    b
                }
            }
            OneSide::Back => {
                if depth(&a) > depth(&b) {
                    a
                } else {
                    b
                }
            }
            OneSide::Fit => {
                if a.rms_px <= b.rms_px {
                    a
                } else {
                    b
                }
            }
        };
        (l.start, l.end) = (keep.start, keep.end);
        moved += 1;
    }
    moved
}
