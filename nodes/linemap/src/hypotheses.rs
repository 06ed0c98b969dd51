//! 3-D line hypotheses from pairs of images: each segment of one image cut with the interpretation plane of every
//! segment of another image that could show the same edge (LIMAP's and Line3D++'s algebraic proposals).
//!
//! A hypothesis needs no second interpretation plane to be told apart from the first: the endpoint rays of the
//! first segment must cross the second plane at a clear angle. A horizontal edge seen from two images of one
//! horizontal strip gives planes that contain those rays; no depth follows from them, and no hypothesis is made
//! (images of another strip, or a sloping path, give it one).
use lineflow_photogrammetry::{Camera, Vec3};

use crate::guide::Guide;
use crate::views::View;
use crate::MapParams;
use lineflow_linegeom::Line2;

/// A hypothesis: the 3-D segment that segment `segment` of view `view` becomes on the interpretation plane of
/// segment `other_segment` of view `other`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Hypothesis {
    /// Index of the source view.
    pub view: usize,
    /// Source segment in it.
    pub segment: usize,
    /// Index of the view it was paired with.
    pub other: usize,
    /// Segment of that view.
    pub other_segment: usize,
    /// Endpoints: the source segment's endpoint rays cut with the other plane.
    pub ends: [Vec3; 2],
}

/// Closest distance along a ray at which a line is sought, metres (in front of the lens).
const MIN_RANGE_M: f64 = 0.5;
/// Farthest distance without bounds, metres.
const MAX_RANGE_M: f64 = 1000.0;

/// Every hypothesis of segment `segment` of view `a` (index `ia`) against the segments of view `b` (index `ib`).
pub fn pair_hypotheses(
    camera: &Camera,
    (ia, a): (usize, &View),
    segment: usize,
    (ib, b): (usize, &View),
    guide: &Guide,
    p: &MapParams,
) -> Vec<Hypothesis> {
    let bounds = guide.bounds.as_ref();
    let ends = a.segments.ends[segment];
    let center = a.pose.center;
    let rays = ends.map(|e| a.pose.ray_of_ideal(camera, e));
    // The stretch of each endpoint ray worth searching.
    let range = |ray: &Vec3| match bounds {
        Some(bx) => bx
            .clip(&center, ray)
            .map(|(t0, t1)| (t0.max(MIN_RANGE_M), t1))
            .filter(|(t0, t1)| t1 > t0),
        None => Some((MIN_RANGE_M, MAX_RANGE_M)),
    };
    let (Some(r0), Some(r1)) = (range(&rays[0]), range(&rays[1])) else {
        return Vec::new();
    };
    // Where in `b` the segment can appear: the box of the four ray ends' projections (clipped to the image where
    // an end lies behind `b`).
    let corners = [
        center + rays[0] * r0.0,
        center + rays[0] * r0.1,
        center + rays[1] * r1.0,
        center + rays[1] * r1.1,
    ];
    let projected: Vec<[f64; 2]> = corners.iter().filter_map(|x| b.pose.project_ideal(camera, x)).collect();
    let half = b.half_extent_mm;
    let (lo, hi) = if projected.len() == 4 {
        let lo = [0, 1].map(|k| projected.iter().map(|q| q[k]).fold(f64::INFINITY, f64::min).max(-half[k]));
        let hi = [0, 1].map(|k| projected.iter().map(|q| q[k]).fold(f64::NEG_INFINITY, f64::max).min(half[k]));
        (lo, hi)
    } else {
        ([-half[0], -half[1]], half)
    };
    if hi[0] < lo[0] || hi[1] < lo[1] {
        return Vec::new();
    }
    let min_sin = p.min_plane_angle_deg.to_radians().sin();
    let weak_sin = p.weak_plane_angle_deg.to_radians().sin();
    let max_sin_level = p.snap_angle_deg.to_radians().sin();
    let max_cos_ray = p.min_ray_angle_deg.to_radians().cos();
    let mid_ray = (rays[0] + rays[1]).normalize();
    b.segments
        .near(lo, hi, 0.0, std::f64::consts::FRAC_PI_2)
        .into_iter()
        .filter_map(|k| {
            let n = b.normals[k];
            let to_b = n.dot(&(b.pose.center - center));
            let cut = |ray: &Vec3, (t0, t1): (f64, f64)| {
                let denom = n.dot(ray);
                if denom.abs() < min_sin {
                    return None;
                }
                let t = to_b / denom;
                (t >= t0 && t <= t1).then(|| center + ray * t)
            };
            let x = [cut(&rays[0], r0)?, cut(&rays[1], r1)?];
            if x.iter().any(|e| guide.hidden(e, p.max_behind_m)) {
                return None;
            }
            let d = (x[1] - x[0]).try_normalize(1e-12)?;
            // A horizontal line from planes this close is placed to decimetres, and one line off among parallel
            // ones (brick courses) to metres, which the images of both strips confirm alike: the corners it makes
            // with the verticals place it instead.
            if p.junctions && d.z.abs() < max_sin_level && a.normals[segment].cross(&n).norm() < weak_sin {
                return None;
            }
            // A line nearly along the line of sight of either image is placed by its endpoints alone.
            let mid_b = ((x[0] + x[1]) * 0.5 - b.pose.center).normalize();
            if d.dot(&mid_ray).abs() > max_cos_ray || d.dot(&mid_b).abs() > max_cos_ray {
                return None;
            }
            // The cut ends lie on segment k's line in `b`; they must overlap the segment itself.
            let q = [b.pose.project_ideal(camera, &x[0])?, b.pose.project_ideal(camera, &x[1])?];
            let line = Line2::new(q[0], q[1])?;
            (line.overlap_share(b.segments.ends[k]) >= p.min_overlap).then_some(Hypothesis {
                view: ia,
                segment,
                other: ib,
                other_segment: k,
                ends: x,
            })
        })
        .collect()
}
