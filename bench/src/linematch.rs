//! `lineflow bench linematch`: one full-size master with all its 2-D lines (Canny + line tracing, the shipped
//! graph's path and defaults) matched against its six slaves with every window mode, on one thread and on every
//! core; the reference, measured in the same run, is the thesis's fully automatic mode (the C window alone).
use std::process::ExitCode;

use anyhow::{bail, Context, Result};
use lineflow_linematch::{
    choose_slaves, match_master_with_lines, DistortionLut, FrameSegments, MasterMatch, MatchParams, Mode, SegmentInput, SlaveSegments,
    View, WallPlane,
};
use lineflow_lines2d::{trace_measured_at, MeasuredSegment, TraceParams};
use lineflow_messages::{Encoding, Segment2};
use lineflow_photogrammetry::Vec3;
use lineflow_synthetic::Synthetic;

use crate::util::median_time;

/// A frame number with its grey image.
type Gray = (u64, Vec<u8>);

/// The target: one 12 MP master against six slaves in at most this many seconds on two cores.
const TARGET_S: f64 = 2.0;

pub fn bench_linematch(preset: &str, scale: f64, reps: usize, points_csv: Option<&std::path::Path>) -> Result<ExitCode> {
    let syn = Synthetic::new(preset, scale, 1)?;
    let cam = *syn.camera();
    let (w, h) = (cam.width as usize, cam.height as usize);
    let walls: Vec<WallPlane> = syn
        .approximate_walls()
        .iter()
        .filter_map(|(name, c)| WallPlane::from_corners(name, &c.iter().map(|&p| Vec3::from(p)).collect::<Vec<_>>()))
        .collect();
    let poses = syn.poses();
    let master = poses.len() / 2;
    let candidates: Vec<(u64, _)> = poses.iter().enumerate().map(|(k, p)| (k as u64, *p)).collect();
    let p = MatchParams::default();
    let slaves = choose_slaves(
        &cam,
        (master as u64, &poses[master]),
        &candidates,
        &walls,
        p.max_slaves,
        p.min_overlap,
    );
    if slaves.is_empty() {
        bail!("frame {master} of {preset} has no slaves");
    }
    // The further frames whose lines alone place the points SNCC gives no depth.
    let mut more = choose_slaves(
        &cam,
        (master as u64, &poses[master]),
        &candidates,
        &walls,
        p.line_views,
        p.min_overlap,
    );
    more.retain(|f| !slaves.contains(f));
    println!(
        "linematch benchmark: {preset} at scale {scale} ({w}x{h}, {:.1} MP), master {master}, slaves {slaves:?}; rendering…",
        (w * h) as f64 / 1e6
    );
    let lut = DistortionLut::new(&cam);
    // Every image rendered once: its grey values for the matching and its lines as the shipped graph has them (the
    // edges stage's default, the colour channels' gradient across plumb edges): the master's to match, the others'
    // to refine depths.
    let rendered: Vec<(Gray, Vec<MeasuredSegment>)> = std::iter::once(master as u64)
        .chain(slaves.iter().copied())
        .chain(more.iter().copied())
        .map(|f| {
            let rgb = syn.render(f as usize);
            let mut g = vec![0u8; w * h];
            lineflow_imaging::gray_into(Encoding::Rgb8, w, h, w * 3, &rgb, &mut g)?;
            let [r, gc, b] = lineflow_imaging::rgb_planes(&rgb, w, h, w * 3);
            let planes = lineflow_imaging::Planes::colour(&g, &r, &gc, &b, lineflow_imaging::ColourEdges::default());
            let edges = lineflow_edges::canny_in(&planes, w, h, 0.4 * 100.0, 100.0);
            let found = lineflow_edges::pixels_in(&planes, w, h, &edges);
            let pixels: Vec<[u16; 2]> = found.iter().map(|e| [e.col, e.row]).collect();
            let positions = lineflow_imaging::subpixel_positions_in(&planes, w, h, &found);
            let lines = trace_measured_at(&cam, &pixels, &positions, &TraceParams::default());
            Ok(((f, g), lines))
        })
        .collect::<Result<_, lineflow_imaging::GrayError>>()?;
    let (grays, traced): (Vec<Gray>, Vec<Vec<MeasuredSegment>>) = rendered.into_iter().unzip();
    let frame_segments: Vec<Option<FrameSegments>> = traced
        .iter()
        .enumerate()
        .map(|(k, lines)| {
            let segs: Vec<Segment2> = lines
                .iter()
                .enumerate()
                .map(|(id, (a, b, _))| Segment2 {
                    id: id as u32,
                    start_px: *a,
                    end_px: *b,
                    ..Default::default()
                })
                .collect();
            (k > 0 && p.line_depth).then(|| FrameSegments::new(&cam, &segs, p.line_min_length_px))
        })
        .collect();
    let views: Vec<View> = grays
        .iter()
        .take(1 + slaves.len())
        .zip(&frame_segments)
        .map(|((f, g), segments)| View {
            frame: *f,
            pose: poses[*f as usize],
            camera: cam,
            lut: &lut,
            gray: g,
            segments: segments.as_ref(),
        })
        .collect();
    let segments: Vec<SegmentInput> = traced[0]
        .iter()
        .enumerate()
        .map(|(k, (a, b, chain))| SegmentInput {
            id: k as u32,
            start_px: *a,
            end_px: *b,
            chain,
        })
        .collect();
    let long = segments
        .iter()
        .filter(|s| (s.end_px[0] - s.start_px[0]).hypot(s.end_px[1] - s.start_px[1]) >= p.min_length_px)
        .count();
    let line_frames: Vec<SlaveSegments> = grays
        .iter()
        .zip(&frame_segments)
        .skip(1)
        .filter_map(|((f, _), segments)| {
            segments.as_ref().map(|segments| SlaveSegments {
                pose: poses[*f as usize],
                segments,
            })
        })
        .collect();
    let match_with = |q: &MatchParams| match_master_with_lines(&views[0], &views[1..], &line_frames, &walls, &segments, q);
    let MasterMatch {
        matches: matched,
        unmatched,
    } = match_with(&p);
    let points: usize = matched.iter().map(|m| m.points.len()).sum();
    let line_depths: usize = matched.iter().map(|m| m.n_line_depths).sum();
    println!(
        "{} segments ({long} of at least {} px), {} matched, {points} points ({line_depths} placed by the other frames' lines: {} frames); {unmatched}",
        segments.len(),
        p.min_length_px,
        matched.len(),
        line_frames.len()
    );
    if let Some(path) = points_csv {
        write_points(path, &matched)?;
        println!(
            "master {master} (centre {:?}): points written to {}",
            poses[master].center.as_slice(),
            path.display()
        );
        return Ok(ExitCode::SUCCESS);
    }
    let c_only = MatchParams {
        modes: vec![Mode::C],
        ..p.clone()
    };
    let one = rayon::ThreadPoolBuilder::new().num_threads(1).build()?;
    let run = |q: &MatchParams| drop(match_with(q));
    let all_1 = median_time(reps, || one.install(|| run(&p)));
    let all_n = median_time(reps, || run(&p));
    let c_n = median_time(reps, || run(&c_only));
    let sncc_only = MatchParams {
        line_depth: false,
        ..p.clone()
    };
    let s_n = median_time(reps, || run(&sncc_only));
    let no_lines_alone = MatchParams {
        line_only_min_slaves: 0,
        ..p.clone()
    };
    let l_n = median_time(reps, || run(&no_lines_alone));
    // The thesis's choice (best SNCC over its eight windows) computes no strips.
    let thesis_choice = MatchParams {
        front_margin: -1.0,
        ..p.clone()
    };
    let t_n = median_time(reps, || run(&thesis_choice));
    let threads = rayon::current_num_threads();
    let modes = p.modes.len();
    println!(
        "all {modes} window modes, 1 thread     {all_1:8.2} s  ({:.2} ms per matched segment)",
        all_1 * 1e3 / matched.len().max(1) as f64
    );
    println!(
        "all {modes} window modes, {threads} threads    {all_n:8.2} s  speed-up {:.2}x  target <= {TARGET_S:.0} s: {}",
        all_1 / all_n,
        if all_n <= TARGET_S { "met" } else { "NOT met" }
    );
    println!(
        "reference: C window only, {threads} threads {c_n:6.2} s  all modes / C only: {:.2}x",
        all_n / c_n
    );
    println!(
        "without the slaves' lines, {threads} threads {s_n:5.2} s  depths from the slaves' lines cost {:.2} s",
        all_n - s_n
    );
    println!(
        "without depths from the lines alone, {threads} threads {l_n:5.2} s  they cost {:.2} s",
        all_n - l_n
    );
    println!(
        "thesis's choice (best SNCC, no strips), {threads} threads {t_n:5.2} s  the strips and the front-most choice cost {:.2} s",
        all_n - t_n
    );
    Ok(ExitCode::SUCCESS)
}

/// Every matched point of the master, one CSV row each.
fn write_points(path: &std::path::Path, matched: &[lineflow_linematch::SegmentMatch]) -> Result<()> {
    use std::fmt::Write as _;
    let mut out = String::from("segment,X,Y,Z,depth_m,sncc,window,from_lines\n");
    for m in matched {
        for q in &m.points {
            let _ = writeln!(
                out,
                "{},{:.4},{:.4},{:.4},{:.4},{:.3},{:?},{}",
                m.segment_id, q.xyz.x, q.xyz.y, q.xyz.z, q.depth_m, q.sncc, q.mode, q.from_lines
            );
        }
    }
    std::fs::write(path, out).with_context(|| format!("cannot write {}", path.display()))
}
