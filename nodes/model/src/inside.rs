//! Roofs inside roofs (seed 003 §3.4.3, fact B6): a stair tower, penthouse or dormer stands on a larger roof and
//! is reconstructed as its own object. In plan, every edge of such an object, extended outward from both of its
//! ends, runs into edges of the one object around it, and all of its corners lie inside that object's outline.
//! The seed works in plan on roofs alone; a façade model also holds windows and reveals inside the eaves' outline
//! in plan, so here the edges run into must also lie no higher than the object's foot: it stands on what
//! surrounds it. The seed uses the relation to decide whether to keep such objects; here they are kept and
//! flagged.
//!
//! Only objects with a footprint take part: a façade element (a window, a reveal) projects onto its wall's line in
//! plan, where the extension test means nothing.
use lineflow_photogrammetry::Vec3;

use crate::refine::{cross, sub};
use lineflow_photogrammetry::signed_area;

/// An object's footprint must cover at least this much in plan, m².
const MIN_FOOTPRINT_M2: f64 = 0.25;
/// Edges shorter than this in plan (vertical edges) are not extended, metres.
const MIN_PLAN_LENGTH_M: f64 = 0.1;
/// How far above an object's foot an edge it runs into may lie, metres.
const FOOT_TOLERANCE_M: f64 = 0.05;

/// One object flagged inside another: their indices in the list given to [`objects_inside`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Inside {
    pub object: usize,
    pub container: usize,
}

/// Which of `objects` (each its edges as 3-D segments) lie inside another in plan, each with the smallest such
/// container.
pub fn objects_inside(objects: &[Vec<[Vec3; 2]>]) -> Vec<Inside> {
    let plans: Vec<Plan> = objects.iter().map(|edges| Plan::of(edges)).collect();
    let mut found = Vec::new();
    for (r, inner) in plans.iter().enumerate() {
        if inner.area < MIN_FOOTPRINT_M2 {
            continue;
        }
        let container = plans
            .iter()
            .enumerate()
            .filter(|&(q, outer)| q != r && outer.area > inner.area && outer.holds(inner))
            .min_by(|a, b| a.1.area.total_cmp(&b.1.area).then(a.0.cmp(&b.0)));
        if let Some((q, _)) = container {
            found.push(Inside { object: r, container: q });
        }
    }
    found
}

/// An object in plan: its edges long enough to extend (with their heights), its corners, their convex hull and
/// its foot's height.
struct Plan {
    edges: Vec<[Vec3; 2]>,
    corners: Vec<[f64; 2]>,
    hull: Vec<[f64; 2]>,
    area: f64,
    foot: f64,
}

impl Plan {
    fn of(edges: &[[Vec3; 2]]) -> Plan {
        let xy = |p: &Vec3| [p.x, p.y];
        let corners: Vec<[f64; 2]> = edges.iter().flat_map(|e| [xy(&e[0]), xy(&e[1])]).collect();
        let hull = convex_hull(&corners);
        Plan {
            edges: edges
                .iter()
                .filter(|[a, b]| (b.x - a.x).hypot(b.y - a.y) >= MIN_PLAN_LENGTH_M)
                .copied()
                .collect(),
            area: signed_area(&hull).abs(),
            hull,
            corners,
            foot: edges.iter().flatten().map(|p| p.z).fold(f64::INFINITY, f64::min),
        }
    }

    /// Whether `inner` lies inside this object: every extendable edge of it, extended outward from both ends, runs
    /// into one of this object's edges no higher than its foot, and its corners lie strictly inside this object's
    /// hull.
    fn holds(&self, inner: &Plan) -> bool {
        let below = inner.foot + FOOT_TOLERANCE_M;
        !inner.edges.is_empty()
            && inner.corners.iter().all(|&c| strictly_inside(c, &self.hull))
            && inner.edges.iter().all(|&[a, b]| {
                let (a, b) = ([a.x, a.y], [b.x, b.y]);
                self.hit_ahead(a, sub(a, b), below) && self.hit_ahead(b, sub(b, a), below)
            })
    }

    /// Whether the ray from `from` along `dir` crosses one of the edges where that lies no higher than `below`.
    fn hit_ahead(&self, from: [f64; 2], dir: [f64; 2], below: f64) -> bool {
        self.edges.iter().any(|&[p3, q3]| {
            let (p, q) = ([p3.x, p3.y], [q3.x, q3.y]);
            let e = sub(q, p);
            let denom = cross(dir, e);
            if denom.abs() < 1e-12 {
                return false;
            }
            let w = sub(p, from);
            let t = cross(w, e) / denom;
            let s = cross(w, dir) / denom;
            t > 0.0 && (0.0..=1.0).contains(&s) && p3.z + s * (q3.z - p3.z) <= below
        })
    }
}

/// The convex hull, counter-clockwise (Andrew's monotone chain).
fn convex_hull(points: &[[f64; 2]]) -> Vec<[f64; 2]> {
    let mut p = points.to_vec();
    p.sort_by(|a, b| a[0].total_cmp(&b[0]).then(a[1].total_cmp(&b[1])));
    p.dedup();
    if p.len() < 3 {
        return p;
    }
    let turn = |o: [f64; 2], a: [f64; 2], b: [f64; 2]| cross(sub(a, o), sub(b, o));
    let reversed: Vec<[f64; 2]> = p.iter().rev().copied().collect();
    let mut hull: Vec<[f64; 2]> = Vec::new();
    // The lower chain left to right, then the upper one back.
    for ordered in [&p, &reversed] {
        let start = hull.len();
        for &q in ordered {
            while hull.len() >= start + 2 && turn(hull[hull.len() - 2], hull[hull.len() - 1], q) <= 0.0 {
                hull.pop();
            }
            hull.push(q);
        }
        hull.pop();
    }
    hull
}

/// Whether `p` lies inside the counter-clockwise convex `hull`, off its boundary.
fn strictly_inside(p: [f64; 2], hull: &[[f64; 2]]) -> bool {
    hull.len() >= 3
        && (0..hull.len()).all(|k| {
            let (a, b) = (hull[k], hull[(k + 1) % hull.len()]);
            cross(sub(b, a), sub(p, a)) > 1e-9
        })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A box's edges: its outline at z0 and z1 and the four uprights.
    fn block(x: [f64; 2], y: [f64; 2], z: [f64; 2]) -> Vec<[Vec3; 2]> {
        let c = |i: usize, z: f64| Vec3::new(x[usize::from(i == 1 || i == 2)], y[usize::from(i >= 2)], z);
        let mut edges = Vec::new();
        for k in 0..4 {
            edges.push([c(k, z[1]), c((k + 1) % 4, z[1])]);
            edges.push([c(k, z[0]), c((k + 1) % 4, z[0])]);
            edges.push([c(k, z[0]), c(k, z[1])]);
        }
        edges
    }

    #[test]
    fn a_penthouse_on_a_roof_is_inside_it_and_not_the_other_way() {
        let found = objects_inside(&[
            block([0.0, 20.0], [0.0, 12.0], [0.0, 10.0]),
            block([8.0, 11.0], [4.0, 7.0], [10.0, 12.5]),
        ]);
        assert_eq!(found, vec![Inside { object: 1, container: 0 }]);
    }

    #[test]
    fn neighbours_and_a_block_overhanging_the_roof_are_not_inside() {
        let touching = objects_inside(&[
            block([0.0, 10.0], [0.0, 6.0], [0.0, 5.0]),
            block([10.0, 20.0], [0.0, 6.0], [0.0, 8.0]),
        ]);
        assert!(touching.is_empty(), "{touching:?}");
        let overhanging = objects_inside(&[
            block([0.0, 20.0], [0.0, 12.0], [0.0, 10.0]),
            block([18.0, 23.0], [4.0, 7.0], [10.0, 12.5]),
        ]);
        assert!(overhanging.is_empty(), "{overhanging:?}");
    }

    #[test]
    fn a_window_with_its_reveals_under_the_eaves_does_not_stand_on_the_roof() {
        // A window 1.4 m wide with 20 cm reveals in the wall y = 0 of a house whose eaves overhang by 0.5 m: in
        // plan inside the eaves' outline, but everything its edges run into lies above it.
        let mut window = block([2.0, 3.4], [0.0, 0.2], [1.0, 2.7]);
        window.retain(|e| (e[0].z - e[1].z).abs() < 1e-9);
        let eaves = vec![
            [Vec3::new(-0.5, -0.5, 6.0), Vec3::new(10.5, -0.5, 6.0)],
            [Vec3::new(10.5, -0.5, 6.0), Vec3::new(10.5, 10.5, 6.0)],
            [Vec3::new(10.5, 10.5, 6.0), Vec3::new(-0.5, 10.5, 6.0)],
            [Vec3::new(-0.5, 10.5, 6.0), Vec3::new(-0.5, -0.5, 6.0)],
        ];
        assert!(objects_inside(&[eaves, window]).is_empty());
    }

    #[test]
    fn a_window_on_a_facade_has_no_footprint() {
        // A window's edges in the wall y = 0: a line in plan.
        let window = vec![
            [Vec3::new(2.0, 0.0, 1.0), Vec3::new(3.4, 0.0, 1.0)],
            [Vec3::new(2.0, 0.0, 2.7), Vec3::new(3.4, 0.0, 2.7)],
            [Vec3::new(2.0, 0.0, 1.0), Vec3::new(2.0, 0.0, 2.7)],
            [Vec3::new(3.4, 0.0, 1.0), Vec3::new(3.4, 0.0, 2.7)],
        ];
        assert!(objects_inside(&[block([0.0, 20.0], [0.0, 12.0], [0.0, 10.0]), window]).is_empty());
    }
}
