//! From hypotheses to 3-D lines: every segment's best-supported hypothesis, taken greedily from the best; each is
//! re-estimated from the segments of every image along it ([`lineflow_linegeom::multiview`]), given the extent
//! that enough images show without a gap (Line3D++'s coverage sweep), and claims its segments so that no edge is
//! reconstructed twice.
use std::collections::BTreeSet;

use lineflow_linegeom::{refine_line, refine_line_along, Line2, SlaveSegments};
use lineflow_photogrammetry::{Camera, Vec3};
use rayon::prelude::*;

use crate::appearance;
use crate::guide::Guide;
use crate::hypotheses::{pair_hypotheses, Hypothesis};
use crate::junctions;
use crate::line::MappedLine;
use crate::meeting;
use crate::support::{support, support_above};
use crate::surfaces;
use crate::views::{parameter_on_line, partners, View};
use crate::MapParams;

/// The lines as message elements, numbered from 1, classed when `p.classify`.
pub fn line_messages(lines: &[MappedLine], p: &MapParams) -> Vec<lineflow_messages::Line3> {
    let mut out: Vec<lineflow_messages::Line3> = lines
        .iter()
        .enumerate()
        .map(|(k, l)| lineflow_messages::Line3 {
            id: k as u64 + 1,
            start_m: l.start.into(),
            end_m: l.end.into(),
            n_points: l.n_segments,
            n_images: l.n_images,
            rms_m: l.rms_m,
            ..Default::default()
        })
        .collect();
    if p.classify {
        lineflow_linegeom::classify_elements(&mut out, &p.class, None);
    }
    out
}

/// A source segment's best hypothesis and its support.
#[derive(Debug, Clone, Copy)]
pub struct Scored {
    /// Support from the images other than the pair, weighted by where the hypothesis lies (the ranking).
    pub score: f64,
    /// The support itself (what must reach `min_score`).
    pub support: f64,
    /// The hypothesis.
    pub hypothesis: Hypothesis,
}

/// What became of the segments' best hypotheses.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct MapStats {
    /// Segments with a hypothesis supported enough.
    pub supported: usize,
    /// Of those, segments already claimed by a better line when their turn came.
    pub claimed: usize,
    /// Hypotheses the re-estimate from every image rejected (too few images agree within the residual).
    pub not_refined: usize,
    /// Re-estimated lines that too few images cover anywhere.
    pub not_covered: usize,
    /// Lines whose segments mostly belong to lines already made.
    pub duplicates: usize,
    /// Lines none of whose covered stretches the images agree along (the appearance test).
    pub inconsistent: usize,
    /// Re-estimated lines that moved inside the building.
    pub hidden: usize,
    /// Lines made (before cutting at gaps).
    pub made: usize,
    /// Re-estimates given a preferred direction.
    pub snapped: usize,
    /// Vertical lines of the first pass that offered junctions.
    pub verticals: usize,
    /// Lines moved onto their wall's surface.
    pub settled: usize,
    /// Level lines that took the depth of a vertical they meet.
    pub cornered: usize,
    /// Milliseconds spent on pairwise hypotheses, on the first pass's lines, on junction hypotheses and on the
    /// final lines.
    pub milliseconds: [u64; 4],
}

/// The 3-D lines of `views` (every oriented image with its segments), sought inside `bounds` when given.
pub fn map_lines(camera: &Camera, views: &[View], guide: &Guide, p: &MapParams) -> Vec<MappedLine> {
    map_lines_with_stats(camera, views, guide, p).0
}

/// [`map_lines`], and what became of the hypotheses.
pub fn map_lines_with_stats(camera: &Camera, views: &[View], guide: &Guide, p: &MapParams) -> (Vec<MappedLine>, MapStats) {
    let sources: Vec<(usize, usize)> = views
        .iter()
        .enumerate()
        .flat_map(|(i, v)| (0..v.len()).map(move |s| (i, s)))
        .collect();
    let clock = std::time::Instant::now();
    let mut lap = {
        let mut last = clock.elapsed();
        move || {
            let now = clock.elapsed();
            let ms = (now - last).as_millis() as u64;
            last = now;
            ms
        }
    };
    let partners: Vec<Vec<usize>> = (0..views.len()).map(|i| partners(views, i, p.max_partners)).collect();
    let pairwise: Vec<Option<Scored>> = sources
        .par_iter()
        .map(|&(i, s)| best_hypothesis(camera, views, (i, s), &partners[i], guide, p))
        .collect();
    let t_pairs = lap();
    // The first pass only offers its verticals to the second when junctions are on; the appearance test, which
    // verticals rarely need, is left to the pass whose lines are kept.
    let (first, mut stats) = build(camera, views, guide, pairwise.iter().flatten().copied().collect(), p, !p.junctions);
    let t_first = lap();
    if !p.junctions {
        let mut first = first;
        (stats.settled, stats.cornered) = settle(camera, views, guide, &mut first, p);
        stats.milliseconds = [t_pairs, t_first, 0, 0];
        return (first, stats);
    }
    // Again, with every segment also offered the hypotheses of the corners it makes with the verticals just made.
    let verticals = junctions::verticals(&first, 0.5);
    let projected: Vec<junctions::ProjectedVerticals> = views
        .iter()
        .map(|v| junctions::ProjectedVerticals::new(camera, v, &verticals))
        .collect();
    let best: Vec<Scored> = sources
        .par_iter()
        .zip(pairwise)
        .filter_map(|(&(i, s), pair)| {
            let corner = junctions::junction_hypotheses(camera, &views[i], s, &projected[i], guide, p)
                .into_iter()
                .filter(|ends| !ends.iter().any(|e| guide.hidden(e, p.max_behind_m)))
                .map(|ends| {
                    let (support, _) = support(camera, views, &ends, [i, i], None, p);
                    let hypothesis = Hypothesis {
                        view: i,
                        segment: s,
                        other: i,
                        other_segment: s,
                        ends,
                    };
                    Scored {
                        score: support,
                        support,
                        hypothesis,
                    }
                })
                .filter(|c| c.support >= p.min_score)
                .fold(None, |best: Option<Scored>, c| match best {
                    Some(b) if b.score >= c.score => Some(b),
                    _ => Some(c),
                });
            match (pair, corner) {
                (Some(a), Some(b)) => Some(if b.score > a.score { b } else { a }),
                (a, b) => a.or(b),
            }
        })
        .collect();
    let t_junctions = lap();
    let (mut lines, mut stats) = build(camera, views, guide, best, p, true);
    (stats.settled, stats.cornered) = settle(camera, views, guide, &mut lines, p);
    stats.verticals = verticals.len();
    stats.milliseconds = [t_pairs, t_first, t_junctions, lap()];
    (lines, stats)
}

/// The lines whose depth their own segments leave open, moved onto their wall's surface and then onto the
/// verticals they meet; how many moved in each step.
fn settle(camera: &Camera, views: &[View], guide: &Guide, lines: &mut [MappedLine], p: &MapParams) -> (usize, usize) {
    let settled = surfaces::settle_on_walls(lines, guide, &p.surfaces());
    let pixel = |x: &Vec3| views.iter().map(|v| v.metres_per_px(camera, x)).fold(f64::INFINITY, f64::min);
    (settled, meeting::settle_on_verticals(lines, guide, pixel, &p.meeting()))
}

/// Lines from the segments' best hypotheses, greedily from the best-supported down, each stretch checked in the
/// images when `appearance_test` is set.
fn build(
    camera: &Camera,
    views: &[View],
    guide: &Guide,
    mut best: Vec<Scored>,
    p: &MapParams,
    appearance_test: bool,
) -> (Vec<MappedLine>, MapStats) {
    // Best support first; ties in a fixed order of views and segments, so the result does not depend on threads.
    best.sort_by(|a, b| {
        b.score
            .total_cmp(&a.score)
            .then(a.hypothesis.view.cmp(&b.hypothesis.view))
            .then(a.hypothesis.segment.cmp(&b.hypothesis.segment))
    });
    let slaves: Vec<SlaveSegments> = views.iter().map(View::as_slave).collect();
    let refine = p.multiview();
    let mut claimed: Vec<Vec<bool>> = views.iter().map(|v| vec![false; v.len()]).collect();
    let mut lines = Vec::new();
    let mut stats = MapStats {
        supported: best.len(),
        ..MapStats::default()
    };
    for b in &best {
        let h = &b.hypothesis;
        if claimed[h.view][h.segment] {
            stats.claimed += 1;
            continue;
        }
        let Some(free) = refine_line(camera, h.ends[0], h.ends[1], &slaves, &refine) else {
            stats.not_refined += 1;
            continue;
        };
        let snapped = (p.snap_angle_deg > 0.0)
            .then(|| guide.snap(&(free.end - free.start), p.snap_angle_deg))
            .flatten()
            .and_then(|d| refine_line_along(camera, free.start, free.end, d, &slaves, &refine));
        if snapped.is_some() {
            stats.snapped += 1;
        }
        let r = snapped.unwrap_or(free);
        if guide.hidden(&r.start, p.max_behind_m) || guide.hidden(&r.end, p.max_behind_m) {
            stats.hidden += 1;
            continue;
        }
        let along = segments_along(camera, views, &[r.start, r.end], p);
        let pieces = covered_pieces(&along, p.min_cover);
        if pieces.is_empty() {
            stats.not_covered += 1;
            continue;
        }
        let fresh = along.iter().filter(|a| !claimed[a.view][a.segment]).count();
        // Mostly segments of lines already made: the same edge again.
        if 2 * fresh < along.len() {
            stats.duplicates += 1;
            continue;
        }
        let dir = (r.end - r.start).normalize();
        let rms_m = r.rms_px * views[h.view].metres_per_px(camera, &((r.start + r.end) * 0.5));
        let kept: Vec<MappedLine> = pieces
            .into_iter()
            .filter(|&(t0, t1, _, _)| t1 - t0 >= p.min_length_m)
            .map(|(t0, t1, n_images, n_segments)| MappedLine {
                start: r.start + dir * t0,
                end: r.start + dir * t1,
                n_segments,
                n_images,
                rms_m,
                across_cov: r.across_cov,
                from_corner: h.other == h.view,
            })
            .filter(|l| !appearance_test || looks_consistent(camera, views, l, p))
            .collect();
        if kept.is_empty() {
            stats.inconsistent += 1;
            continue;
        }
        stats.made += 1;
        for a in &along {
            claimed[a.view][a.segment] = true;
        }
        lines.extend(kept);
    }
    (lines, stats)
}

/// Whether the images that see `line` agree along it (the appearance test), or cannot tell. Every image that sees
/// at least half of it counts, not only those with a segment along it: the images of one strip agree at any depth
/// of a horizontal line, and those that would disagree may have found no segment there.
fn looks_consistent(camera: &Camera, views: &[View], line: &MappedLine, p: &MapParams) -> bool {
    if p.min_correlation <= -1.0 {
        return true;
    }
    let ends = [line.start, line.end];
    // Images that see at least half of it: each compares the part it sees.
    let seen_by: Vec<usize> = (0..views.len())
        .filter(|&k| {
            (0..5)
                .filter(|&i| views[k].sees(camera, &(line.start + (line.end - line.start) * (i as f64 / 4.0)), 0.0))
                .count()
                >= 3
        })
        .collect();
    appearance::agrees(camera, views, &seen_by, &ends, &p.appearance(), p.min_correlation, p.max_offset_px)
}

/// The best-supported hypothesis of segment `s` of view `i` over its `partners` (`views::partners`), if it has
/// enough support.
pub fn best_hypothesis(
    camera: &Camera,
    views: &[View],
    (i, s): (usize, usize),
    partners: &[usize],
    guide: &Guide,
    p: &MapParams,
) -> Option<Scored> {
    let mut scored: Vec<Scored> = Vec::new();
    for &j in partners {
        let other = &views[j];
        for h in pair_hypotheses(camera, (i, &views[i]), s, (j, other), guide, p) {
            let weight = guide.placement_weight(&h.ends, p.near_wall_m, p.off_wall_weight);
            // Only hypotheses that could still be the best, or (with the ambiguity test) its rival, are scored to
            // the end.
            let leader = scored.iter().map(|c| c.score).fold(0.0, f64::max);
            let floor = (p.max_ambiguity * p.min_score).max(p.max_ambiguity * leader / weight);
            if let Some((support, _)) = support_above(camera, views, &h.ends, [i, j], Some(i), floor, p) {
                scored.push(Scored {
                    score: support * weight,
                    support,
                    hypothesis: h,
                });
            }
        }
    }
    unambiguous_best(camera, &views[i], &scored, p)
}

/// The best of a segment's scored hypotheses, unless one placing it elsewhere (its midpoint `distinct_px` pixels of
/// the source image or more away) scores nearly as well: a line among repeated parallel lines (brick courses,
/// glazing bars) matched one line off in another strip lies at a wrong depth that every image of both strips
/// confirms alike.
fn unambiguous_best(camera: &Camera, view: &View, scored: &[Scored], p: &MapParams) -> Option<Scored> {
    let best = scored
        .iter()
        .fold(None, |b: Option<&Scored>, c| match b {
            Some(b) if b.score >= c.score => Some(b),
            _ => Some(c),
        })
        .filter(|b| b.support >= p.min_score)?;
    let mid = |h: &Hypothesis| (h.ends[0] + h.ends[1]) * 0.5;
    let apart = p.distinct_px * view.metres_per_px(camera, &mid(&best.hypothesis));
    let rival = scored
        .iter()
        .filter(|c| (mid(&c.hypothesis) - mid(&best.hypothesis)).norm() > apart)
        .map(|c| c.score)
        .fold(0.0, f64::max);
    (rival < p.max_ambiguity * best.score).then_some(*best)
}

/// One 2-D segment along a 3-D line: its view, its index, and the stretch of the line it covers (metres from the
/// line's start).
#[derive(Debug, Clone, Copy, PartialEq)]
struct Along {
    view: usize,
    segment: usize,
    t0: f64,
    t1: f64,
}

/// Every segment of every view that lies along the line `ends` (within the distance and angle tolerances) and
/// covers part of it or of its continuation up to one line length on either side.
fn segments_along(camera: &Camera, views: &[View], ends: &[Vec3; 2], p: &MapParams) -> Vec<Along> {
    let length = (ends[1] - ends[0]).norm();
    let dir = (ends[1] - ends[0]) / length;
    let reach = [ends[0] - dir * length, ends[1] + dir * length];
    let mut out = Vec::new();
    for (k, v) in views.iter().enumerate() {
        let (Some(a), Some(b)) = (v.pose.project_ideal(camera, &reach[0]), v.pose.project_ideal(camera, &reach[1])) else {
            continue;
        };
        let Some(line) = Line2::new(a, b) else { continue };
        let tolerance = p.max_residual_px * v.segments.pixel_mm;
        for s in v.segments.near(a, b, tolerance, p.max_angle_deg.to_radians()) {
            let e = v.segments.ends[s];
            if line.across(e[0]).abs().max(line.across(e[1]).abs()) > tolerance {
                continue;
            }
            let t = e.map(|q| parameter_on_line(&ends[0], &dir, &v.pose.center, &v.pose.ray_of_ideal(camera, q)));
            if let [Some(t0), Some(t1)] = t {
                let (t0, t1) = (t0.min(t1).max(-length), t0.max(t1).min(2.0 * length));
                if t1 > t0 {
                    out.push(Along {
                        view: k,
                        segment: s,
                        t0,
                        t1,
                    });
                }
            }
        }
    }
    out
}

/// A stretch of a line that enough views cover: from `t0` to `t1` metres along it, the views and the segments
/// that cover it.
#[derive(Debug, Clone, PartialEq)]
struct Piece {
    t0: f64,
    t1: f64,
    views: BTreeSet<usize>,
    segments: BTreeSet<(usize, usize)>,
}

impl Piece {
    fn counted(self) -> (f64, f64, u32, u32) {
        (self.t0, self.t1, self.views.len() as u32, self.segments.len() as u32)
    }
}

/// The stretches of the line that at least `min_cover` distinct views cover without a gap, each with the number
/// of views and of segments that cover it.
fn covered_pieces(along: &[Along], min_cover: usize) -> Vec<(f64, f64, u32, u32)> {
    let mut cuts: Vec<f64> = along.iter().flat_map(|a| [a.t0, a.t1]).collect();
    cuts.sort_by(f64::total_cmp);
    cuts.dedup();
    let mut pieces = Vec::new();
    let mut open: Option<Piece> = None;
    for w in cuts.windows(2) {
        let (lo, hi) = (w[0], w[1]);
        let mid = 0.5 * (lo + hi);
        let covering: Vec<&Along> = along.iter().filter(|a| a.t0 <= mid && a.t1 >= mid).collect();
        let views: BTreeSet<usize> = covering.iter().map(|a| a.view).collect();
        if views.len() >= min_cover {
            let o = open.get_or_insert_with(|| Piece {
                t0: lo,
                t1: hi,
                views: BTreeSet::new(),
                segments: BTreeSet::new(),
            });
            o.t1 = hi;
            o.views.extend(views);
            o.segments.extend(covering.iter().map(|a| (a.view, a.segment)));
        } else if let Some(piece) = open.take() {
            pieces.push(piece.counted());
        }
    }
    pieces.extend(open.map(Piece::counted));
    pieces
}

#[cfg(test)]
mod tests {
    use super::*;

    fn along(view: usize, t0: f64, t1: f64) -> Along {
        Along { view, segment: 0, t0, t1 }
    }

    #[test]
    fn coverage_keeps_gaps_and_needs_distinct_views() {
        // Views 0 and 1 cover 0–1 m, then a gap at 1.0–1.2 m that only view 0 covers, then views 1 and 2 again.
        let a = [
            along(0, 0.0, 1.2),
            along(1, 0.0, 1.0),
            along(1, 1.2, 2.0),
            along(2, 1.2, 2.0),
            along(2, 0.5, 0.6),
        ];
        let pieces = covered_pieces(&a, 2);
        assert_eq!(pieces.len(), 2, "{pieces:?}");
        assert_eq!((pieces[0].0, pieces[0].1), (0.0, 1.0));
        assert_eq!((pieces[1].0, pieces[1].1), (1.2, 2.0));
        assert_eq!(pieces[0].2, 3, "views 0, 1 and (over 0.5–0.6) 2");
        // Two segments of one view never make coverage of two.
        assert!(covered_pieces(&[along(0, 0.0, 1.0), along(0, 0.0, 1.0)], 2).is_empty());
    }

    #[test]
    fn the_point_of_a_line_nearest_a_ray() {
        let t = parameter_on_line(&Vec3::zeros(), &Vec3::x(), &Vec3::new(2.0, -5.0, 1.0), &Vec3::y()).unwrap();
        assert!((t - 2.0).abs() < 1e-12);
        assert!(parameter_on_line(&Vec3::zeros(), &Vec3::x(), &Vec3::new(0.0, 1.0, 0.0), &Vec3::x()).is_none());
    }
}
