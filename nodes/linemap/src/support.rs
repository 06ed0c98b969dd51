//! How well the other images confirm a 3-D segment: each image contributes its best 2-D segment along the
//! segment's projection, scored by a Gaussian of its distance across (in that image's pixels), so every image
//! counts once however many segments it has there (LIMAP's and Line3D++'s symmetric scoring).
use lineflow_photogrammetry::{Camera, Vec3};

use crate::views::View;
use crate::MapParams;
use lineflow_linegeom::Line2;

/// The best segment of one view along a projected 3-D segment.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Match {
    /// Index of the view.
    pub view: usize,
    /// Its segment.
    pub segment: usize,
    /// Larger distance of the segment's endpoints from the projection, pixels.
    pub distance_px: f64,
}

/// The segment of view `v` that best lies along the projection of `ends`, if any lies within the tolerances.
pub fn best_match(camera: &Camera, (iv, v): (usize, &View), ends: &[Vec3; 2], p: &MapParams) -> Option<Match> {
    let q = [v.pose.project_ideal(camera, &ends[0])?, v.pose.project_ideal(camera, &ends[1])?];
    if !(v.sees(camera, &ends[0], 0.0) || v.sees(camera, &ends[1], 0.0)) {
        return None;
    }
    let line = Line2::new(q[0], q[1])?;
    let pixel = v.segments.pixel_mm;
    if line.len < p.min_length_px * pixel {
        return None;
    }
    let tolerance = p.max_distance_px * pixel;
    v.segments
        .near(q[0], q[1], tolerance, p.max_angle_deg.to_radians())
        .into_iter()
        .filter_map(|k| {
            let s = v.segments.ends[k];
            let distance = line.across(s[0]).abs().max(line.across(s[1]).abs());
            (distance <= tolerance && line.overlap_share(s) >= p.min_overlap).then_some(Match {
                view: iv,
                segment: k,
                distance_px: distance / pixel,
            })
        })
        .min_by(|x, y| x.distance_px.total_cmp(&y.distance_px).then(x.segment.cmp(&y.segment)))
}

/// The support of a 3-D segment in `views`, leaving out the views in `skip`: the sum over views of the best
/// segment's Gaussian weight, and those best segments. With `depth_from`, only views that see the segment's depth
/// differently from that view count: those whose plane through the segment makes at least `min_plane_angle_deg`
/// with its plane. A view in the same plane (a horizontal edge seen from the same horizontal strip) sees the segment
/// where it sees every segment in front of or behind it, and would confirm any depth.
pub fn support(
    camera: &Camera,
    views: &[View],
    ends: &[Vec3; 2],
    skip: [usize; 2],
    depth_from: Option<usize>,
    p: &MapParams,
) -> (f64, Vec<Match>) {
    support_above(camera, views, ends, skip, depth_from, 0.0, p).unwrap_or_default()
}

/// [`support`], or `None` as soon as the views left cannot lift it to `floor` (each adds at most 1).
pub fn support_above(
    camera: &Camera,
    views: &[View],
    ends: &[Vec3; 2],
    skip: [usize; 2],
    depth_from: Option<usize>,
    floor: f64,
    p: &MapParams,
) -> Option<(f64, Vec<Match>)> {
    let plane = |v: &View| (ends[0] - v.pose.center).cross(&(ends[1] - v.pose.center)).try_normalize(1e-15);
    let reference = depth_from.and_then(|i| plane(&views[i]));
    let max_cos = p.min_plane_angle_deg.to_radians().cos();
    let counted: Vec<usize> = (0..views.len())
        .filter(|k| !skip.contains(k))
        .filter(|&k| match (&reference, depth_from) {
            (Some(n), Some(_)) => plane(&views[k]).is_some_and(|m| m.dot(n).abs() <= max_cos),
            (None, Some(_)) => false,
            _ => true,
        })
        .collect();
    let mut score = 0.0;
    let mut matches = Vec::new();
    for (done, &k) in counted.iter().enumerate() {
        if score + ((counted.len() - done) as f64) < floor {
            return None;
        }
        if let Some(m) = best_match(camera, (k, &views[k]), ends, p) {
            score += weight(m.distance_px, p.sigma_px);
            matches.push(m);
        }
    }
    (score >= floor).then_some((score, matches))
}

/// Gaussian weight of a distance.
pub fn weight(distance_px: f64, sigma_px: f64) -> f64 {
    (-0.5 * (distance_px / sigma_px).powi(2)).exp()
}
