//! The depth search of one master line (seed 000 §2.9–2.15): every sampled chain pixel's master ray is cut by
//! planes parallel to its wall at depths −range…+range; at each depth an object-space lattice along the line is
//! resampled from the master and every slave, and the single-point (C, L, R, U, B) and linear (C, L, R) windows
//! are correlated through summed-area tables. Coarse depths on a third-resolution lattice first, then the full
//! lattice at every fine depth near the coarse peaks.
use lineflow_photogrammetry::{Camera, Pose, Vec3};

use crate::ncc::{build_cross, master_window, ncc, BandScratch, BandSums, Bands, PatchSums, MIN_VARIANCE};
use crate::slave_lines::{depths_from_lines, refine_depths, LineSearch};
use crate::view::View;
use crate::wall::{wall_of_ray, WallPlane};
use crate::{MatchParams, MatchedPoint, Mode};
use lineflow_linegeom::SlaveSegments;

/// A 2-D segment of the master frame with its pixel chain (measured pixel coordinates).
#[derive(Debug, Clone, Copy)]
pub struct SegmentInput<'a> {
    /// Segment id in the master frame.
    pub id: u32,
    /// First endpoint (col, row).
    pub start_px: [f64; 2],
    /// Second endpoint.
    pub end_px: [f64; 2],
    /// The ordered chain.
    pub chain: &'a [[u16; 2]],
}

/// The matched points of one segment.
#[derive(Debug, Clone, PartialEq)]
pub struct SegmentMatch {
    /// Segment id in the master frame.
    pub segment_id: u32,
    /// Index of the wall in the list searched.
    pub wall: usize,
    /// Images that took part: the master and the slaves that see the wall.
    pub n_views: u32,
    /// Matched points in chain order (rejected pixels left out).
    pub points: Vec<MatchedPoint>,
    /// Points whose depth the slaves' 2-D lines fixed.
    pub n_line_depths: usize,
}

/// Geometry of one segment shared by every depth.
struct Line<'w> {
    wall: &'w WallPlane,
    center: Vec3,
    /// Ray of the segment's start (the lattice origin) and of each sampled pixel.
    start_ray: Vec3,
    end_ray: Vec3,
    rays: Vec<Vec3>,
    along: Vec3,
    across: Vec3,
}

impl Line<'_> {
    fn at(&self, ray: &Vec3, depth: f64) -> Vec3 {
        let s = self.wall.ray_parameter(&self.center, ray, depth).unwrap_or(f64::NAN);
        self.center + s * ray
    }
}

/// SNCC of every sampled point for each single-point mode, and of the line for each linear mode, at one depth.
#[derive(Debug, Clone)]
struct DepthScores {
    /// `point[k · modes + m]`: point k, single-point mode m (index into the enabled single modes); NaN when invalid.
    point: Vec<f64>,
    /// Enabled single-point modes.
    modes: usize,
    /// One per enabled linear mode; NaN when invalid.
    linear: Vec<f64>,
}

/// Reused buffers of one search.
#[derive(Default)]
struct Scratch {
    patches: Vec<Vec<f32>>,
    sums: Vec<PatchSums>,
    cross: Vec<BandSums>,
    bands: Bands,
    windows: Vec<Window>,
    per_patch: BandScratch<3>,
    per_cross: BandScratch<1>,
}

/// A window on the lattice: its row band and inclusive columns (lattice indices), `None` when it leaves the lattice.
type Window = Option<(usize, (usize, usize))>;

/// Why a segment gave no 3-D points: reported per master, so that a wrong site model (lines outside every wall) or
/// a wall with nothing to correlate (glass) shows in the log instead of as silently missing lines.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Unmatched {
    /// Shorter than `min_length_px` in the image or `min_length_m` on its wall, or without a chain.
    TooShort,
    /// Its midpoint ray meets no wall whose front the master sees (within `wall_margin_m` of the polygon).
    OutsideWalls,
    /// Fewer than `min_slaves` slaves see its wall.
    NoSlave,
    /// Searched, but no point passed the robust tests: no texture to correlate (glass, a uniform wall), ambiguous
    /// or below `min_sncc`.
    NoDepth,
}

/// Matches one master segment against the slaves.
pub fn match_segment(
    master: &View,
    slaves: &[View],
    line_frames: &[SlaveSegments],
    walls: &[WallPlane],
    seg: &SegmentInput,
    p: &MatchParams,
) -> Result<SegmentMatch, Unmatched> {
    let len_px = (seg.end_px[0] - seg.start_px[0]).hypot(seg.end_px[1] - seg.start_px[1]);
    if len_px < p.min_length_px || seg.chain.is_empty() {
        return Err(Unmatched::TooShort);
    }
    let cam = &master.camera;
    let center = master.pose.center;
    let ray = |px: [f64; 2]| master.pose.ray_of_pixel(cam, px);
    let (start_ray, end_ray) = (ray(seg.start_px), ray(seg.end_px));
    let mid_ray = (start_ray + end_ray).normalize();
    let wall_index = wall_of_ray(walls, &center, &mid_ray, p.wall_margin_m).ok_or(Unmatched::OutsideWalls)?;
    let wall = &walls[wall_index];
    // The interpretation plane cuts every wall-parallel plane along the same direction; where it is parallel to the
    // wall (the wall seen edge-on) the line has no extent on it.
    let mut along = start_ray
        .cross(&end_ray)
        .cross(&wall.normal)
        .try_normalize(1e-9)
        .ok_or(Unmatched::TooShort)?;
    let probe = Line {
        wall,
        center,
        start_ray,
        end_ray,
        rays: Vec::new(),
        along,
        across: Vec3::zeros(),
    };
    let (a0, b0) = (probe.at(&start_ray, 0.0), probe.at(&end_ray, 0.0));
    if !(a0.iter().all(|v| v.is_finite()) && b0.iter().all(|v| v.is_finite())) {
        return Err(Unmatched::OutsideWalls);
    }
    if (b0 - a0).dot(&along) < 0.0 {
        along = -along;
    }
    if (b0 - a0).norm() < p.min_length_m {
        return Err(Unmatched::TooShort);
    }
    let mid0 = (a0 + b0) / 2.0;
    let seen: Vec<&View> = slaves.iter().filter(|s| sees(&s.pose, &s.camera, wall, &mid0)).collect();
    if seen.len() < p.min_slaves {
        return Err(Unmatched::NoSlave);
    }
    let step = (seg.chain.len() as f64 * p.spacing_px / len_px.max(1.0)).max(1.0);
    let pixels: Vec<[f64; 2]> = (0..)
        .map(|k| (k as f64 * step) as usize)
        .take_while(|&i| i < seg.chain.len())
        .map(|i| [seg.chain[i][0] as f64, seg.chain[i][1] as f64])
        .collect();
    // Chain pixels scatter by half a pixel about the line; their feet on the fitted line put every ray in the
    // line's interpretation plane.
    let (ia, ib) = (cam.pixel_to_ideal(seg.start_px), cam.pixel_to_ideal(seg.end_px));
    let (dx, dy) = (ib[0] - ia[0], ib[1] - ia[1]);
    let len2 = (dx * dx + dy * dy).max(1e-18);
    let ideals: Vec<[f64; 2]> = pixels
        .iter()
        .map(|&px| {
            let q = cam.pixel_to_ideal(px);
            let t = ((q[0] - ia[0]) * dx + (q[1] - ia[1]) * dy) / len2;
            [ia[0] + t * dx, ia[1] + t * dy]
        })
        .collect();
    let line = Line {
        rays: ideals.iter().map(|&q| master.pose.ray_of_ideal(cam, q)).collect(),
        across: wall.normal.cross(&along),
        ..probe
    };
    // Cells and depth steps grow with the ground sample distance so that a window always spans ~20 pixels.
    let gsd = cam.gsd_m((mid0 - center).norm());
    let scale = (p.min_cell_gsd * gsd / p.cell_m).max(1.0);
    let (cell, depth_step) = (p.cell_m * scale, p.depth_step_m * scale);
    let (sncc, without_depth) = sncc_points(master, &seen, &line, (&pixels, &ideals), (gsd, cell, depth_step), &mid0, p);
    let (chain_index, mut points): (Vec<usize>, Vec<MatchedPoint>) = sncc.into_iter().unzip();
    // SNCC's depths are refined by the slaves' lines only: with more frames, more parallel lines (the courses of a
    // brick wall) offer a popular wrong depth within reach of a right one.
    let slave_segments: Vec<SlaveSegments> = seen
        .iter()
        .filter_map(|v| v.segments.map(|segments| SlaveSegments { pose: v.pose, segments }))
        .collect();
    let rays: Vec<Vec3> = chain_index.iter().map(|&k| line.rays[k]).collect();
    let mut n_line_depths = refine_depths(cam, &center, wall, &mut points, &rays, &slave_segments, p);
    let line_segments: Vec<SlaveSegments> = line_frames.iter().filter(|s| sees(&s.pose, cam, wall, &mid0)).cloned().collect();
    let from_lines_alone = depths_from_lines_alone(&line, (&pixels, &ideals), &without_depth, &line_segments, master, p);
    let points = if from_lines_alone.is_empty() {
        points
    } else {
        n_line_depths += from_lines_alone.len();
        // Back in chain order: the parallel snap fits depth against position along the line.
        let mut ordered: Vec<(usize, MatchedPoint)> = chain_index.into_iter().zip(points).chain(from_lines_alone).collect();
        ordered.sort_by_key(|(k, _)| *k);
        ordered.into_iter().map(|(_, q)| q).collect()
    };
    let points = snap_parallel(points, &line, depth_step, p.parallel_snap_m, p.line_max_shift_m);
    if points.is_empty() {
        return Err(Unmatched::NoDepth);
    }
    Ok(SegmentMatch {
        segment_id: seg.id,
        wall: wall_index,
        n_views: 1 + seen.len() as u32,
        points,
        n_line_depths,
    })
}

/// Whether a camera sees the wall point `x` from the wall's front, inside its image.
fn sees(pose: &Pose, camera: &Camera, wall: &WallPlane, x: &Vec3) -> bool {
    wall.normal.dot(&(x - pose.center)) < 0.0 && pose.project(camera, x).is_some_and(|px| camera.contains(px, 0.0))
}

/// SNCC over the depth range (§2.10–2.13, with the windows and choices above): the points with an accepted depth
/// and their chain indices, and the chain indices without one.
fn sncc_points(
    master: &View,
    seen: &[&View],
    line: &Line,
    (pixels, ideals): (&[[f64; 2]], &[[f64; 2]]),
    (gsd, cell, depth_step): (f64, f64, f64),
    mid0: &Vec3,
    p: &MatchParams,
) -> (Vec<(usize, MatchedPoint)>, Vec<usize>) {
    let center = master.pose.center;
    let n_depths = (p.depth_range_m / depth_step).floor() as i32;
    let depth = |i: i32| i as f64 * depth_step;
    // Another surface in front has to lie a resolvable depth away: `front_min_px` pixels of parallax at the longest
    // baseline, at least `front_min_m` (3 cm on the D2X strip). Where that step is coarser than `front_max_step_m`
    // (7–12 cm on the A55's short baselines) the correlation curves are too broad to tell a step in depth from the
    // same surface, and the thesis's choice applies.
    let baseline = seen.iter().map(|s| (s.pose.center - center).norm()).fold(0.0, f64::max);
    let front_min = (p.front_min_px * gsd * (mid0 - center).norm() / baseline.max(1e-9)).max(p.front_min_m);
    let front_margin = if front_min <= p.front_max_step_m { p.front_margin } else { -1.0 };
    let singles: Vec<Mode> = p.modes.iter().copied().filter(|m| !m.is_linear()).collect();
    // The strips serve only the front-most choice; the thesis's best-over-all-modes has no use for them.
    let linears: Vec<Mode> = p
        .modes
        .iter()
        .copied()
        .filter(|m| m.is_linear() && !(m.is_strip() && front_margin < 0.0))
        .collect();
    let mut scratch = Scratch::default();
    let views: Vec<&View> = std::iter::once(master).chain(seen.iter().copied()).collect();
    let cf = p.coarse_factor.max(1) as i32;
    let h = p.half_window as i32;
    let score = |i: i32, coarse: bool, scratch: &mut Scratch| {
        let (c, hw) = if coarse { (3.0 * cell, (h / 3).max(1)) } else { (cell, h) };
        score_depth(&views, line, depth(i), c, hw, &singles, &linears, p.min_slaves, scratch)
    };

    // Coarse pass: every cf-th depth on a half-resolution lattice.
    let coarse_idx: Vec<i32> = (-n_depths..=n_depths).filter(|i| i.rem_euclid(cf) == 0).collect();
    let coarse: Vec<DepthScores> = coarse_idx.iter().map(|&i| score(i, true, &mut scratch)).collect();
    let n_pts = pixels.len();
    let mut votes: Vec<(i32, usize)> = Vec::new();
    let mut vote = |i: i32, weight: usize| match votes.iter_mut().find(|(d, _)| *d == i) {
        Some(v) => v.1 += weight,
        None => votes.push((i, weight)),
    };
    // The strips do not vote: they only ever pull points forward (`choose_peak`), and would crowd out the windows'
    // depths as candidates. Their own coarse peaks are searched below when they lie in front.
    let mut strip_peaks: Vec<i32> = Vec::new();
    for (m, mode) in linears.iter().enumerate() {
        if let Some((j, _)) = argmax(curve_linear(&coarse, m)) {
            if mode.is_strip() {
                strip_peaks.push(coarse_idx[j]);
            } else {
                vote(coarse_idx[j], n_pts.max(1));
            }
        }
    }
    for k in 0..n_pts {
        let best = (0..singles.len())
            .filter_map(|m| argmax(curve_point(&coarse, k, m)))
            .max_by(|a, b| a.1.total_cmp(&b.1));
        if let Some((j, _)) = best {
            vote(coarse_idx[j], 1);
        }
    }
    votes.sort_by(|a, b| b.1.cmp(&a.1).then(a.0.abs().cmp(&b.0.abs())).then(a.0.cmp(&b.0)));
    // Further candidates only when a real share of the points backs them: most lines have one depth.
    let top = votes.first().map_or(0, |v| v.1);
    let mut candidates: Vec<i32> = votes
        .iter()
        .take(p.max_candidates.max(1))
        .filter(|v| 4 * v.1 >= top)
        .map(|v| v.0)
        .collect();
    if let Some(&lead) = candidates.first() {
        let reach = (p.front_reach_m / depth_step).ceil() as i32 + cf;
        candidates.extend(strip_peaks.iter().filter(|&&c| c > lead && c <= lead + reach));
    }
    let mut fine_idx: Vec<i32> = candidates
        .iter()
        .flat_map(|&c| (c - 1..=c + 1).filter(|i| i.abs() <= n_depths))
        .collect();
    fine_idx.sort_unstable();
    fine_idx.dedup();
    let mut fine: Vec<DepthScores> = fine_idx.iter().map(|&i| score(i, false, &mut scratch)).collect();
    // The true peak lies within half a coarse step of the coarse one; rather than evaluating that whole span, a
    // curve whose best depth lies at the edge of the three evaluated gets the next depth (its parabola needs it,
    // and the peak may lie there), which most lines never need. On the D2X benchmark master this gives the same
    // lines and 99.8 % of the points of the whole span, 12 % faster.
    let mut edges: Vec<i32> = (0..n_pts)
        .flat_map(|k| (0..singles.len()).map(move |m| (k, m)))
        .filter_map(|(k, m)| argmax(curve_point(&fine, k, m)))
        .chain((0..linears.len()).filter_map(|m| argmax(curve_linear(&fine, m))))
        .flat_map(|(j, _)| [fine_idx[j] - 1, fine_idx[j] + 1])
        .filter(|i| i.abs() <= n_depths && fine_idx.binary_search(i).is_err())
        .collect();
    edges.sort_unstable();
    edges.dedup();
    for i in edges {
        let at = fine_idx.binary_search(&i).unwrap_or_else(|e| e);
        fine.insert(at, score(i, false, &mut scratch));
        fine_idx.insert(at, i);
    }

    // Each point chooses among its own single-point curves and the line's linear curves (`choose_peak`).
    let linear_best: Vec<Option<Peak>> = (0..linears.len())
        .map(|m| {
            peak(
                &fine_idx,
                &fine.iter().map(|s| s.linear[m]).collect::<Vec<_>>(),
                &coarse_idx,
                &curve_linear(&coarse, m).collect::<Vec<_>>(),
                cf,
                n_depths,
                p,
            )
        })
        .collect();
    let mut points = Vec::new();
    let mut without_depth: Vec<usize> = Vec::new();
    for k in 0..n_pts {
        let mut peaks: Vec<(Peak, Mode)> = Vec::new();
        for (m, &mode) in singles.iter().enumerate() {
            let f: Vec<f64> = curve_point(&fine, k, m).collect();
            let c: Vec<f64> = curve_point(&coarse, k, m).collect();
            peaks.extend(peak(&fine_idx, &f, &coarse_idx, &c, cf, n_depths, p).map(|pk| (pk, mode)));
        }
        peaks.extend(linears.iter().zip(&linear_best).filter_map(|(&mode, pk)| pk.map(|pk| (pk, mode))));
        let best = choose_peak(&peaks, front_margin, (front_min / depth_step, p.front_reach_m / depth_step));
        let Some((pk, mode)) = best.filter(|(pk, _)| pk.accepted) else {
            without_depth.push(k);
            continue;
        };
        let d = pk.index * depth_step;
        let xyz = line.at(&line.rays[k], d);
        points.push((
            k,
            MatchedPoint {
                pixel: pixels[k],
                ideal: ideals[k],
                depth_m: d,
                xyz,
                sncc: pk.value,
                mode,
                from_lines: false,
            },
        ));
    }
    (points, without_depth)
}

/// The points SNCC gave no accepted depth (a plastered or painted wall, eaves and cornices have little texture to
/// correlate) placed where the 2-D lines of the other frames (`line_frames`) agree anywhere in the depth range, with
/// the wall as the prior. With no SNCC depth to confirm it, the agreement must be broad and unrivalled
/// ([`LineSearch`]): the courses of a brick wall seen from the other strip agree as well one course off.
fn depths_from_lines_alone(
    line: &Line,
    (pixels, ideals): (&[[f64; 2]], &[[f64; 2]]),
    which: &[usize],
    slaves: &[SlaveSegments],
    master: &View,
    p: &MatchParams,
) -> Vec<(usize, MatchedPoint)> {
    // Where SNCC placed most of the line, its depth is settled (step 8 snaps the rest to it): the lines' cuts
    // would add little (measured: no figure changed on the tuning buildings).
    if !p.line_depth || p.line_only_min_slaves == 0 || which.len() < 2 || 2 * which.len() < pixels.len() {
        return Vec::new();
    }
    let rays: Vec<Vec3> = which.iter().map(|&k| line.rays[k]).collect();
    let priors = vec![0.0; rays.len()];
    let search = LineSearch {
        priors: &priors,
        max_shift_m: p.depth_range_m,
        min_slaves: p.line_only_min_slaves,
        max_rival: p.line_only_max_rival,
        min_share: p.line_only_min_share,
    };
    let cam = &master.camera;
    depths_from_lines(cam, &line.center, line.wall, &rays, slaves, &search, p)
        .into_iter()
        .zip(which)
        .zip(&rays)
        .filter_map(|((d, &k), ray)| {
            let (depth_m, s) = d?;
            Some((
                k,
                MatchedPoint {
                    pixel: pixels[k],
                    ideal: ideals[k],
                    depth_m,
                    xyz: line.center + s * ray,
                    sncc: 0.0,
                    mode: Mode::LinearC,
                    from_lines: false,
                },
            ))
        })
        .collect()
}

/// A line whose depth changes by less than `tolerance` from end to end (robust straight-line fit of depth against
/// position) is parallel to its wall, as most façade edges are: its points move to their common depth, so that the
/// line's direction comes from the 2-D line (sub-pixel) instead of from noisy per-point depths. Where at least three
/// points have their depth from the slaves' lines, those alone decide the depth (SNCC follows the more textured
/// surface at a depth step) and SNCC-only points within `max_shift` of it follow; otherwise points more than three
/// depth steps off are dropped. Receding lines (reveals) keep their per-point depths.
fn snap_parallel(points: Vec<MatchedPoint>, line: &Line, depth_step: f64, tolerance: f64, max_shift: f64) -> Vec<MatchedPoint> {
    if tolerance <= 0.0 || points.len() < 3 {
        return points;
    }
    let median = |mut v: Vec<f64>| {
        v.sort_by(f64::total_cmp);
        v[v.len() / 2]
    };
    let from_lines = points.iter().filter(|q| q.from_lines).count() >= 3;
    let reference: Vec<&MatchedPoint> = points.iter().filter(|q| q.from_lines || !from_lines).collect();
    let mid = median(reference.iter().map(|q| q.depth_m).collect());
    let near: Vec<&MatchedPoint> = reference
        .into_iter()
        .filter(|q| (q.depth_m - mid).abs() <= 3.0 * depth_step)
        .collect();
    if near.len() < 3 {
        return points;
    }
    // Position along the line: distance of the point's foot from the first one, in metres.
    let t: Vec<f64> = near.iter().map(|q| (q.xyz - near[0].xyz).dot(&line.along)).collect();
    let d: Vec<f64> = near.iter().map(|q| q.depth_m).collect();
    let n = near.len() as f64;
    let (mt, md) = (t.iter().sum::<f64>() / n, d.iter().sum::<f64>() / n);
    let stt: f64 = t.iter().map(|x| (x - mt).powi(2)).sum();
    let std: f64 = t.iter().zip(&d).map(|(x, y)| (x - mt) * (y - md)).sum();
    let span = t.iter().fold(f64::NEG_INFINITY, |a, &b| a.max(b)) - t.iter().fold(f64::INFINITY, |a, &b| a.min(b));
    let slope = if stt > 0.0 { std / stt } else { 0.0 };
    if (slope * span).abs() > tolerance {
        return points;
    }
    let depth = median(d);
    let keep = |q: &MatchedPoint| {
        let off = (q.depth_m - depth).abs();
        if from_lines {
            (q.from_lines && off <= 3.0 * depth_step) || (!q.from_lines && off <= max_shift)
        } else {
            off <= 3.0 * depth_step
        }
    };
    points
        .iter()
        .filter(|q| keep(q))
        .map(|q| MatchedPoint {
            depth_m: depth,
            xyz: line.at(&(q.xyz - line.center).normalize(), depth),
            ..*q
        })
        .collect()
}

/// Single-point mode `m` of point `k` over depths.
fn curve_point(scores: &[DepthScores], k: usize, m: usize) -> impl Iterator<Item = f64> + '_ {
    scores.iter().map(move |s| s.point[k * s.modes + m])
}

/// Linear mode `m` over depths.
fn curve_linear(scores: &[DepthScores], m: usize) -> impl Iterator<Item = f64> + '_ {
    scores.iter().map(move |s| s.linear[m])
}

/// The window a point takes: with `front_margin` < 0 the best SNCC over all modes (the thesis); otherwise the
/// front-most accepted peak within `front_margin` of the best accepted one and between `front.0` and `front.1` depth
/// steps in front of it, or the best when there is none. An image edge at a depth step belongs to the nearer
/// surface, while the window with the highest correlation is often the one on the other side, where more texture
/// lies (the interior of a window opening behind a sill or an outline edge). The thin strips only ever pull a point
/// forward: on their own, along a brick course, their few rows correlate as well at a wrong depth as at the right
/// one.
fn choose_peak(peaks: &[(Peak, Mode)], front_margin: f64, front: (f64, f64)) -> Option<(Peak, Mode)> {
    let by_value = |a: &&(Peak, Mode), b: &&(Peak, Mode)| a.0.value.total_cmp(&b.0.value);
    let windows = peaks.iter().filter(|(_, m)| !m.is_strip());
    if front_margin < 0.0 {
        return windows.max_by(by_value).copied();
    }
    let best = *windows.filter(|(pk, _)| pk.accepted).max_by(by_value)?;
    let (lo, hi) = (best.0.index + front.0, best.0.index + front.1);
    let in_front = peaks
        .iter()
        .filter(|(pk, _)| pk.accepted && pk.value >= best.0.value - front_margin && pk.index >= lo && pk.index <= hi)
        .max_by(|a, b| a.0.index.total_cmp(&b.0.index).then(a.0.value.total_cmp(&b.0.value)));
    Some(*in_front.unwrap_or(&best))
}

/// The best depth of one curve.
#[derive(Debug, Clone, Copy)]
struct Peak {
    /// Depth index with parabolic sub-step refinement.
    index: f64,
    value: f64,
    /// Passes the robust tests (minimum SNCC, not at the range boundary, no rival peak on the coarse curve).
    accepted: bool,
}

/// The peak of a fine curve (values at `fine_idx`), refined by a parabola, and the robust tests on it, the rival
/// peak taken from the coarse curve (values at `coarse_idx`).
fn peak(fine_idx: &[i32], fine: &[f64], coarse_idx: &[i32], coarse: &[f64], cf: i32, n: i32, p: &MatchParams) -> Option<Peak> {
    let (j, value) = argmax(fine.iter().copied())?;
    let i = fine_idx[j];
    let neighbour = |di: i32| {
        fine_idx
            .iter()
            .position(|&x| x == i + di)
            .map(|q| fine[q])
            .filter(|v| v.is_finite())
    };
    let mut index = i as f64;
    if let (Some(a), Some(b)) = (neighbour(-1), neighbour(1)) {
        let denom = a - 2.0 * value + b;
        if denom < 0.0 {
            index += (0.5 * (a - b) / denom).clamp(-0.5, 0.5);
        }
    }
    // A rival: the best coarse value at least two coarse steps from this peak.
    let rival = coarse_idx
        .iter()
        .zip(coarse)
        .filter(|(&ci, v)| (ci - i).abs() >= 2 * cf && v.is_finite())
        .map(|(_, &v)| v)
        .fold(f64::NEG_INFINITY, f64::max);
    let best_coarse = coarse
        .iter()
        .zip(coarse_idx)
        .filter(|(v, &ci)| (ci - i).abs() < 2 * cf && v.is_finite())
        .map(|(&v, _)| v)
        .fold(f64::NEG_INFINITY, f64::max);
    let unique = rival <= p.max_ambiguity * best_coarse.max(value) || rival.is_nan();
    let accepted = value >= p.min_sncc && i.abs() < n && unique;
    Some(Peak { index, value, accepted })
}

/// Index and value of the largest finite element.
fn argmax(values: impl Iterator<Item = f64>) -> Option<(usize, f64)> {
    values
        .enumerate()
        .filter(|(_, v)| v.is_finite())
        .fold(None, |best: Option<(usize, f64)>, (k, v)| match best {
            Some((_, b)) if b >= v => best,
            _ => Some((k, v)),
        })
}

/// Scores every window at one depth.
#[allow(clippy::too_many_arguments)]
fn score_depth(
    views: &[&View],
    line: &Line,
    depth: f64,
    cell: f64,
    h: i32,
    singles: &[Mode],
    linears: &[Mode],
    min_slaves: usize,
    s: &mut Scratch,
) -> DepthScores {
    let origin = line.at(&line.start_ray, depth);
    let end = line.at(&line.end_ray, depth);
    let pos = |x: &Vec3| {
        let d = x - origin;
        [
            (d.dot(&line.along) / cell).round() as i32,
            (d.dot(&line.across) / cell).round() as i32,
        ]
    };
    let spots: Vec<[i32; 2]> = line.rays.iter().map(|r| pos(&line.at(r, depth))).collect();
    let end_col = pos(&end)[0];
    let invalid = || DepthScores {
        point: vec![f64::NAN; singles.len() * line.rays.len()],
        modes: singles.len(),
        linear: vec![f64::NAN; linears.len()],
    };
    if !origin.iter().all(|v| v.is_finite()) || spots.is_empty() {
        return invalid();
    }
    let c_lo = spots.iter().map(|q| q[0]).min().unwrap_or(0).min(0).min(end_col) - 2 * h;
    let c_hi = spots.iter().map(|q| q[0]).max().unwrap_or(0).max(end_col) + 2 * h;
    let r_lo = spots.iter().map(|q| q[1]).min().unwrap_or(0).min(0) - 2 * h;
    let r_hi = spots.iter().map(|q| q[1]).max().unwrap_or(0).max(0) + 2 * h;
    let (width, height) = ((c_hi - c_lo + 1) as usize, (r_hi - r_lo + 1) as usize);
    // A runaway lattice means the plane is nearly parallel to the rays at this depth: nothing to match.
    if width * height > 4_000_000 {
        return invalid();
    }
    // Every window of this depth, point by point and mode by mode, then the linear ones.
    s.bands.clear();
    s.windows.clear();
    let window = |cols: (i32, i32), rows: (i32, i32), bands: &mut Bands| -> Window {
        if cols.0 < c_lo || cols.1 > c_hi || rows.0 < r_lo || rows.1 > r_hi {
            return None;
        }
        let band = bands.index(((rows.0 - r_lo) as usize, (rows.1 - r_lo) as usize));
        Some((band, ((cols.0 - c_lo) as usize, (cols.1 - c_lo) as usize)))
    };
    for &[c, r] in &spots {
        for m in singles {
            let (cols, rows) = m.window(c, r, h);
            s.windows.push(window(cols, rows, &mut s.bands));
        }
    }
    let (first, last) = (0.min(end_col), 0.max(end_col));
    for m in linears {
        let (_, rows) = m.window(0, 0, h);
        s.windows.push(window(m.linear_cols(first, last, h), rows, &mut s.bands));
    }
    s.bands.seal();
    let (along, across) = (line.along * cell, line.across * cell);
    s.patches.resize_with(views.len(), Vec::new);
    s.sums.resize_with(views.len(), PatchSums::default);
    s.cross.resize_with(views.len(), BandSums::default);
    for (v, view) in views.iter().enumerate() {
        view.sample_lattice(&origin, &along, &across, (c_lo, c_hi), (r_lo, r_hi), &mut s.patches[v]);
        s.sums[v].build(width, height, &s.bands, &mut s.per_patch, &s.patches[v]);
    }
    for v in 1..views.len() {
        build_cross(
            width,
            height,
            &s.bands,
            &mut s.per_cross,
            &s.patches[0],
            &s.patches[v],
            &mut s.cross[v],
        );
    }
    let sncc = |w: Window, min_variance: f64| -> f64 {
        let Some((band, cols)) = w else { return f64::NAN };
        let Some(master) = master_window(&s.sums[0], band, cols, s.bands.rows(band), min_variance) else {
            return f64::NAN;
        };
        let (mut total, mut count) = (0.0, 0usize);
        for v in 1..views.len() {
            if let Some(r) = ncc(&master, &s.sums[v], &s.cross[v]) {
                total += r;
                count += 1;
            }
        }
        if count >= min_slaves.max(1) {
            total / count as f64
        } else {
            f64::NAN
        }
    };
    let n_single = singles.len();
    let point = s.windows[..spots.len() * n_single].iter().map(|&w| sncc(w, MIN_VARIANCE)).collect();
    let linear = s.windows[spots.len() * n_single..]
        .iter()
        .zip(linears)
        .map(|(&w, m)| sncc(w, m.min_variance()))
        .collect();
    DepthScores {
        point,
        modes: n_single,
        linear,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Points of the vertical edge x = 0.5 seen from (0, −12, 1.5) in front of the wall y = 0, at the given depths.
    fn points(depths: &[(f64, bool)]) -> (Vec<MatchedPoint>, WallPlane) {
        let wall = WallPlane::from_plane("w", Vec3::new(0.0, -1.0, 0.0), Vec3::zeros());
        let center = Vec3::new(0.0, -12.0, 1.5);
        let pts = depths
            .iter()
            .enumerate()
            .map(|(k, &(depth, from_lines))| {
                let ray = (Vec3::new(0.5, 0.0, 0.5 + 0.1 * k as f64) - center).normalize();
                let s = wall.ray_parameter(&center, &ray, depth).unwrap();
                MatchedPoint {
                    pixel: [0.0; 2],
                    ideal: [0.0; 2],
                    depth_m: depth,
                    xyz: center + s * ray,
                    sncc: 0.9,
                    mode: Mode::C,
                    from_lines,
                }
            })
            .collect();
        (pts, wall)
    }

    fn snap(depths: &[(f64, bool)]) -> Vec<MatchedPoint> {
        let (pts, wall) = points(depths);
        let line = Line {
            wall: &wall,
            center: Vec3::new(0.0, -12.0, 1.5),
            start_ray: Vec3::zeros(),
            end_ray: Vec3::zeros(),
            rays: Vec::new(),
            along: Vec3::z(),
            across: Vec3::x(),
        };
        snap_parallel(pts, &line, 0.01, 0.03, 0.15)
    }

    fn pk(index: f64, value: f64) -> Peak {
        Peak {
            index,
            value,
            accepted: true,
        }
    }

    #[test]
    fn the_thesis_takes_the_best_window_and_ignores_the_strips() {
        let peaks = [(pk(0.0, 0.95), Mode::C), (pk(6.0, 0.97), Mode::B), (pk(9.0, 0.99), Mode::StripL)];
        let (best, mode) = choose_peak(&peaks, -1.0, (3.0, 10.0)).unwrap();
        assert_eq!((best.index, mode), (6.0, Mode::B));
    }

    #[test]
    fn the_front_most_peak_within_margin_and_reach_wins() {
        // The wall around a 6 cm sill correlates best; the strip on the sill's face peaks 6 steps in front.
        let peaks = [(pk(0.0, 0.99), Mode::C), (pk(6.0, 0.96), Mode::StripL)];
        assert_eq!(choose_peak(&peaks, 0.05, (3.0, 10.0)).unwrap().1, Mode::StripL);
        // Out of reach, too near to be another surface, or too weak: the best window stays.
        assert_eq!(choose_peak(&peaks, 0.05, (3.0, 5.0)).unwrap().1, Mode::C);
        assert_eq!(choose_peak(&peaks, 0.05, (7.0, 10.0)).unwrap().1, Mode::C);
        assert_eq!(choose_peak(&peaks, 0.02, (3.0, 10.0)).unwrap().1, Mode::C);
        // A strip never pushes a point back, and never decides alone.
        let behind = [(pk(0.0, 0.99), Mode::C), (pk(-6.0, 0.99), Mode::StripL)];
        assert_eq!(choose_peak(&behind, 0.05, (3.0, 10.0)).unwrap().1, Mode::C);
        let alone = [
            (
                Peak {
                    accepted: false,
                    ..pk(0.0, 0.5)
                },
                Mode::C,
            ),
            (pk(6.0, 0.99), Mode::StripL),
        ];
        assert!(choose_peak(&alone, 0.05, (3.0, 10.0)).is_none());
    }

    #[test]
    fn a_parallel_line_takes_the_median_depth_and_drops_stray_points() {
        let out = snap(&[(0.10, false), (0.11, false), (0.10, false), (0.50, false), (0.09, false)]);
        assert_eq!(out.len(), 4);
        assert!(out.iter().all(|q| q.depth_m == 0.10));
    }

    #[test]
    fn the_slaves_lines_decide_the_depth_and_sncc_points_follow() {
        // SNCC put half the line on the textured surface 12 cm behind the edge the slaves' lines see.
        let out = snap(&[
            (0.20, false),
            (0.08, true),
            (0.20, false),
            (0.081, true),
            (0.20, false),
            (0.079, true),
            (0.5, false),
        ]);
        assert_eq!(out.len(), 6, "the point 42 cm off is dropped");
        assert!(out.iter().all(|q| q.depth_m == 0.08));
        assert!(out.iter().all(|q| (q.xyz.y + 0.08).abs() < 1e-9));
    }
}
