//! Two line stages' lines of one building as one set.
//!
//! The two designs find different edges (docs/lines3d.md, "Both designs in one set"): linematch's masters, matched
//! in object space against their slaves and the lines of twelve frames, place more of the level edges; linemap's
//! hypotheses from every pair of images, scored by every image, more of the plumb ones. A line of the second set
//! joins the first where the first leaves it uncovered; where a line of the first already lies along it, it is the
//! same edge twice.
use lineflow_photogrammetry::Vec3;

use crate::grid::Grid;

/// When a line of one set covers (part of) a line of the other.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Cover {
    /// Largest angle between the two, degrees.
    pub angle_deg: f64,
    /// Largest distance of the covering line from the covered one's line, over the stretch it covers, metres.
    pub distance_m: f64,
}

/// Cells of the grid the covering lines are found in, metres: large enough that a line meets few cells.
const CELL_M: f64 = 0.5;

/// For each line of `others`, the share of its length that the lines of `own` cover under `rule` (0 for a line
/// of no length).
pub fn covered_shares(own: &[[Vec3; 2]], others: &[[Vec3; 2]], rule: &Cover) -> Vec<f64> {
    uncovered_stretches(own, others, rule)
        .iter()
        .zip(others)
        .map(|(free, x)| match (x[1] - x[0]).norm() > 1e-9 {
            true => 1.0 - free.iter().map(|(s, t)| t - s).sum::<f64>(),
            false => 0.0,
        })
        .collect()
}

/// For each line `x` of `others`, the stretches of it no line of `own` covers under `rule`, as parameters
/// `(s, t)` from 0 at `x[0]` to 1 at `x[1]`, in order (none for a line of no length).
pub fn uncovered_stretches(own: &[[Vec3; 2]], others: &[[Vec3; 2]], rule: &Cover) -> Vec<Vec<(f64, f64)>> {
    let grid = Grid::of(own, CELL_M.max(rule.distance_m));
    let mut seen = vec![usize::MAX; own.len()];
    let mut near = Vec::new();
    let cos = rule.angle_deg.to_radians().cos();
    others
        .iter()
        .enumerate()
        .map(|(q, x)| {
            let d = x[1] - x[0];
            let length = d.norm();
            if length <= 1e-9 {
                return Vec::new();
            }
            let u = d / length;
            near.clear();
            grid.around(x, q, &mut seen, &mut near);
            let mut spans: Vec<(f64, f64)> = near
                .iter()
                .filter_map(|&j| covered_span(&own[j], x, &u, length, cos, rule.distance_m))
                .collect();
            spans.sort_by(|a, b| a.0.total_cmp(&b.0));
            let mut free = Vec::new();
            let mut end = 0.0f64;
            for (s, t) in spans {
                if s > end {
                    free.push((end / length, s / length));
                }
                end = end.max(t);
            }
            if end < length {
                free.push((end / length, 1.0));
            }
            free
        })
        .collect()
}

/// The stretch `[s, t]` (metres from `x[0]` along `u`) of line `x` that line `o` covers: `o` within the angle,
/// and its points over that stretch within `distance_m` of `x`'s line (a straight line, so its ends suffice).
fn covered_span(o: &[Vec3; 2], x: &[Vec3; 2], u: &Vec3, length: f64, cos: f64, distance_m: f64) -> Option<(f64, f64)> {
    let d = o[1] - o[0];
    let along = d.dot(u);
    if along.abs() < cos * d.norm() || along.abs() <= 1e-12 {
        return None;
    }
    let t = |p: &Vec3| (p - x[0]).dot(u);
    let (t0, t1) = (t(&o[0]), t(&o[1]));
    let (s, e) = (t0.min(t1).max(0.0), t0.max(t1).min(length));
    if e <= s {
        return None;
    }
    // The points of `o` whose projections onto x's line fall at s and e.
    let at = |tt: f64| o[0] + d * ((tt - t0) / (t1 - t0));
    let off = |p: Vec3| {
        let w = p - x[0];
        (w - u * w.dot(u)).norm()
    };
    (off(at(s)) <= distance_m && off(at(e)) <= distance_m).then_some((s, e))
}

#[cfg(test)]
mod tests {
    use super::*;

    const RULE: Cover = Cover {
        angle_deg: 2.0,
        distance_m: 0.03,
    };

    fn level(x0: f64, x1: f64, y: f64, z: f64) -> [Vec3; 2] {
        [Vec3::new(x0, y, z), Vec3::new(x1, y, z)]
    }

    #[test]
    fn the_share_counts_each_covered_stretch_once() {
        // Two own lines overlap on [2, 3] over the other's [0, 10]; a third lies 5 cm away and covers nothing.
        let own = [level(1.0, 3.0, 0.0, 0.0), level(2.0, 5.0, 0.01, 0.0), level(0.0, 10.0, 0.05, 0.0)];
        let shares = covered_shares(&own, &[level(0.0, 10.0, 0.0, 0.0)], &RULE);
        assert!((shares[0] - 0.4).abs() < 1e-9, "{shares:?}");
    }

    #[test]
    fn the_uncovered_stretches_are_what_the_covered_ones_leave() {
        let own = [level(1.0, 3.0, 0.0, 0.0), level(2.0, 5.0, 0.01, 0.0), level(8.0, 12.0, 0.0, 0.0)];
        let free = &uncovered_stretches(&own, &[level(0.0, 10.0, 0.0, 0.0)], &RULE)[0];
        let expect = [(0.0, 0.1), (0.5, 0.8)];
        assert_eq!(free.len(), 2, "{free:?}");
        for (f, e) in free.iter().zip(expect) {
            assert!((f.0 - e.0).abs() < 1e-9 && (f.1 - e.1).abs() < 1e-9, "{free:?}");
        }
    }

    #[test]
    fn lines_across_tilted_or_beyond_the_ends_cover_nothing() {
        let across = [Vec3::new(5.0, 0.0, -1.0), Vec3::new(5.0, 0.0, 1.0)];
        let tilted = [Vec3::new(0.0, 0.0, 0.0), Vec3::new(10.0, 0.0, 0.6)];
        let beyond = level(11.0, 20.0, 0.0, 0.0);
        let shares = covered_shares(&[across, tilted, beyond], &[level(0.0, 10.0, 0.0, 0.0)], &RULE);
        assert_eq!(shares, vec![0.0]);
    }

    #[test]
    fn a_line_reversed_or_converging_covers_only_where_it_is_close() {
        // Reversed, 1° off: within 3 cm of the other's line over its first 1.7 m only.
        let tilt = 1f64.to_radians().tan();
        let own = [[Vec3::new(4.0, 4.0 * tilt, 0.0), Vec3::new(0.0, 0.0, 0.0)]];
        let share = covered_shares(&own, &[level(0.0, 10.0, 0.0, 0.0)], &RULE)[0];
        assert!(share == 0.0, "the far end is 7 cm off: {share}");
        let own = [[Vec3::new(1.5, 1.5 * tilt, 0.0), Vec3::new(0.0, 0.0, 0.0)]];
        let share = covered_shares(&own, &[level(0.0, 10.0, 0.0, 0.0)], &RULE)[0];
        assert!((share - 0.15).abs() < 1e-3, "{share}");
    }

    #[test]
    fn degenerate_lines_are_handled() {
        let point = level(1.0, 1.0, 0.0, 0.0);
        assert_eq!(covered_shares(&[point], &[level(0.0, 2.0, 0.0, 0.0), point], &RULE), vec![0.0, 0.0]);
        assert!(covered_shares(&[], &[level(0.0, 2.0, 0.0, 0.0)], &RULE) == vec![0.0]);
    }
}
