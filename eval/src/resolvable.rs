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
    let grid = neighbour_grid(truth);
    (0..truth.len())
        .into_par_iter()
        .map(|i| resolved(camera, poses, truth, &grid, i))
        .collect()
}

/// The true edges indexed for finding each one's neighbours.
fn neighbour_grid(truth: &[Seg]) -> Grid {
    let (lo, hi) = bounds(truth.iter().flat_map(|s| [&s.a, &s.b]));
    segment_grid(truth, NEIGHBOUR_M, (lo - Vec3::repeat(1.0), hi + Vec3::repeat(1.0)))
}

fn resolved(camera: &Camera, poses: &[Pose], truth: &[Seg], grid: &Grid, i: usize) -> bool {
    let beside: Vec<Vec3> = neighbours(truth, grid, i).into_iter().map(|(_, q)| q).collect();
    beside.is_empty() || views_apart(camera, poses, &truth[i], &beside) >= RESOLVE_VIEWS
}

/// The parallel true edges that run beside edge `i`, each with its point beside `i`'s midpoint.
fn neighbours(truth: &[Seg], grid: &Grid, i: usize) -> Vec<(usize, Vec3)> {
    let edge = &truth[i];
    let mid = edge.at(0.5);
    grid.near(&mid)
        .iter()
        .map(|&j| j as usize)
        .filter(|&j| j != i)
        .filter(|&j| truth[j].angle_deg(edge) <= PARALLEL_DEG && truth[j].line_distance(&mid) <= NEIGHBOUR_M)
        .filter_map(|j| {
            let t = truth[j].param(&mid);
            (0.0..=1.0).contains(&t).then(|| (j, truth[j].at(t)))
        })
        .collect()
}

/// The images that show `edge`'s midpoint at least [`RESOLVE_PX`] from each of the points `beside` it.
fn views_apart(camera: &Camera, poses: &[Pose], edge: &Seg, beside: &[Vec3]) -> usize {
    let mid = edge.at(0.5);
    // A short piece of the edge around its midpoint gives its image direction.
    let half = edge.dir() * (0.05f64).min(edge.length() / 2.0);
    poses
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
        .count()
}

/// For each true edge, the parallel neighbours more than `min_apart_m` from it (one line cannot lie within the
/// tolerance of both) that fewer than [`RESOLVE_VIEWS`] images show apart from it, taken one neighbour at a time and
/// both ways: pairs of which lines placed from the images recover one.
pub fn inseparable(camera: &Camera, poses: &[Pose], truth: &[Seg], min_apart_m: f64) -> Vec<Vec<usize>> {
    if truth.is_empty() {
        return Vec::new();
    }
    let grid = neighbour_grid(truth);
    let one_way: Vec<Vec<usize>> = (0..truth.len())
        .into_par_iter()
        .map(|i| {
            neighbours(truth, &grid, i)
                .into_iter()
                .filter(|(_, q)| (q - truth[i].at(0.5)).norm() > min_apart_m)
                .filter(|(_, q)| views_apart(camera, poses, &truth[i], std::slice::from_ref(q)) < RESOLVE_VIEWS)
                .map(|(j, _)| j)
                .collect()
        })
        .collect();
    let mut both = one_way.clone();
    for (i, js) in one_way.iter().enumerate() {
        for &j in js {
            both[j].push(i);
        }
    }
    for js in &mut both {
        js.sort_unstable();
        js.dedup();
    }
    both
}

/// The most of the edges `members` that any set of lines can recover when of two inseparable edges
/// ([`inseparable`]) only one can be: the largest set of members no two of which are inseparable (exact on
/// groups of up to [`EXACT_GROUP`] edges, greedy, by fewest conflicts first, on larger ones).
pub fn most_recoverable(members: &[usize], inseparable: &[Vec<usize>]) -> usize {
    let mut index = std::collections::BTreeMap::new();
    for (k, &m) in members.iter().enumerate() {
        index.insert(m, k);
    }
    let adjacent: Vec<Vec<usize>> = members
        .iter()
        .map(|&m| inseparable[m].iter().filter_map(|j| index.get(j).copied()).collect())
        .collect();
    let mut seen = vec![false; members.len()];
    let mut total = 0;
    for start in 0..members.len() {
        if seen[start] {
            continue;
        }
        let mut group = vec![start];
        seen[start] = true;
        let mut k = 0;
        while k < group.len() {
            for &j in &adjacent[group[k]] {
                if !seen[j] {
                    seen[j] = true;
                    group.push(j);
                }
            }
            k += 1;
        }
        total += largest_free_set(&group, &adjacent);
    }
    total
}

/// Groups up to this size get the exact largest set of mutually separable edges.
pub const EXACT_GROUP: usize = 20;

/// The size of the largest subset of `group` with no two members adjacent.
fn largest_free_set(group: &[usize], adjacent: &[Vec<usize>]) -> usize {
    if group.len() <= EXACT_GROUP {
        let position = |x: usize| group.iter().position(|&g| g == x);
        let masks: Vec<u32> = group
            .iter()
            .map(|&g| adjacent[g].iter().filter_map(|&j| position(j)).fold(0u32, |m, p| m | 1 << p))
            .collect();
        return (0u32..1 << group.len())
            .filter(|set| (0..group.len()).all(|k| set & (1 << k) == 0 || set & masks[k] == 0))
            .map(u32::count_ones)
            .max()
            .unwrap_or(0) as usize;
    }
    let mut left: Vec<usize> = group.to_vec();
    let mut count = 0;
    while !left.is_empty() {
        let degree = |x: usize| adjacent[x].iter().filter(|j| left.contains(j)).count();
        let pick = *left.iter().min_by_key(|&&x| (degree(x), x)).expect("left is not empty");
        count += 1;
        left.retain(|&x| x != pick && !adjacent[pick].contains(&x));
    }
    count
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

    #[test]
    fn of_two_inseparable_edges_one_is_recoverable_and_a_chain_keeps_its_ends() {
        let (camera, poses) = strip();
        let seg = |a: [f64; 3], b: [f64; 3]| Seg::new(Vec3::from(a), Vec3::from(b));
        let truth = [
            seg([0.0, 0.2, 1.6], [1.4, 0.2, 1.6]),
            seg([0.0, 0.3, 1.6], [1.4, 0.3, 1.6]),
            seg([6.0, 0.0, 3.0], [7.0, 0.0, 3.0]),
        ];
        let pairs = inseparable(&camera, &poses, &truth, 0.05);
        assert_eq!(pairs, vec![vec![1], vec![0], vec![]]);
        assert_eq!(most_recoverable(&[0, 1, 2], &pairs), 2);
        // A chain a – b – c, where a and c are apart: both ends count.
        let chain = vec![vec![1], vec![0, 2], vec![1]];
        assert_eq!(most_recoverable(&[0, 1, 2], &chain), 2);
        // Only the members count: without b, a and c are free.
        assert_eq!(most_recoverable(&[0, 2], &chain), 2);
    }
}
