//! `lineflow bench linemap`: the linemap algorithm run again, in this process, on a finished run's 2-D lines and
//! poses (`lines2d.csv`, `poses.csv`) of a synthetic building, and scored against its truth as `bench buildings`
//! scores a whole run. For trying parameters and designs of the 3-D line stage in seconds instead of a run; use
//! tuning buildings (`PRESET@N`, N < 1000) for that, and `bench buildings` for the held-out figures.
use std::collections::BTreeMap;
use std::process::ExitCode;
use std::sync::Arc;

use anyhow::{Context, Result};
use lineflow_eval::lines3d::evaluate;
use lineflow_eval::Truth;
use lineflow_formats::{read_lines2d, read_poses, Line3Row};
use lineflow_linefit::{bridges, join_lines, line_elements, snap, FitParams, Merged, MULTIVIEW_MIN_SEGMENT_PX};
use lineflow_linegeom::{FrameSegments, SlaveSegments};
use lineflow_linemap::{line_messages, map_lines_with_stats, Guide, MapParams, Photo, View};
use lineflow_messages::Segment2;
use lineflow_photogrammetry::Vec3;
use lineflow_synthetic::Synthetic;
use rayon::prelude::*;

use crate::buildings::{print_header, print_row, row};

/// A finished run of a synthetic building, for the benchmarks that rerun a stage's steps on its results.
#[derive(Debug, clap::Args)]
pub struct FinishedRun {
    /// The run's output folder.
    pub run: std::path::PathBuf,
    /// The building the run filmed (PRESET or PRESET@N).
    #[arg(long)]
    pub building: String,
    /// Image scale of the run.
    #[arg(long, default_value_t = 0.3)]
    pub scale: f64,
    /// Seed of the run's scene.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
}

impl FinishedRun {
    /// The scene the run filmed.
    pub fn scene(&self) -> Result<Synthetic> {
        Synthetic::new(&self.building, self.scale, self.seed).map_err(|e| anyhow::anyhow!("{e}"))
    }
}

/// What `lineflow bench linemap` is asked.
#[derive(Debug, clap::Args)]
pub struct LinemapBench {
    #[command(flatten)]
    pub of: FinishedRun,
    /// Use the true poses instead of the run's.
    #[arg(long)]
    pub truth_poses: bool,
    /// Also print, per class of true edge, where the edges are lost.
    #[arg(long)]
    pub funnel: bool,
    /// Parameter override KEY=VALUE of the linemap stage (repeatable).
    #[arg(long)]
    pub set: Vec<String>,
    /// Parameter override KEY=VALUE of the linefit stage, for the run's lines joined with linemap's (repeatable).
    #[arg(long)]
    pub join_set: Vec<String>,
}

/// `lineflow bench linemap RUN --building B [--scale S] [--seed N] [--truth-poses] [--set KEY=VALUE]...
/// [--join-set KEY=VALUE]...`
pub fn bench_linemap(args: &LinemapBench) -> Result<ExitCode> {
    let (run, building, truth_poses) = (args.of.run.as_path(), args.of.building.as_str(), args.truth_poses);
    let params: MapParams = lineflow_runtime::launch::params_from_overrides(&args.set)?;
    lineflow_runtime::StageParams::validate(&params)?;
    let fit: FitParams = lineflow_runtime::launch::params_from_overrides(&args.join_set)?;
    lineflow_runtime::StageParams::validate(&fit)?;
    let scene = args.of.scene()?;
    let camera = *scene.camera();
    let walls = scene.approximate_walls();
    let walls: Vec<Vec<Vec3>> = walls.iter().map(|(_, c)| c.iter().map(|&p| Vec3::from(p)).collect()).collect();
    let guide = Guide::from_walls(&walls, params.site_margin_m);
    // Frames by image name: the run's poses.csv may leave frames out (not oriented).
    let frames: BTreeMap<String, usize> = (0..scene.poses().len()).map(|f| (scene.image_name(f), f)).collect();
    // The images only for the appearance test, which is off with min_correlation = -1.
    let photos: Vec<Option<Arc<Photo>>> = if params.min_correlation > -1.0 {
        eprintln!("rendering {} frames for the appearance test...", scene.poses().len());
        (0..scene.poses().len())
            .into_par_iter()
            .map(|f| rendered_photo(&scene, f))
            .collect()
    } else {
        Vec::new()
    };
    let truth = Truth::from_scene(scene);
    let poses = if truth_poses {
        truth.poses.clone()
    } else {
        read_poses(&run.join("poses.csv")).with_context(|| format!("{}: the run's poses", run.display()))?
    };
    let segments = run_segments(run)?;
    let views: Vec<View> = poses
        .iter()
        .filter_map(|p| {
            let f = *frames.get(&p.image)?;
            let view = View::new(&camera, f as u64, p.pose, segments.get(&p.image)?, params.min_length_px);
            Some(match photos.get(f).cloned().flatten() {
                Some(photo) => view.with_photo(photo),
                None => view,
            })
        })
        .collect();
    let start = std::time::Instant::now();
    let (lines, stats) = map_lines_with_stats(&camera, &views, &guide, &params);
    let seconds = start.elapsed().as_secs_f64();
    let messages = line_messages(&lines, &params);
    let rows: Vec<Line3Row> = messages.iter().map(Line3Row::from).collect();
    lineflow_formats::write_lines3d(&run.join("lines3d_linemap.csv"), &rows)?;
    println!(
        "linemap on {} ({} views, {} segments, {} poses), {:.2} s:\n",
        building,
        views.len(),
        views.iter().map(View::len).sum::<usize>(),
        if truth_poses { "true" } else { "the run's" },
        seconds
    );
    println!("{stats:?}\n");
    print_header();
    print_row(&row(format!("{building} linemap"), &evaluate(&truth, &rows), seconds));
    if let Ok(theirs) = lineflow_formats::read_lines3d(&run.join("lines3d.csv")) {
        print_row(&row(
            format!("{building} the run's lines3d.csv"),
            &evaluate(&truth, &theirs),
            f64::NAN,
        ));
        // As linefit joins linemap's final set to its own (its `joined` input), the run's lines standing for its
        // own: meaningful on a run of a graph without linemap.
        let start = std::time::Instant::now();
        let mut own: Vec<Merged> = theirs.iter().map(Merged::from_row).collect();
        let pose_list: Vec<lineflow_photogrammetry::Pose> = poses.iter().map(|p| p.pose).collect();
        let sight = lineflow_linegeom::Sight {
            camera: &camera,
            poses: &pose_list,
        };
        let n = join_lines(&mut own, &messages, &fit, Some(sight));
        snap(&mut own, &fit);
        if fit.bridge_max_span_m > 0.0 {
            let frames = frame_segments(&camera, &poses, &segments);
            let slaves: Vec<SlaveSegments> = frames
                .iter()
                .map(|(pose, segments)| SlaveSegments { pose: *pose, segments })
                .collect();
            let found = bridges(&camera, &own, &slaves, &fit);
            own.extend(found);
            snap(&mut own, &fit);
        }
        let joined: Vec<Line3Row> = line_elements(&own, &fit, Some(&camera), &pose_list)
            .iter()
            .map(Line3Row::from)
            .collect();
        print_row(&row(
            format!("{building} the run's joined by {n} stretches of linemap's"),
            &evaluate(&truth, &joined),
            start.elapsed().as_secs_f64(),
        ));
        lineflow_formats::write_lines3d(&run.join("lines3d_joined.csv"), &joined)?;
    }
    if args.funnel {
        print_funnel(&camera, &views, &guide, &truth, &rows, &params);
    }
    Ok(ExitCode::SUCCESS)
}

/// Each oriented image's segments indexed as the multi-view re-estimate takes them, with its pose.
pub(crate) fn frame_segments(
    camera: &lineflow_photogrammetry::Camera,
    poses: &[lineflow_formats::PoseRow],
    segments: &BTreeMap<String, Vec<Segment2>>,
) -> Vec<(lineflow_photogrammetry::Pose, FrameSegments)> {
    poses
        .iter()
        .filter_map(|p| {
            Some((
                p.pose,
                FrameSegments::new(camera, segments.get(&p.image)?, MULTIVIEW_MIN_SEGMENT_PX),
            ))
        })
        .collect()
}

/// A run's 2-D segments (`lines2d.csv`) by image name.
pub(crate) fn run_segments(run: &std::path::Path) -> Result<BTreeMap<String, Vec<Segment2>>> {
    let mut segments: BTreeMap<String, Vec<Segment2>> = BTreeMap::new();
    for r in read_lines2d(&run.join("lines2d.csv")).with_context(|| format!("{}: the run's 2-D lines", run.display()))? {
        segments.entry(r.image.clone()).or_default().push(Segment2 {
            start_px: r.start_px,
            end_px: r.end_px,
            ..Default::default()
        });
    }
    Ok(segments)
}

/// Frame `f` of the scene as the convert stage's grey image.
pub(crate) fn rendered_photo(scene: &Synthetic, f: usize) -> Option<Arc<Photo>> {
    let (w, h) = (scene.camera().width as usize, scene.camera().height as usize);
    let rgb = scene.render(f);
    let mut gray = vec![0u8; w * h];
    lineflow_imaging::gray_into(lineflow_messages::Encoding::Rgb8, w, h, 3 * w, &rgb, &mut gray).ok()?;
    Photo::new(w, h, gray).map(Arc::new)
}

/// Where the true edges of at least 0.5 m are lost, per class: seen as a 2-D segment in two or more images, given
/// a hypothesis within 2 GSD and 2° by some pair (before any snapping), given one as its segments' best
/// hypothesis, and found among the lines; and how many of them the images resolve from their parallel neighbours
/// (`lineflow_eval::resolvable`: one image edge where the truth has two recovers at most one), and how many of
/// those are found; then how far the images' segments along those edges lie from them.
fn print_funnel(camera: &lineflow_photogrammetry::Camera, views: &[View], guide: &Guide, truth: &Truth, lines: &[Line3Row], p: &MapParams) {
    use lineflow_eval::geometry::{class_on_walls, Class, Seg, WallPlane};
    use lineflow_linemap::hypotheses::pair_hypotheses;
    use lineflow_linemap::support::best_match;
    let tol = 2.0 * truth.gsd_m();
    let near = |g: &Seg, a: &Vec3, b: &Vec3| {
        let e = Seg::new(*a, *b);
        g.line_distance(a) <= tol && g.line_distance(b) <= tol && g.angle_deg(&e) <= 2.0 && {
            let (t0, t1) = (g.param(a), g.param(b));
            t0.max(t1) > 0.0 && t0.min(t1) < g.length()
        }
    };
    let walls: Vec<WallPlane> = truth
        .scene
        .approximate_walls()
        .into_iter()
        .filter_map(|(_, c)| WallPlane::new(c.into_iter().map(Vec3::from).collect()))
        .collect();
    let truth_segs: Vec<Seg> = truth.lines.iter().map(|r| Seg::new(r.start, r.end)).collect();
    let poses: Vec<lineflow_photogrammetry::Pose> = truth.poses.iter().map(|p| p.pose).collect();
    let resolved = lineflow_eval::resolvable::resolvable(camera, &poses, &truth_segs);
    let partners: Vec<Vec<usize>> = (0..views.len())
        .map(|i| lineflow_linemap::views::partners(views, i, p.max_partners))
        .collect();
    let names = ["horizontal", "vertical", "oblique", "depth"];
    let mut counts = [[0usize; 7]; 4];
    let mut offsets: [Vec<f64>; 4] = Default::default();
    for (r, &resolved) in truth.lines.iter().zip(&resolved).filter(|(r, _)| (r.end - r.start).norm() >= 0.5) {
        let g = Seg::new(r.start, r.end);
        let found = lines.iter().any(|l| near(&g, &l.start, &l.end));
        let c = match class_on_walls(&g, &walls) {
            Class::Horizontal => 0,
            Class::Vertical => 1,
            Class::Oblique => 2,
            Class::Depth => 3,
        };
        counts[c][0] += 1;
        counts[c][5] += resolved as usize;
        counts[c][6] += (resolved && found) as usize;
        let matches: Vec<_> = views
            .iter()
            .enumerate()
            .filter_map(|(k, v)| best_match(camera, (k, v), &[r.start, r.end], p))
            .collect();
        offsets[c].extend(matches.iter().map(|m| m.distance_px));
        let seen: Vec<(usize, usize)> = matches.iter().map(|m| (m.view, m.segment)).collect();
        if seen.len() < 2 {
            continue;
        }
        counts[c][1] += 1;
        let proposed = seen.iter().any(|&(i, s)| {
            (0..views.len()).filter(|&j| j != i).any(|j| {
                pair_hypotheses(camera, (i, &views[i]), s, (j, &views[j]), guide, p)
                    .iter()
                    .any(|h| near(&g, &h.ends[0], &h.ends[1]))
            })
        });
        counts[c][2] += proposed as usize;
        let bests: Vec<_> = seen
            .iter()
            .filter_map(|&(i, s)| lineflow_linemap::best_hypothesis(camera, views, (i, s), &partners[i], guide, p))
            .filter(|b| near(&g, &b.hypothesis.ends[0], &b.hypothesis.ends[1]))
            .collect();
        counts[c][3] += !bests.is_empty() as usize;
        counts[c][4] += found as usize;
    }
    println!(
        "\n| class | true edges ≥ 0.5 m | 2-D in ≥ 2 images | a pair proposes it | best of its segments | found | resolvable | found of those |"
    );
    println!("|---|---|---|---|---|---|---|---|");
    for (name, c) in names.iter().zip(counts) {
        println!(
            "| {name} | {} | {} | {} | {} | {} | {} | {} |",
            c[0], c[1], c[2], c[3], c[4], c[5], c[6]
        );
    }
    println!(
        "\nHow far the 2-D segments lie from the true edges (each image's best segment along an edge, the larger \
         distance of its two ends from the edge's projection with the poses used):\n"
    );
    println!("| class | segments | median (px) | 90th percentile (px) |\n|---|---|---|---|");
    for (name, mut d) in names.iter().zip(offsets) {
        d.sort_by(f64::total_cmp);
        let at = |q: f64| d.get(((d.len() as f64 - 1.0) * q).round() as usize).copied().unwrap_or(f64::NAN);
        println!("| {name} | {} | {:.3} | {:.3} |", d.len(), at(0.5), at(0.9));
    }
}
