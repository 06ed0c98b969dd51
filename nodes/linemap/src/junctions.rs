//! Hypotheses from junctions: a segment that ends on a vertical 3-D line already made (a window head or sill
//! meeting its jambs, a storey line meeting a corner) passes through the point where that vertical pierces the
//! segment's interpretation plane, and runs along a preferred direction lying in that plane.
//!
//! Pairs cannot place a horizontal edge seen from one horizontal strip (its planes are all one plane), and place it
//! poorly from strips a few metres apart, where a parallel line one pixel away in the other strip is a wrong depth
//! of several decimetres. A vertical edge is placed well by the same strip; where the two meet, the corner gives the
//! horizontal its depth.
use lineflow_photogrammetry::{Camera, Vec3};

use crate::guide::Guide;
use crate::line::MappedLine;
use crate::views::View;
use crate::MapParams;
use lineflow_linegeom::Line2;

/// The vertical lines as one view sees them.
pub struct ProjectedVerticals<'a> {
    lines: Vec<(&'a MappedLine, Line2)>,
}

impl<'a> ProjectedVerticals<'a> {
    /// The projections into `view` of the lines of `verticals` in front of it.
    pub fn new(camera: &Camera, view: &View, verticals: &[&'a MappedLine]) -> Self {
        let lines = verticals
            .iter()
            .filter_map(|l| {
                let (a, b) = (view.pose.project_ideal(camera, &l.start)?, view.pose.project_ideal(camera, &l.end)?);
                Some((*l, Line2::new(a, b)?))
            })
            .collect();
        ProjectedVerticals { lines }
    }
}

/// The lines of `lines` within `max_angle_deg` of the vertical.
pub fn verticals(lines: &[MappedLine], max_angle_deg: f64) -> Vec<&MappedLine> {
    let min_cos = max_angle_deg.to_radians().cos();
    lines
        .iter()
        .filter(|l| (l.end - l.start).try_normalize(1e-12).is_some_and(|d| d.z.abs() >= min_cos))
        .collect()
}

/// The junction hypotheses (3-D endpoints) of segment `s` of `view`, given the verticals it sees.
pub fn junction_hypotheses(
    camera: &Camera,
    view: &View,
    s: usize,
    verticals: &ProjectedVerticals,
    guide: &Guide,
    p: &MapParams,
) -> Vec<[Vec3; 2]> {
    let ends = view.segments.ends[s];
    let normal = view.normals[s];
    let center = view.pose.center;
    // The preferred non-vertical directions that lie in the segment's plane, turned into it.
    let max_sin = p.snap_angle_deg.to_radians().sin();
    let directions: Vec<Vec3> = guide
        .directions
        .iter()
        .filter(|d| d.z.abs() < 0.5 && d.dot(&normal).abs() <= max_sin)
        .filter_map(|d| (d - normal * d.dot(&normal)).try_normalize(1e-12))
        .collect();
    if directions.is_empty() {
        return Vec::new();
    }
    let rays = ends.map(|e| view.pose.ray_of_ideal(camera, e));
    let tolerance = p.junction_px * view.segments.pixel_mm;
    let mut out = Vec::new();
    for end in ends {
        for (line, projected) in &verticals.lines {
            let along = projected.along(end);
            if projected.across(end).abs() > tolerance || along < -tolerance || along > projected.len + tolerance {
                continue;
            }
            let Some(corner) = pierce(&line.start, &line.end, &center, &normal) else {
                continue;
            };
            for d in &directions {
                let t = rays.map(|r| crate::views::parameter_on_line(&corner, d, &center, &r));
                if let [Some(t0), Some(t1)] = t {
                    if (t1 - t0).abs() > 1e-6 {
                        out.push([corner + d * t0, corner + d * t1]);
                    }
                }
            }
        }
    }
    out
}

/// Where the line through `a` and `b` pierces the plane through `center` with unit normal `normal`, if it crosses
/// it at a clear angle.
fn pierce(a: &Vec3, b: &Vec3, center: &Vec3, normal: &Vec3) -> Option<Vec3> {
    let d = b - a;
    let denom = normal.dot(&d);
    if denom.abs() < 0.05 * d.norm() {
        return None;
    }
    Some(a + d * (normal.dot(&(center - a)) / denom))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_vertical_pierces_a_plane_and_a_parallel_one_does_not() {
        let (a, b) = (Vec3::new(1.0, 2.0, 0.0), Vec3::new(1.0, 2.0, 3.0));
        let p = pierce(&a, &b, &Vec3::new(0.0, 0.0, 1.5), &Vec3::z()).unwrap();
        assert!((p - Vec3::new(1.0, 2.0, 1.5)).norm() < 1e-12);
        assert!(pierce(&a, &b, &Vec3::zeros(), &Vec3::x()).is_none());
    }
}
