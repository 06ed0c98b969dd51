//! Which true edges the images can tell apart from their parallel neighbours.
//!
//! A window's frame stands 4 cm in front of its glass, a sill's top edge 3 cm below the opening: seen from a
//! street 19 m away such pairs of parallel edges are a pixel or two apart in most images, one image edge where
//! the truth has two. No method working from image edges recovers both, so the success rate is reported over the
//! edges the images resolve as well as over all of them (`docs/eval.md`).
use lineflow_photogrammetry::{Camera, Pose, Vec3};
use rayon::prelude::*;

use crate::geometry::{bounds, segment_grid, Grid, Seg};

/// Parallel edges closer than this in an image are one image edge there, pixels.
pub const RESOLVE_PX: f64 = 4.0;
/// Images that must show an edge that far from each of its neighbours: a 3-D line needs two views.
pub const RESOLVE_VIEWS: usize = 2;
/// Neighbours are parallel true edges (within this angle, degrees)…
const PARALLEL_DEG: f64 = 2.0;
/// …within this distance of the edge's midpoint, metres (farther ones are apart in any image of a façade).
const NEIGHBOUR_M: f64 = 0.15;

/// For each true edge: whether at least [`RESOLVE_VIEWS`] images show its midpoint at least [`RESOLVE_PX`] from
/// the projection of every parallel true edge that runs beside it. Images count where the midpoint projects
/// into the frame; occlusion is not tested, so this overstates what is resolvable rather than understating it.
pub fn resolvable(camera: &Camera, poses: &[Pose], truth: &[Seg]) -> Vec<bool> {
    if truth.is_empty() {
        return Vec::new();
    }
    let (lo, hi) = bounds(truth.iter().flat_map(|s| [&s.a, &s.b]));
    let grid = segment_grid(truth, NEIGHBOUR_M, (lo - Vec3::repeat(1.0), hi + Vec3::repeat(1.0)));
    (0..truth.len())
        .into_par_iter()
        .map(|i| resolved(camera, poses, truth, &grid, i))
        .collect()
}

fn resolved(camera: &Camera, poses: &[Pose], truth: &[Seg], grid: &Grid, i: usize) -> bool {
    let edge = &truth[i];
    let mid = edge.at(0.5);
    // The point of each neighbour beside the midpoint.
    let beside: Vec<Vec3> = grid
        .near(&mid)
        .iter()
        .filter(|&&j| j as usize != i)
        .map(|&j| &truth[j as usize])
        .filter(|other| other.angle_deg(edge) <= PARALLEL_DEG && other.line_distance(&mid) <= NEIGHBOUR_M)
        .filter_map(|other| {
            let t = other.param(&mid);
            (0.0..=1.0).contains(&t).then(|| other.at(t))
        })
        .collect();
    if beside.is_empty() {
        return true;
    }
    // A short piece of the edge around its midpoint gives its image direction.
    let half = edge.dir() * (0.05f64).min(edge.length() / 2.0);
    let views = poses
        .iter()
        .filter(|pose| {
            let (Some(m), Some(a), Some(b)) = (
                pose.project(camera, &mid),
                pose.project(camera, &(mid - half)),
                pose.project(camera, &(mid + half)),
            ) else {
                return false;
            };
            let (dx, dy) = (b[0] - a[0], b[1] - a[1]);
            let len = dx.hypot(dy);
            if !camera.contains(m, 0.0) || len < 1e-9 {
                return false;
            }
            let across = |p: [f64; 2]| ((p[0] - m[0]) * -dy + (p[1] - m[1]) * dx).abs() / len;
            beside
                .iter()
                .all(|q| pose.project(camera, q).is_none_or(|p| across(p) >= RESOLVE_PX))
        })
        .count();
    views >= RESOLVE_VIEWS
}

#[cfg(test)]
mod tests {
    use super::*;
    use lineflow_photogrammetry::rotation_from_opk;

    /// A strip of cameras 19 m in front of the wall y = 0, every 2 m along x, looking at it.
    fn strip() -> (Camera, Vec<Pose>) {
        let camera = Camera::pinhole(4288, 2848, 0.0055, 17.6);
        let poses = (0..9)
            .map(|k| Pose {
                center: Vec3::new(2.0 * k as f64 - 8.0, -19.0, 1.6),
                rotation: rotation_from_opk(std::f64::consts::FRAC_PI_2, 0.0, 0.0),
            })
            .collect();
        (camera, poses)
    }

    #[test]
    fn parallel_edges_one_behind_the_other_are_resolved_only_where_the_views_separate_them() {
        let (camera, poses) = strip();
        let seg = |a: [f64; 3], b: [f64; 3]| Seg::new(Vec3::from(a), Vec3::from(b));
        let truth = [
            // A horizontal edge at camera height and a parallel one 10 cm behind it: the strip sees them along
            // its own plane, where they coincide.
            seg([0.0, 0.2, 1.6], [1.4, 0.2, 1.6]),
            seg([0.0, 0.3, 1.6], [1.4, 0.3, 1.6]),
            // The same pair standing vertically: cameras 5 m or more to the side see the 10 cm as at least 4 px.
            seg([3.0, 0.2, 1.0], [3.0, 0.2, 2.5]),
            seg([3.0, 0.3, 1.0], [3.0, 0.3, 2.5]),
            // An edge with no neighbour.
            seg([6.0, 0.0, 3.0], [7.0, 0.0, 3.0]),
        ];
        assert_eq!(resolvable(&camera, &poses, &truth), vec![false, false, true, true, true]);
    }
}
