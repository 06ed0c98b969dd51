//! Construct, part 1: candidate junctions between pairs of 3-D lines and the seed's acceptance conditions.
//!
//! The seed (003 §3.3.1) reasons in the XY projection because its lines come from 2.5-D roof data. A façade is
//! not 2.5-D: a window's outline on the wall and its recessed frame coincide in the wall's projection. So the
//! junctions are inferred in 3-D: two lines meet where their common perpendicular is short (a gap gate derived
//! from the endpoint precision), and the junction is the midpoint of that perpendicular. The conditions of the
//! seed's three stages (error-free logic, distance checks, topology) are applied to the parameters along the
//! lines exactly as in the plane.
use lineflow_photogrammetry::Vec3;

use crate::{ModelLine, ModelParams};

/// A candidate junction of lines `i` and `j`.
#[derive(Debug, Clone)]
pub struct Junction {
    pub i: usize,
    pub j: usize,
    /// The junction point, metres.
    pub point: Vec3,
    /// Parameters along each line (0 at the start, 1 at the end).
    pub t: [f64; 2],
    /// Standard deviation of the junction point, metres.
    pub sigma: f64,
    /// The end of each line the junction belongs to: the end on its side of the midpoint, if the junction lies
    /// beyond that end or within reach of it. A junction deep inside a line (where another line ends on it) belongs
    /// to no end of it.
    pub ends: [Option<usize>; 2],
}

impl Junction {
    /// The end of line `line` (0 or 1) the junction belongs to, if any.
    pub fn end_of(&self, line: usize) -> Option<usize> {
        if line == self.i {
            self.ends[0]
        } else {
            self.ends[1]
        }
    }
    /// The parameter along line `line`.
    pub fn t_of(&self, line: usize) -> f64 {
        if line == self.i {
            self.t[0]
        } else {
            self.t[1]
        }
    }
    /// The other line.
    pub fn other(&self, line: usize) -> usize {
        if line == self.i {
            self.j
        } else {
            self.i
        }
    }
}

/// Whether a point at parameter `t` lies inside a segment of length `len`, with a tolerance of `tol` metres.
fn interior(t: f64, len: f64, tol: f64) -> bool {
    let slack = tol / len.max(1e-9);
    t >= -slack && t <= 1.0 + slack
}

/// All candidate junctions: pairs that are not parallel (angle gate), nearly meet (gap gate), and whose junction
/// lies within `max_reach_m` of an endpoint of each line (distance gate). Sorted by (i, j).
pub fn candidates(lines: &[ModelLine], params: &ModelParams) -> Vec<Junction> {
    let grid = crate::grid::SegmentGrid::new(lines, params.max_reach_m);
    let mut out = Vec::new();
    for (i, a) in lines.iter().enumerate() {
        for j in grid.near(a, params.max_reach_m) {
            if j <= i {
                continue;
            }
            if let Some(junction) = intersect(i, a, j, &lines[j], params) {
                out.push(junction);
            }
        }
    }
    out
}

/// The same candidates from every pair of lines, as the seed computes them: the reference the grid is checked and
/// timed against.
pub fn candidates_all_pairs(lines: &[ModelLine], params: &ModelParams) -> Vec<Junction> {
    let mut out = Vec::new();
    for i in 0..lines.len() {
        for j in i + 1..lines.len() {
            out.extend(intersect(i, &lines[i], j, &lines[j], params));
        }
    }
    out
}

fn intersect(i: usize, a: &ModelLine, j: usize, b: &ModelLine, params: &ModelParams) -> Option<Junction> {
    let (da, db) = (a.end - a.start, b.end - b.start);
    let (la, lb) = (da.norm(), db.norm());
    let (ua, ub) = (da / la, db / lb);
    let sin = ua.cross(&ub).norm();
    // Seed: σ_α ≈ √2 σ_p / length per line; the gate is 3 σ_α within [5°, 20°] (ENG values of the spec).
    let sigma_angle = (2.0f64.sqrt() * a.sigma_m / la).hypot(2.0f64.sqrt() * b.sigma_m / lb);
    let gate = (3.0 * sigma_angle).clamp(params.min_angle_deg.to_radians(), 20f64.to_radians());
    if sin < gate.sin() {
        return None;
    }
    // Closest points of the two infinite lines.
    let w = a.start - b.start;
    let (bb, d, e) = (ua.dot(&ub), ua.dot(&w), ub.dot(&w));
    let den = 1.0 - bb * bb;
    let sa = (bb * e - d) / den;
    let sb = (e - bb * d) / den;
    let (pa, pb) = (a.start + ua * sa, b.start + ub * sb);
    let gap = (pa - pb).norm();
    let sigma_gap = a.sigma_m.hypot(b.sigma_m);
    if gap > params.gap_k * sigma_gap {
        return None;
    }
    // Distance gate: not far beyond either segment, and near an end of at least one (else it is a crossing).
    let overshoot = |s: f64, l: f64| (-s).max(s - l).max(0.0);
    let to_end = |s: f64, l: f64| s.abs().min((l - s).abs());
    // Intersection of two lines, each known to σ across itself: the point moves by σ / sin(angle).
    let sigma = a.sigma_m.max(b.sigma_m) / sin;
    let (reach_a, reach_b) = (a.reach(b.sigma_m / sin, params), b.reach(a.sigma_m / sin, params));
    if overshoot(sa, la) > reach_a || overshoot(sb, lb) > reach_b {
        return None;
    }
    if to_end(sa, la) > reach_a && to_end(sb, lb) > reach_b {
        return None;
    }
    let end = |s: f64, l: f64, reach: f64| (to_end(s, l) <= reach || overshoot(s, l) > 0.0).then_some(usize::from(s >= l / 2.0));
    Some(Junction {
        i,
        j,
        point: (pa + pb) * 0.5,
        t: [sa / la, sb / lb],
        sigma,
        ends: [end(sa, la, reach_a), end(sb, lb, reach_b)],
    })
}

/// How an end of a line was resolved.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Resolution {
    /// Stage 1: the nearest junction, accepted by conditions 1-3.
    Logic,
    /// Stage 2: the one junction left after the distance checks (conditions 4-8).
    Distance,
    /// Stage 3: the one candidate the topology check left.
    Topology,
    /// No candidate, or several that no stage could separate: the end stays free.
    Free,
}

/// The accepted junctions (indices into `junctions`) and how each line end was resolved.
pub struct Accepted {
    pub junctions: Vec<usize>,
    /// Per line, per end.
    pub ends: Vec<[Resolution; 2]>,
}

/// The seed's three stages for every end of every line.
pub fn accept(lines: &[ModelLine], junctions: &[Junction], params: &ModelParams) -> Accepted {
    // Candidates per (line, end), nearest to that endpoint first.
    let mut at: Vec<[Vec<usize>; 2]> = vec![[Vec::new(), Vec::new()]; lines.len()];
    for (k, jn) in junctions.iter().enumerate() {
        for line in [jn.i, jn.j] {
            if let Some(end) = jn.end_of(line) {
                at[line][end].push(k);
            }
        }
    }
    let endpoint = |line: usize, end: usize| if end == 0 { lines[line].start } else { lines[line].end };
    for (line, ends) in at.iter_mut().enumerate() {
        for (end, list) in ends.iter_mut().enumerate() {
            let p = endpoint(line, end);
            list.sort_by(|&x, &y| {
                (junctions[x].point - p)
                    .norm()
                    .total_cmp(&(junctions[y].point - p).norm())
                    .then(x.cmp(&y))
            });
        }
    }
    let first = |line: usize, end: usize| at[line][end].first().copied();
    let inside = |k: usize, line: usize| {
        let l = &lines[line];
        interior(junctions[k].t_of(line), l.length(), 2.0 * l.sigma_m)
    };
    // Whether junction k is (near) the first intersection of line `s` at its end where k lies.
    let near_first_of = |k: usize, s: usize, tau: f64| {
        junctions[k]
            .end_of(s)
            .and_then(|end| first(s, end))
            .is_some_and(|f| f == k || (junctions[f].point - junctions[k].point).norm() < tau)
    };

    let mut accepted = Vec::new();
    let mut ends = vec![[Resolution::Free; 2]; lines.len()];
    for line in 0..lines.len() {
        for end in 0..2 {
            let list = &at[line][end];
            let Some(&f) = list.first() else { continue };
            let s = junctions[f].other(line);
            // Stage 1 (conditions 1-3): the nearest junction is also S's nearest, or lies inside S (T-junction),
            // or inside both.
            if junctions[f].end_of(s).and_then(|e| first(s, e)) == Some(f) || inside(f, s) {
                accepted.push(f);
                ends[line][end] = Resolution::Logic;
                continue;
            }
            let tau = 2.0 * lines[line].sigma_m.max(junctions[f].sigma);
            let p = endpoint(line, end);
            // Stage 2: junctions in the endpoint interval (conditions 4, 5) and near the first intersection on
            // the extension (conditions 6-8), each confirmed by the other line.
            let kept: Vec<usize> = list
                .iter()
                .copied()
                .filter(|&k| {
                    let jn = &junctions[k];
                    let s = jn.other(line);
                    let in_interval = (jn.point - p).norm() < tau || (jn.point - junctions[f].point).norm() < tau;
                    in_interval && (near_first_of(k, s, tau) || inside(k, s))
                })
                .collect();
            match kept.len() {
                1 => {
                    accepted.push(kept[0]);
                    ends[line][end] = Resolution::Distance;
                }
                0 => {}
                _ => {
                    let survivors = topology(lines, junctions, line, &kept, params);
                    if survivors.len() == 1 {
                        accepted.push(survivors[0]);
                        ends[line][end] = Resolution::Topology;
                    }
                }
            }
        }
    }
    accepted.sort_unstable();
    accepted.dedup();
    Accepted { junctions: accepted, ends }
}

/// Stage 3: a candidate S_k is invalid when another candidate's midpoint lies in the region bounded by the target
/// T and S_k (the same side of S_k as T's midpoint and the same side of T as S_k's midpoint): structure lines meet
/// once and stop. Signs are taken in the plane of T and S_k; lines away from that plane do not vote.
fn topology(lines: &[ModelLine], junctions: &[Junction], target: usize, kept: &[usize], params: &ModelParams) -> Vec<usize> {
    let t = &lines[target];
    kept.iter()
        .copied()
        .filter(|&k| {
            let s = &lines[junctions[k].other(target)];
            let normal = t.direction().cross(&s.direction());
            let n = normal.norm();
            if n < 1e-9 {
                return false;
            }
            let normal = normal / n;
            // In-plane side of point p with respect to line l: sign of ((p − l.start) × dir) · normal.
            let side = |l: &ModelLine, p: Vec3| ((p - l.start).cross(&l.direction())).dot(&normal).signum();
            let template = (side(s, t.midpoint()), side(t, s.midpoint()));
            !kept.iter().any(|&other| {
                if other == k {
                    return false;
                }
                let o = &lines[junctions[other].other(target)];
                let m = o.midpoint();
                let off_plane = (m - t.start).dot(&normal).abs();
                off_plane < params.gap_k * o.sigma_m.hypot(t.sigma_m) && (side(s, m), side(t, m)) == template
            })
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn line(a: [f64; 3], b: [f64; 3]) -> ModelLine {
        ModelLine::new(Vec3::from(a), Vec3::from(b), 0.005)
    }

    #[test]
    fn a_rectangle_resolves_every_end_by_logic() {
        let lines = vec![
            line([0.0, 0.0, 0.0], [2.0, 0.0, 0.0]),
            line([2.0, 0.0, 0.0], [2.0, 0.0, 1.0]),
            line([2.0, 0.0, 1.0], [0.0, 0.0, 1.0]),
            line([0.0, 0.0, 1.0], [0.0, 0.0, 0.0]),
        ];
        let params = ModelParams::default();
        let j = candidates(&lines, &params);
        assert_eq!(j.len(), 4, "parallel sides are not intersected");
        let acc = accept(&lines, &j, &params);
        assert_eq!(acc.junctions.len(), 4);
        assert!(acc.ends.iter().flatten().all(|r| *r == Resolution::Logic));
    }

    #[test]
    fn a_gap_beyond_the_endpoints_noise_is_no_junction_where_that_noise_is_known() {
        // A pane's jamb stopping 4 cm below the transom: within max_reach_m (5 cm), but 5.7 joint σ at 5 mm.
        let jamb = line([0.0, 0.0, 0.0], [0.0, 0.0, 1.0]);
        let transom = line([-0.5, 0.0, 1.04], [0.5, 0.0, 1.04]);
        let params = ModelParams::default();
        assert_eq!(
            candidates(&[jamb.clone(), transom.clone()], &params).len(),
            1,
            "a fitted line keeps the full reach"
        );
        let known = |l: ModelLine| ModelLine {
            sigma_end_m: Some(0.005),
            ..l
        };
        assert!(candidates(&[known(jamb.clone()), known(transom.clone())], &params).is_empty());
        // 1 cm short is within the noise.
        let closer = line([0.0, 0.0, 0.03], [0.0, 0.0, 1.03]);
        assert_eq!(candidates(&[known(closer), known(transom)], &params).len(), 1);
    }

    #[test]
    fn the_grid_finds_exactly_the_junctions_of_all_pairs() {
        // A lattice of horizontal and vertical lines with gaps, long and short, in two planes.
        let mut lines = Vec::new();
        for k in 0..12 {
            let z = k as f64 * 0.37;
            lines.push(line([0.1 * k as f64, 0.0, z], [6.0 - 0.2 * k as f64, 0.0, z]));
            let x = k as f64 * 0.51;
            lines.push(line([x, 0.02 * (k % 3) as f64, -0.1], [x, 0.0, 4.0 - 0.15 * k as f64]));
        }
        let params = ModelParams::default();
        let key = |j: &Vec<Junction>| j.iter().map(|j| (j.i, j.j)).collect::<Vec<_>>();
        let grid = candidates(&lines, &params);
        assert!(!grid.is_empty());
        assert_eq!(key(&grid), key(&candidates_all_pairs(&lines, &params)));
    }

    #[test]
    fn skew_lines_far_apart_do_not_meet() {
        let lines = vec![line([0.0, 0.0, 0.0], [1.0, 0.0, 0.0]), line([1.0, 0.3, -0.5], [1.0, 0.3, 0.5])];
        assert!(candidates(&lines, &ModelParams::default()).is_empty());
    }

    #[test]
    fn a_short_line_ending_on_a_long_one_is_a_t_junction() {
        let lines = vec![line([0.0, 0.0, 0.0], [4.0, 0.0, 0.0]), line([2.0, 0.0, 0.02], [2.0, 0.0, 1.0])];
        let params = ModelParams::default();
        let j = candidates(&lines, &params);
        let acc = accept(&lines, &j, &params);
        assert_eq!(acc.junctions.len(), 1);
        assert_eq!(acc.ends[1][0], Resolution::Logic);
        assert_eq!(
            acc.ends[0],
            [Resolution::Free, Resolution::Free],
            "the long line's own ends stay free"
        );
    }
}
