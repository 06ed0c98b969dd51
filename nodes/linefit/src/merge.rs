//! Fragments of one 3-D edge, seen from different masters (or traced as pieces in one), merged into one segment.
use std::collections::HashMap;

use lineflow_linegeom::Sight;
use lineflow_photogrammetry::Vec3;

use crate::fit::principal_axis;

/// A fitted line of one master's segment.
#[derive(Debug, Clone, PartialEq)]
pub struct Fragment {
    /// Master frame.
    pub master: u64,
    /// Segment id in the master.
    pub segment: u32,
    /// Endpoints.
    pub start: Vec3,
    /// Second endpoint.
    pub end: Vec3,
    /// The inlier points.
    pub points: Vec<Vec3>,
    /// Images that took part in matching it.
    pub n_views: u32,
    /// RMS of its inliers, metres.
    pub rms_m: f64,
}

/// A merged 3-D segment.
#[derive(Debug, Clone, PartialEq)]
pub struct Merged {
    /// First endpoint.
    pub start: Vec3,
    /// Second endpoint.
    pub end: Vec3,
    /// Supporting points.
    pub n_points: u32,
    /// Images: the larger of the distinct masters and the views of its best-supported fragment.
    pub n_images: u32,
    /// RMS distance of all supporting points from the merged line, metres.
    pub rms_m: f64,
    /// The fragments, as (master, segment).
    pub fragments: Vec<(u64, u32)>,
}

impl Merged {
    /// A line read back from `lines3d.csv` (no fragments).
    pub fn from_row(r: &lineflow_formats::Line3Row) -> Self {
        Merged {
            start: r.start,
            end: r.end,
            n_points: r.n_points.unwrap_or(0),
            n_images: r.n_images.unwrap_or(0),
            rms_m: r.rms_m.unwrap_or(0.0),
            fragments: Vec::new(),
        }
    }
}

/// When two fragments are one edge.
#[derive(Debug, Clone, Copy)]
pub struct MergeRule {
    /// Largest angle, degrees.
    pub angle_deg: f64,
    /// Largest distance of either fragment's endpoints from the other's line, metres.
    pub distance_m: f64,
    /// Largest gap between them along the line, metres.
    pub gap_m: f64,
    /// With the images' poses: largest distance across the line, pixels, between the two fragments in any image
    /// whose frame holds them; 0 leaves it to `distance_m`. Two edges a few millimetres apart (a window's sill
    /// and the mortar joint below it) are apart in every image, while one edge's fragments at slightly different
    /// depths are not.
    pub max_apart_px: f64,
}

fn line_distance(p: &Vec3, a: &Vec3, dir: &Vec3) -> f64 {
    let v = p - a;
    (v - dir * v.dot(dir)).norm()
}

/// The distance, pixels, across the line between `p` and `q` (points of two near-parallel fragments beside each
/// other, along direction `dir`) in the image of `pose`, or `None` where the image does not hold `p`.
fn apart_in_image(sight: &Sight<'_>, pose: &lineflow_photogrammetry::Pose, p: &Vec3, q: &Vec3, dir: &Vec3) -> Option<f64> {
    let cam = sight.camera;
    if !pose.project(cam, p).is_some_and(|px| cam.contains(px, 0.0)) {
        return None;
    }
    let a = pose.project_ideal(cam, p)?;
    let b = pose.project_ideal(cam, q)?;
    let c = pose.project_ideal(cam, &(p + dir * 0.1))?;
    let (tx, ty) = (c[0] - a[0], c[1] - a[1]);
    let n = tx.hypot(ty);
    if n < 1e-12 {
        return None;
    }
    Some(((b[0] - a[0]) * ty - (b[1] - a[1]) * tx).abs() / n / cam.pixel_size_mm)
}

/// Whether `f` and `g` (overlapping over `[lo, hi]` along `f`'s direction, or the nearest ends where they leave
/// a gap) stay within `limit` pixels of each other in every image that holds them.
fn together_in_images(sight: &Sight<'_>, f: &Fragment, g: &Fragment, lo: f64, hi: f64, limit: f64) -> bool {
    let (df, dg) = ((f.end - f.start).normalize(), (g.end - g.start).normalize());
    [lo, hi].iter().all(|&t| {
        let p = f.start + df * t;
        let q = g.start + dg * (p - g.start).dot(&dg);
        sight
            .poses
            .iter()
            .all(|pose| apart_in_image(sight, pose, &p, &q, &df).is_none_or(|d| d <= limit))
    })
}

/// Whether two fragments belong to one edge under `rule` (and, with `sight`, the images).
fn same_edge(f: &Fragment, g: &Fragment, rule: &MergeRule, sight: Option<&Sight<'_>>) -> bool {
    let (df, dg) = ((f.end - f.start).normalize(), (g.end - g.start).normalize());
    if df.dot(&dg).abs() < rule.angle_deg.to_radians().cos() {
        return false;
    }
    let close = |a: &Fragment, b: &Fragment, db: &Vec3| {
        line_distance(&a.start, &b.start, db) <= rule.distance_m && line_distance(&a.end, &b.start, db) <= rule.distance_m
    };
    if !(close(f, g, &dg) && close(g, f, &df)) {
        return false;
    }
    // Intervals along f's direction: overlapping or within the gap.
    let t = |p: &Vec3| (p - f.start).dot(&df);
    let (g0, g1) = (t(&g.start).min(t(&g.end)), t(&g.start).max(t(&g.end)));
    let (f0, f1) = (0.0, t(&f.end));
    if !(g0 <= f1 + rule.gap_m && f0 <= g1 + rule.gap_m) {
        return false;
    }
    match sight {
        Some(sight) if rule.max_apart_px > 0.0 => {
            // g0 ≤ g1, so the interval held to f stays ordered: the overlap, or the nearest ends across a gap
            // (max/min rather than clamp, which panics on a degenerate fragment's NaN).
            let (lo, hi) = (g0.max(f0).min(f1), g1.max(f0).min(f1));
            together_in_images(sight, f, g, lo, hi, rule.max_apart_px)
        }
        _ => true,
    }
}

fn find(parent: &mut [usize], mut i: usize) -> usize {
    while parent[i] != i {
        parent[i] = parent[parent[i]];
        i = parent[i];
    }
    i
}

/// Merges fragments that are one edge (transitively), each group refitted by its principal axis over all its
/// points, endpoints at the extreme projections. Output in the order of each group's first fragment. With `sight`
/// (the camera and the images' poses) and `rule.max_apart_px`, fragments the images show apart stay apart.
pub fn merge(fragments: &[Fragment], rule: &MergeRule, sight: Option<&Sight<'_>>) -> Vec<Merged> {
    let n = fragments.len();
    let mut parent: Vec<usize> = (0..n).collect();
    // Candidate pairs share a cell of a coarse grid over samples along each fragment.
    let cell = (rule.distance_m + rule.gap_m).max(0.25);
    let key = |p: &Vec3| {
        [
            (p.x / cell).floor() as i64,
            (p.y / cell).floor() as i64,
            (p.z / cell).floor() as i64,
        ]
    };
    let mut grid: HashMap<[i64; 3], Vec<usize>> = HashMap::new();
    for (i, f) in fragments.iter().enumerate() {
        let steps = ((f.end - f.start).norm() / cell).ceil() as usize + 1;
        let mut keys: Vec<[i64; 3]> = (0..=steps)
            .map(|k| key(&(f.start + (f.end - f.start) * (k as f64 / steps as f64))))
            .collect();
        keys.sort_unstable();
        keys.dedup();
        for k in keys {
            grid.entry(k).or_default().push(i);
        }
    }
    let mut cells: Vec<(&[i64; 3], &Vec<usize>)> = grid.iter().collect();
    cells.sort_unstable_by_key(|(k, _)| **k);
    for (k, members) in cells {
        let mut near: Vec<usize> = Vec::new();
        for dx in -1..=1 {
            for dy in -1..=1 {
                for dz in -1..=1 {
                    if let Some(m) = grid.get(&[k[0] + dx, k[1] + dy, k[2] + dz]) {
                        near.extend(m);
                    }
                }
            }
        }
        near.sort_unstable();
        near.dedup();
        for &i in members {
            for &j in near.iter().filter(|&&j| j > i) {
                let (ri, rj) = (find(&mut parent, i), find(&mut parent, j));
                if ri != rj && same_edge(&fragments[i], &fragments[j], rule, sight) {
                    parent[ri.max(rj)] = ri.min(rj);
                }
            }
        }
    }
    let mut groups: Vec<Vec<usize>> = Vec::new();
    let mut index: HashMap<usize, usize> = HashMap::new();
    for i in 0..n {
        let r = find(&mut parent, i);
        let g = *index.entry(r).or_insert_with(|| {
            groups.push(Vec::new());
            groups.len() - 1
        });
        groups[g].push(i);
    }
    groups.iter().filter_map(|g| merged(fragments, g)).collect()
}

fn merged(fragments: &[Fragment], group: &[usize]) -> Option<Merged> {
    let points: Vec<Vec3> = group.iter().flat_map(|&i| fragments[i].points.iter().copied()).collect();
    let (origin, mut dir) = principal_axis(&points)?;
    let first = &fragments[group[0]];
    if dir.dot(&(first.end - first.start)) < 0.0 {
        dir = -dir;
    }
    let (lo, hi) = points
        .iter()
        .map(|p| (p - origin).dot(&dir))
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(l, h), t| (l.min(t), h.max(t)));
    let rms = (points.iter().map(|p| line_distance(p, &origin, &dir).powi(2)).sum::<f64>() / points.len() as f64).sqrt();
    let mut masters: Vec<u64> = group.iter().map(|&i| fragments[i].master).collect();
    masters.sort_unstable();
    masters.dedup();
    let best_views = group.iter().map(|&i| fragments[i].n_views).max().unwrap_or(0);
    Some(Merged {
        start: origin + dir * lo,
        end: origin + dir * hi,
        n_points: points.len() as u32,
        n_images: best_views.max(masters.len() as u32),
        rms_m: rms,
        fragments: group.iter().map(|&i| (fragments[i].master, fragments[i].segment)).collect(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn fragment(master: u64, a: [f64; 3], b: [f64; 3]) -> Fragment {
        let (a, b) = (Vec3::from(a), Vec3::from(b));
        Fragment {
            master,
            segment: 0,
            start: a,
            end: b,
            points: (0..=10).map(|k| a + (b - a) * (k as f64 / 10.0)).collect(),
            n_views: 5,
            rms_m: 0.0,
        }
    }

    fn rule(distance_m: f64, max_apart_px: f64) -> MergeRule {
        MergeRule {
            angle_deg: 2.0,
            distance_m,
            gap_m: 0.05,
            max_apart_px,
        }
    }

    #[test]
    fn overlapping_collinear_fragments_merge_and_others_stay() {
        let rule = rule(0.02, 0.0);
        let frags = [
            fragment(1, [0.0, 0.0, 1.0], [1.0, 0.0, 1.0]),
            fragment(2, [0.8, 0.005, 1.0], [2.0, 0.005, 1.0]),
            // A gap of 3 cm: still the same edge.
            fragment(3, [2.03, 0.0, 1.0], [2.5, 0.0, 1.0]),
            // Parallel, 10 cm above: another edge.
            fragment(4, [0.0, 0.0, 1.1], [1.0, 0.0, 1.1]),
            // Crossing at right angles: another edge.
            fragment(5, [0.5, 0.0, 0.5], [0.5, 0.0, 1.5]),
        ];
        let merged = merge(&frags, &rule, None);
        assert_eq!(merged.len(), 3);
        assert_eq!(merged[0].fragments, vec![(1, 0), (2, 0), (3, 0)]);
        assert!((merged[0].start - Vec3::new(0.0, 0.0, 1.0)).norm() < 0.01);
        assert!((merged[0].end - Vec3::new(2.5, 0.0, 1.0)).norm() < 0.01);
        assert_eq!(merged[0].n_points, 33);
        assert_eq!(merged[0].n_images, 5);
    }

    /// Two strips of stations 25 m in front of the wall Y = 0 (ω = 90°: looking along +Y), at 1.5 and 4.5 m.
    fn strips() -> (lineflow_photogrammetry::Camera, Vec<lineflow_photogrammetry::Pose>) {
        let camera = lineflow_photogrammetry::Camera::pinhole(4912, 3264, 0.0048, 18.0);
        let rotation = lineflow_photogrammetry::rotation_from_opk(90f64.to_radians(), 0.0, 0.0);
        let poses = [1.5, 4.5]
            .iter()
            .flat_map(|&z| (0..5).map(move |k| Vec3::new(2.0 * k as f64, -25.0, z)))
            .map(|center| lineflow_photogrammetry::Pose { center, rotation })
            .collect();
        (camera, poses)
    }

    #[test]
    fn fragments_the_images_show_apart_stay_apart_and_one_edge_at_two_depths_merges() {
        let (camera, poses) = strips();
        let sight = Sight {
            camera: &camera,
            poses: &poses,
        };
        let rule = rule(0.03, 1.5);
        // A sill 1.4 cm below a mortar joint that continues it: 2 px apart in every image (7 mm a pixel).
        let apart = [
            fragment(1, [3.8, 0.0, 4.9], [5.2, 0.0, 4.9]),
            fragment(2, [5.2, 0.0, 4.886], [6.8, 0.0, 4.886]),
        ];
        assert_eq!(merge(&apart, &rule, None).len(), 1, "the distance alone merges them");
        assert_eq!(merge(&apart, &rule, Some(&sight)).len(), 2);
        // One level edge matched 2 cm apart in depth: along the strips' epipolar lines, under a pixel apart.
        let depths = [
            fragment(1, [3.8, 0.0, 4.9], [5.2, 0.0, 4.9]),
            fragment(2, [4.5, 0.02, 4.9], [6.0, 0.02, 4.9]),
        ];
        assert_eq!(merge(&depths, &rule, Some(&sight)).len(), 1);
    }
}
