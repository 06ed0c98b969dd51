//! Depths from the slaves' own 2-D lines (the thesis's future work: multi-image forward intersection of lines).
//!
//! SNCC finds the depth of a master line to about a depth step, and at a depth discontinuity (a reveal, a sill) its
//! window sees two surfaces and follows the one with more texture. A slave that saw the same edge as a 2-D segment
//! fixes the depth far better: every master ray of the line cut with that segment's interpretation plane gives the
//! depth at which the slave sees the edge, to the sub-pixel precision of the 2-D line. SNCC's depth only has to be
//! close enough to pick the right slave segment. Lines parallel to the baseline (the horizontal edges of a strip)
//! have interpretation planes that contain the master rays; they keep their SNCC depth.
use lineflow_linegeom::segments::unit;
use lineflow_linegeom::SlaveSegments;
use lineflow_photogrammetry::{Camera, Pose, Vec3};

use crate::wall::WallPlane;
use crate::{MatchParams, MatchedPoint};

/// One slave segment, as seen from the master line: its interpretation plane and its extent in the slave image.
struct Candidate {
    /// Ideal endpoints in the slave (mm).
    ends: [[f64; 2]; 2],
    /// Unit normal of the interpretation plane through the slave's centre.
    normal: Vec3,
    /// The same plane with the line moved one pixel across, for the depth's sensitivity.
    shifted_normal: Vec3,
}

/// Where the slaves' 2-D lines are searched for one line's rays: around a prior depth per ray, within a window.
pub struct LineSearch<'a> {
    /// Each ray's prior depth in front of the wall, metres (its SNCC depth, or the wall itself).
    pub priors: &'a [f64],
    /// Largest distance of a depth from its prior, metres.
    pub max_shift_m: f64,
    /// Slaves whose lines must agree on a depth.
    pub min_slaves: usize,
    /// No depth where another one, more than a pixel away, has this share of its slaves agreeing (above 1: no
    /// such test).
    pub max_rival: f64,
    /// Share of the slaves with a line near the ray (a cut anywhere in the window) that must agree.
    pub min_share: f64,
}

/// Moves each point to the depth at which the slaves' 2-D lines put its edge, where enough slaves agree; points
/// without such support keep their SNCC depth. `master_center` and `rays[k]` are point k's master ray, `wall` the
/// plane its depths are measured from.
pub fn refine_depths(
    camera: &Camera,
    master_center: &Vec3,
    wall: &WallPlane,
    points: &mut [MatchedPoint],
    rays: &[Vec3],
    slaves: &[SlaveSegments],
    p: &MatchParams,
) -> usize {
    if !p.line_depth || points.len() < 2 {
        return 0;
    }
    let priors: Vec<f64> = points.iter().map(|q| q.depth_m).collect();
    let search = LineSearch {
        priors: &priors,
        max_shift_m: p.line_max_shift_m,
        min_slaves: p.line_min_slaves,
        max_rival: f64::INFINITY,
        min_share: 0.0,
    };
    let depths = depths_from_lines(camera, master_center, wall, rays, slaves, &search, p);
    let mut moved = 0;
    for ((pt, ray), d) in points.iter_mut().zip(rays).zip(depths) {
        let Some((depth, s)) = d else { continue };
        pt.depth_m = depth;
        pt.xyz = master_center + s * ray;
        pt.from_lines = true;
        moved += 1;
    }
    moved
}

/// For each ray, the depth in front of the wall at which the slaves' 2-D lines put its edge within the search
/// window, where at least `min_slaves` slaves agree, and the ray parameter that reaches it.
pub fn depths_from_lines(
    camera: &Camera,
    master_center: &Vec3,
    wall: &WallPlane,
    rays: &[Vec3],
    slaves: &[SlaveSegments],
    search: &LineSearch,
    p: &MatchParams,
) -> Vec<Option<(f64, f64)>> {
    let none = vec![None; rays.len()];
    if rays.len() < 2 || slaves.is_empty() {
        return none;
    }
    let at = |k: usize| {
        wall.ray_parameter(master_center, &rays[k], search.priors[k])
            .map(|s| master_center + s * rays[k])
    };
    let (Some(first), Some(last)) = (at(0), at(rays.len() - 1)) else {
        return none;
    };
    let max_angle = p.line_max_angle_deg.to_radians();
    let lowest = search.priors.iter().copied().fold(f64::INFINITY, f64::min);
    let highest = search.priors.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    let window = (lowest - search.max_shift_m, highest + search.max_shift_m);
    // Per slave: the candidates near the master line's projection.
    let candidates: Vec<(&SlaveSegments, Vec<Candidate>)> = slaves
        .iter()
        .filter_map(|s| {
            let (a, b) = (s.pose.project_ideal(camera, &first)?, s.pose.project_ideal(camera, &last)?);
            // A depth change of max_shift_m moves the projection by at most this much (generously: the parallax
            // of the whole shift at the nearer end, plus a few pixels of slack).
            let parallax = |x: &Vec3| parallax_mm(camera, &s.pose, x, &wall.normal, search.max_shift_m);
            let margin = parallax(&first).max(parallax(&last)) + 3.0 * s.segments.pixel_mm;
            let found: Vec<Candidate> = s
                .segments
                .near(a, b, margin, max_angle)
                .into_iter()
                .filter_map(|k| candidate(camera, &s.pose, s.segments.ends[k], s.segments.pixel_mm))
                .filter(|c| reaches_window(c, (master_center, &rays[0], &rays[rays.len() - 1]), wall, s, window))
                .collect();
            (!found.is_empty()).then_some((s, found))
        })
        .collect();
    if candidates.is_empty() {
        return none;
    }
    let mut cuts: Vec<Cut> = Vec::new();
    rays.iter()
        .zip(search.priors)
        .map(|(ray, &prior)| {
            cuts.clear();
            for (k, (slave, found)) in candidates.iter().enumerate() {
                cuts.extend(
                    found
                        .iter()
                        .filter_map(|c| slave_depth(camera, (master_center, ray), wall, (prior, search.max_shift_m), slave, c, p))
                        .map(|(depth, per_px)| Cut { depth, per_px, slave: k }),
                );
            }
            cuts.sort_by(|a, b| a.depth.total_cmp(&b.depth));
            let depth_m = consensus(&cuts, prior, search.min_slaves, search.max_rival)?;
            let near_ray = distinct_slaves(cuts.iter());
            let agreeing = distinct_slaves(cuts.iter().filter(|c| (c.depth - depth_m).abs() <= AGREE_PX * c.per_px));
            if (agreeing as f64) < search.min_share * near_ray as f64 {
                return None;
            }
            Some((depth_m, wall.ray_parameter(master_center, ray, depth_m)?))
        })
        .collect()
}

/// How many slaves the cuts come from (they are sorted by depth, not by slave).
fn distinct_slaves<'c>(cuts: impl Iterator<Item = &'c Cut>) -> usize {
    let mut slaves: Vec<usize> = cuts.map(|c| c.slave).collect();
    slaves.sort_unstable();
    slaves.dedup();
    slaves.len()
}

/// Whether a candidate's plane can cut the line's rays within the depth window: the cuts of the rays between the
/// first and the last lie on one 3-D line, so their depths lie between those of the two ends (or the plane is
/// met behind the master, and the candidate is kept for the per-ray test).
fn reaches_window(
    c: &Candidate,
    (center, first, last): (&Vec3, &Vec3, &Vec3),
    wall: &WallPlane,
    slave: &SlaveSegments,
    (lo, hi): (f64, f64),
) -> bool {
    let depth = |ray: &Vec3| {
        let denom = c.normal.dot(ray);
        let s = c.normal.dot(&(slave.pose.center - center)) / denom;
        (denom.abs() > 1e-12 && s > 0.0).then(|| wall.depth_of(&(center + s * ray)))
    };
    match (depth(first), depth(last)) {
        (Some(a), Some(b)) => a.max(b) >= lo && a.min(b) <= hi,
        _ => true,
    }
}

/// How far (mm, ideal) the projection of `x` moves in the slave when `x` moves `shift` metres along `normal`.
fn parallax_mm(camera: &Camera, pose: &Pose, x: &Vec3, normal: &Vec3, shift: f64) -> f64 {
    match (
        pose.project_ideal(camera, &(x + normal * shift)),
        pose.project_ideal(camera, &(x - normal * shift)),
    ) {
        (Some(a), Some(b)) => (a[0] - b[0]).hypot(a[1] - b[1]) / 2.0,
        _ => f64::INFINITY,
    }
}

/// The interpretation plane of a slave segment and that of the segment moved one pixel across.
fn candidate(camera: &Camera, pose: &Pose, ends: [[f64; 2]; 2], pixel_mm: f64) -> Option<Candidate> {
    let plane = |e: [[f64; 2]; 2]| {
        pose.ray_of_ideal(camera, e[0])
            .cross(&pose.ray_of_ideal(camera, e[1]))
            .try_normalize(1e-12)
    };
    let d = unit([ends[1][0] - ends[0][0], ends[1][1] - ends[0][1]]);
    let off = [-d[1] * pixel_mm, d[0] * pixel_mm];
    let shifted = [
        [ends[0][0] + off[0], ends[0][1] + off[1]],
        [ends[1][0] + off[0], ends[1][1] + off[1]],
    ];
    Some(Candidate {
        ends,
        normal: plane(ends)?,
        shifted_normal: plane(shifted)?,
    })
}

/// The depth (in front of `wall`) where the master ray meets the candidate's plane, with its change per pixel
/// across the slave line, if the slave sees the point on (or within a few pixels of) the segment, the geometry is
/// not degenerate and the depth is within `max_shift` of the prior.
fn slave_depth(
    camera: &Camera,
    (master_center, ray): (&Vec3, &Vec3),
    wall: &WallPlane,
    (prior, max_shift): (f64, f64),
    slave: &SlaveSegments,
    c: &Candidate,
    p: &MatchParams,
) -> Option<(f64, f64)> {
    let slave_center = slave.pose.center;
    let cut = |n: &Vec3| {
        let denom = n.dot(ray);
        (denom.abs() > 1e-12).then(|| n.dot(&(slave_center - master_center)) / denom)
    };
    let (s, s1) = (cut(&c.normal)?, cut(&c.shifted_normal)?);
    if s <= 0.0 {
        return None;
    }
    let x = master_center + s * ray;
    let depth = wall.depth_of(&x);
    let per_px = (wall.depth_of(&(master_center + s1 * ray)) - depth).abs();
    if per_px.is_nan() || per_px >= p.line_max_depth_per_px_m || (depth - prior).abs() > max_shift {
        return None;
    }
    // The slave must see the point on the segment, not on its extension.
    let q = slave.pose.project_ideal(camera, &x)?;
    let [a, b] = c.ends;
    let (dx, dy) = (b[0] - a[0], b[1] - a[1]);
    let len = dx.hypot(dy);
    let t = ((q[0] - a[0]) * dx + (q[1] - a[1]) * dy) / len;
    let slack = 2.0 * slave.segments.pixel_mm;
    (t >= -slack && t <= len + slack).then_some((depth, per_px))
}

/// Slaves agree when their depths differ by less than this many pixels of the less certain one.
const AGREE_PX: f64 = 0.5;

/// One master ray cut with one slave segment's interpretation plane.
#[derive(Debug, Clone, Copy)]
struct Cut {
    /// Depth in front of the wall, metres.
    depth: f64,
    /// Depth change for one pixel across the slave line, metres.
    per_px: f64,
    /// Which slave.
    slave: usize,
}

/// The agreed depth of the cuts: each cut seeds a group of the cuts within [`AGREE_PX`] of it, at most one per slave
/// (the nearest); the group with the most slaves wins, ties going to the one nearest the SNCC depth `prior`; its
/// depths are averaged with weights 1/σ². Several parallel edges near one another (the outer and inner edges of a
/// reveal, a frame's profile) each give a cut per slave, but only the true one gives the same depth in every slave.
/// `cuts` sorted by depth lets each seed look only at the cuts within reach of it (hundreds of cuts per ray where
/// the courses of a brick wall are all candidates).
fn consensus(cuts: &[Cut], prior: f64, min_slaves: usize, max_rival: f64) -> Option<f64> {
    debug_assert!(cuts.windows(2).all(|w| w[0].depth <= w[1].depth));
    let reach = AGREE_PX * cuts.iter().map(|c| c.per_px).fold(0.0, f64::max);
    // (slaves, mean, largest σ per pixel) of the group each cut seeds.
    let mut groups: Vec<(usize, f64, f64)> = Vec::with_capacity(cuts.len());
    let mut group: Vec<Cut> = Vec::new();
    for seed in cuts {
        group.clear();
        let from = cuts.partition_point(|c| c.depth < seed.depth - reach);
        let to = cuts.partition_point(|c| c.depth <= seed.depth + reach);
        for c in &cuts[from..to] {
            if (c.depth - seed.depth).abs() > AGREE_PX * c.per_px.max(seed.per_px) {
                continue;
            }
            match group.iter_mut().find(|g| g.slave == c.slave) {
                Some(g) if (c.depth - seed.depth).abs() < (g.depth - seed.depth).abs() => *g = *c,
                Some(_) => {}
                None => group.push(*c),
            }
        }
        let w: f64 = group.iter().map(|c| 1.0 / (c.per_px * c.per_px).max(1e-12)).sum();
        let mean = group.iter().map(|c| c.depth / (c.per_px * c.per_px).max(1e-12)).sum::<f64>() / w;
        let widest = group.iter().map(|c| c.per_px).fold(0.0, f64::max);
        groups.push((group.len(), mean, widest));
    }
    let best = groups.iter().copied().reduce(|best, g| {
        let better = g.0 > best.0 || (g.0 == best.0 && (g.1 - prior).abs() < (best.1 - prior).abs());
        if better {
            g
        } else {
            best
        }
    })?;
    // Repeated structure (the jambs of a row of windows, a frame's profile) can give a second depth that as many
    // slaves agree on; without an SNCC depth to choose, such a point has none.
    let rivalled = groups
        .iter()
        .any(|g| g.0 as f64 >= max_rival * best.0 as f64 && (g.1 - best.1).abs() > best.2.max(g.2));
    (best.0 >= min_slaves && !rivalled).then_some(best.1)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::Mode;
    use lineflow_linegeom::FrameSegments;
    use lineflow_messages::Segment2;
    use lineflow_photogrammetry::rotation_from_opk;

    fn sorted(cuts: &[Cut]) -> Vec<Cut> {
        let mut v = cuts.to_vec();
        v.sort_by(|a, b| a.depth.total_cmp(&b.depth));
        v
    }

    fn camera() -> Camera {
        Camera::pinhole(4000, 3000, 0.005, 20.0)
    }

    /// A camera 12 m in front of the wall y = 0 (outward normal −y), looking at it.
    fn pose(x: f64) -> Pose {
        Pose {
            center: Vec3::new(x, -12.0, 1.5),
            rotation: rotation_from_opk(std::f64::consts::FRAC_PI_2, 0.0, 0.0),
        }
    }

    fn segment(cam: &Camera, pose: &Pose, a: Vec3, b: Vec3, id: u32) -> Segment2 {
        Segment2 {
            id,
            start_px: pose.project(cam, &a).unwrap(),
            end_px: pose.project(cam, &b).unwrap(),
            ..Default::default()
        }
    }

    /// Points of the master's view of the edge a–b, all placed at a wrong SNCC depth.
    fn points(cam: &Camera, master: &Pose, wall: &WallPlane, a: Vec3, b: Vec3, sncc_depth: f64) -> (Vec<MatchedPoint>, Vec<Vec3>) {
        (0..=10)
            .map(|k| {
                let x = a + (b - a) * (k as f64 / 10.0);
                let ideal = master.project_ideal(cam, &x).unwrap();
                let ray = master.ray_of_ideal(cam, ideal);
                let s = wall.ray_parameter(&master.center, &ray, sncc_depth).unwrap();
                let pt = MatchedPoint {
                    pixel: cam.ideal_to_pixel(ideal).unwrap(),
                    ideal,
                    depth_m: sncc_depth,
                    xyz: master.center + s * ray,
                    sncc: 0.9,
                    mode: Mode::C,
                    from_lines: false,
                };
                (pt, ray)
            })
            .unzip()
    }

    /// Three slaves at −1.5, 1.5 and 3 m; each sees the edge a–b and a parallel joint 25 cm to the side.
    fn slave_frames(cam: &Camera, a: Vec3, b: Vec3) -> Vec<(Pose, FrameSegments)> {
        let side = Vec3::new(0.25, 0.0, 0.0);
        [-1.5, 1.5, 3.0]
            .iter()
            .map(|&x| {
                let p = pose(x);
                let segs = [segment(cam, &p, a + side, b + side, 0), segment(cam, &p, a, b, 1)];
                (p, FrameSegments::new(cam, &segs, 10.0))
            })
            .collect()
    }

    fn refine(a: Vec3, b: Vec3, sncc_depth: f64) -> (Vec<MatchedPoint>, usize) {
        let cam = camera();
        let wall = WallPlane::from_plane("w", Vec3::new(0.0, -1.0, 0.0), Vec3::zeros());
        let master = pose(0.0);
        let frames = slave_frames(&cam, a, b);
        let slaves: Vec<SlaveSegments> = frames
            .iter()
            .map(|(pose, segments)| SlaveSegments { pose: *pose, segments })
            .collect();
        let (mut pts, rays) = points(&cam, &master, &wall, a, b, sncc_depth);
        let moved = refine_depths(&cam, &master.center, &wall, &mut pts, &rays, &slaves, &MatchParams::default());
        (pts, moved)
    }

    #[test]
    fn slave_lines_put_a_vertical_edge_at_its_true_depth() {
        let (a, b) = (Vec3::new(0.5, -0.08, 0.5), Vec3::new(0.5, -0.08, 2.5));
        let (pts, moved) = refine(a, b, 0.12);
        assert_eq!(moved, pts.len());
        for p in &pts {
            assert!((p.depth_m - 0.08).abs() < 1e-6, "depth {}", p.depth_m);
            assert!((p.xyz.x - 0.5).abs() < 1e-6 && (p.xyz.y + 0.08).abs() < 1e-6, "{:?}", p.xyz);
        }
    }

    #[test]
    fn a_line_along_the_baseline_keeps_its_sncc_depth() {
        let (a, b) = (Vec3::new(-1.0, -0.08, 1.0), Vec3::new(2.0, -0.08, 1.0));
        let (pts, moved) = refine(a, b, 0.12);
        assert_eq!(moved, 0);
        assert!(pts.iter().all(|p| p.depth_m == 0.12));
    }

    #[test]
    fn a_depth_beyond_the_allowed_shift_is_left_alone() {
        let (a, b) = (Vec3::new(0.5, -0.08, 0.5), Vec3::new(0.5, -0.08, 2.5));
        let sncc = 0.08 + MatchParams::default().line_max_shift_m + 0.05;
        let (pts, moved) = refine(a, b, sncc);
        assert_eq!(moved, 0);
        assert!(pts.iter().all(|p| p.depth_m == sncc));
    }

    #[test]
    fn lines_alone_place_an_edge_anywhere_in_the_range_but_not_a_rivalled_one() {
        let cam = camera();
        let wall = WallPlane::from_plane("w", Vec3::new(0.0, -1.0, 0.0), Vec3::zeros());
        let master = pose(0.0);
        let (a, b) = (Vec3::new(0.5, -0.6, 0.5), Vec3::new(0.5, -0.6, 2.5));
        let frames = slave_frames(&cam, a, b);
        let slaves: Vec<SlaveSegments> = frames
            .iter()
            .map(|(pose, segments)| SlaveSegments { pose: *pose, segments })
            .collect();
        let (_, rays) = points(&cam, &master, &wall, a, b, 0.0);
        let priors = vec![0.0; rays.len()];
        let search = |min_slaves, max_rival| LineSearch {
            priors: &priors,
            max_shift_m: 1.0,
            min_slaves,
            max_rival,
            min_share: 0.6,
        };
        let p = MatchParams::default();
        // 60 cm in front of the wall, far beyond any SNCC depth's reach: every slave agrees.
        let found = depths_from_lines(&cam, &master.center, &wall, &rays, &slaves, &search(3, 0.5), &p);
        for d in &found {
            let (depth, _) = d.expect("a depth for every ray");
            assert!((depth - 0.6).abs() < 1e-6, "depth {depth}");
        }
        // Four slaves are more than there are.
        let too_few = depths_from_lines(&cam, &master.center, &wall, &rays, &slaves, &search(4, 0.5), &p);
        assert!(too_few.iter().all(Option::is_none));
    }

    #[test]
    fn a_depth_as_many_slaves_agree_on_elsewhere_is_no_depth() {
        let cut = |depth, slave| Cut {
            depth,
            per_px: 0.01,
            slave,
        };
        // A course one course off: all three slaves agree there as well.
        let cuts = [cut(0.0, 0), cut(0.001, 1), cut(0.0, 2), cut(0.3, 0), cut(0.301, 1), cut(0.3, 2)];
        let d = consensus(&sorted(&cuts), 0.0, 3, f64::INFINITY).unwrap();
        assert!((d - 0.001 / 3.0).abs() < 1e-12, "{d}");
        assert_eq!(consensus(&sorted(&cuts), 0.0, 3, 0.5), None);
        // Only one slave sees the other depth: no rival.
        let lone = [cut(0.0, 0), cut(0.001, 1), cut(0.0, 2), cut(0.3, 0)];
        assert!(consensus(&sorted(&lone), 0.0, 3, 0.5).is_some());
    }

    #[test]
    fn slaves_are_counted_once_whatever_the_order_of_their_cuts() {
        let cut = |depth, slave| Cut {
            depth,
            per_px: 0.01,
            slave,
        };
        // Sorted by depth, one slave's cuts are not next to each other.
        let cuts = sorted(&[cut(0.0, 0), cut(0.1, 1), cut(0.2, 0), cut(0.3, 1), cut(0.4, 2)]);
        assert_eq!(distinct_slaves(cuts.iter()), 3);
    }

    #[test]
    fn consensus_needs_agreeing_slaves() {
        let cut = |depth, slave| Cut {
            depth,
            per_px: 0.01,
            slave,
        };
        assert_eq!(consensus(&sorted(&[cut(0.1, 0)]), 0.1, 2, f64::INFINITY), None);
        assert_eq!(consensus(&sorted(&[cut(0.1, 0), cut(0.3, 1)]), 0.1, 2, f64::INFINITY), None);
        // Two cuts of one slave are one vote.
        assert_eq!(consensus(&sorted(&[cut(0.1, 0), cut(0.102, 0)]), 0.1, 2, f64::INFINITY), None);
        let d = consensus(&sorted(&[cut(0.1, 0), cut(0.104, 1), cut(0.3, 2)]), 0.1, 2, f64::INFINITY).unwrap();
        assert!((d - 0.102).abs() < 1e-12);
    }

    #[test]
    fn the_edge_every_slave_agrees_on_wins_over_the_one_nearest_sncc() {
        let cut = |depth, slave| Cut {
            depth,
            per_px: 0.02,
            slave,
        };
        // Each slave also sees the reveal's outer edge; its cuts scatter (different parallax), the inner edge's agree.
        let cuts = [
            cut(0.02, 0),
            cut(0.21, 0),
            cut(0.06, 1),
            cut(0.212, 1),
            cut(-0.03, 2),
            cut(0.208, 2),
        ];
        let d = consensus(&sorted(&cuts), 0.03, 2, f64::INFINITY).unwrap();
        assert!((d - 0.21).abs() < 0.003, "{d}");
    }
}
