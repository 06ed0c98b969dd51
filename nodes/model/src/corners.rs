//! Construct, part 2: accepted junctions clustered into corners (seed 003 §3.3.3: junctions of one corner are
//! scattered by random error), and lines grouped into objects through their corners (§3.3.2).
use lineflow_photogrammetry::Vec3;

use crate::disjoint::Disjoint;
use crate::junction::Junction;
use crate::ModelLine;

/// A corner before adjustment.
#[derive(Debug, Clone)]
pub struct Corner {
    /// Mean of its junctions.
    pub point: Vec3,
    /// The lines through it, ascending.
    pub lines: Vec<usize>,
    /// The line ends it holds, (line, end), ascending; a line it holds deep inside (a T) has none.
    pub ends: Vec<(usize, usize)>,
}

/// Single-linkage clusters of the accepted junctions: two junctions are one corner when they are closer than
/// `radius_k` times their joint standard deviation, unless that would put into one corner both ends of one line
/// (a reveal a few σ deep has its two ends at two corners, however close) or the ends of two parallel lines
/// leaving it the same way (a frame's edge and the glazing's a few centimetres behind it each end at their own
/// corner; angles below `min_angle_deg` count as parallel). Pairs are merged nearest first, so which of two
/// conflicting merges wins does not depend on the junctions' order.
pub fn cluster(junctions: &[Junction], accepted: &[usize], lines: &[ModelLine], radius_k: f64, min_angle_deg: f64) -> Vec<Corner> {
    let cos_parallel = min_angle_deg.to_radians().cos();
    let inward = |(l, e): (usize, usize)| if e == 0 { lines[l].direction() } else { -lines[l].direction() };
    let conflict = |a: &[(usize, usize)], b: &[(usize, usize)]| {
        a.iter().any(|&x| {
            b.iter().any(|&y| {
                if x.0 == y.0 {
                    x.1 != y.1
                } else {
                    inward(x).dot(&inward(y)) > cos_parallel
                }
            })
        })
    };
    let mut pairs = Vec::new();
    for a in 0..accepted.len() {
        for b in a + 1..accepted.len() {
            let (ja, jb) = (&junctions[accepted[a]], &junctions[accepted[b]]);
            let radius = radius_k * ja.sigma.hypot(jb.sigma);
            let d = (ja.point - jb.point).norm();
            if d < radius {
                pairs.push((d / radius, a, b));
            }
        }
    }
    pairs.sort_by(|x, y| x.0.total_cmp(&y.0).then(x.1.cmp(&y.1)).then(x.2.cmp(&y.2)));
    // The line ends each cluster holds, by its representative.
    let mut ends: Vec<Vec<(usize, usize)>> = accepted
        .iter()
        .map(|&k| {
            let j = &junctions[k];
            [(j.i, j.ends[0]), (j.j, j.ends[1])]
                .into_iter()
                .filter_map(|(l, e)| e.map(|e| (l, e)))
                .collect()
        })
        .collect();
    let mut sets = Disjoint::new(accepted.len());
    for (_, a, b) in pairs {
        let (ra, rb) = (sets.root(a), sets.root(b));
        if ra == rb || conflict(&ends[ra], &ends[rb]) {
            continue;
        }
        sets.join(ra, rb);
        let (keep, gone) = (ra.min(rb), ra.max(rb));
        let moved = std::mem::take(&mut ends[gone]);
        for end in moved {
            if !ends[keep].contains(&end) {
                ends[keep].push(end);
            }
        }
    }
    let mut groups: std::collections::BTreeMap<usize, Vec<usize>> = Default::default();
    for (a, &junction) in accepted.iter().enumerate() {
        groups.entry(sets.root(a)).or_default().push(junction);
    }
    let mut corners: Vec<Corner> = groups
        .into_iter()
        .map(|(rep, members)| {
            let point = members.iter().map(|&k| junctions[k].point).sum::<Vec3>() / members.len() as f64;
            let mut lines: Vec<usize> = members.iter().flat_map(|&k| [junctions[k].i, junctions[k].j]).collect();
            lines.sort_unstable();
            lines.dedup();
            let mut ends = std::mem::take(&mut ends[rep]);
            ends.sort_unstable();
            Corner { point, lines, ends }
        })
        .collect();
    one_corner_per_end(&mut corners, lines, cos_parallel);
    corners
}

/// A line end held by two corners (each too far from the other, or in conflict with it, to be one) stays with the
/// nearer and leaves the other: a line has one corner at each end, and one end tied to two corners binds them in
/// Shape. A corner left without two lines at an angle is dropped.
fn one_corner_per_end(corners: &mut Vec<Corner>, lines: &[ModelLine], cos_parallel: f64) {
    let endpoint = |(l, e): (usize, usize)| if e == 0 { lines[l].start } else { lines[l].end };
    let mut holders: std::collections::BTreeMap<(usize, usize), Vec<usize>> = Default::default();
    for (c, corner) in corners.iter().enumerate() {
        for &end in &corner.ends {
            holders.entry(end).or_default().push(c);
        }
    }
    for (end, cs) in holders.into_iter().filter(|(_, cs)| cs.len() > 1) {
        let distance = |c: usize| (corners[c].point - endpoint(end)).norm();
        let nearest = cs
            .iter()
            .copied()
            .min_by(|&a, &b| distance(a).total_cmp(&distance(b)))
            .unwrap_or(cs[0]);
        for c in cs.into_iter().filter(|&c| c != nearest) {
            let corner = &mut corners[c];
            corner.ends.retain(|&x| x != end);
            // The corner lets go of the line altogether: it cannot hold one end of it and, beside it, the line's
            // inside as a T.
            corner.lines.retain(|&l| l != end.0);
        }
    }
    corners.retain(|corner| {
        corner.lines.iter().enumerate().any(|(k, &a)| {
            corner.lines[k + 1..]
                .iter()
                .any(|&b| lines[a].direction().dot(&lines[b].direction()).abs() < cos_parallel)
        })
    });
}

/// Objects: the lines connected through corners. Returns, per line, its object's index (objects numbered by their
/// smallest line, so the numbering does not depend on input order beyond the lines' own order).
pub fn objects(n_lines: usize, corners: &[Corner]) -> Vec<usize> {
    let mut sets = Disjoint::new(n_lines);
    for c in corners {
        for w in c.lines.windows(2) {
            sets.join(w[0], w[1]);
        }
    }
    let roots: Vec<usize> = (0..n_lines).map(|l| sets.root(l)).collect();
    let mut numbering = std::collections::BTreeMap::new();
    roots
        .iter()
        .map(|r| {
            let next = numbering.len();
            *numbering.entry(*r).or_insert(next)
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn line(a: [f64; 3], b: [f64; 3]) -> ModelLine {
        ModelLine::new(Vec3::from(a), Vec3::from(b), 0.01)
    }

    fn junction(i: usize, j: usize, point: [f64; 3], ends: [Option<usize>; 2]) -> Junction {
        Junction {
            i,
            j,
            point: Vec3::from(point),
            t: [0.0, 0.0],
            sigma: 0.01,
            ends,
        }
    }

    #[test]
    fn a_reveal_shallower_than_the_cluster_radius_keeps_its_two_corners() {
        // Line 0 is a 4 cm reveal from the frame (line 1) back to the glazing (line 2); 3 σ of the pair is 4.2 cm.
        let junctions = [
            junction(0, 1, [0.0, 0.0, 0.0], [Some(0), Some(1)]),
            junction(0, 2, [0.0, 0.04, 0.0], [Some(1), Some(1)]),
        ];
        let lines = [
            line([0.0, 0.0, 0.0], [0.0, 0.04, 0.0]),
            line([-1.0, 0.0, 0.0], [0.0, 0.0, 0.0]),
            line([-1.0, 0.04, 0.0], [0.0, 0.04, 0.0]),
        ];
        let corners = cluster(&junctions, &[0, 1], &lines, 3.0, 5.0);
        assert_eq!(corners.len(), 2);
        assert_eq!((corners[0].lines.clone(), corners[1].lines.clone()), (vec![0, 1], vec![0, 2]));
    }

    #[test]
    fn junctions_of_one_corner_merge_and_the_nearest_pair_wins_a_conflict() {
        // Lines 1 and 3 both end where line 0 starts (1 cm apart); line 2 ends at line 0's other end, 3 cm away:
        // close enough for single linkage to chain all three, but it would hold both ends of line 0.
        let junctions = [
            junction(0, 1, [0.0, 0.0, 0.0], [Some(0), Some(1)]),
            junction(0, 2, [0.0, 0.03, 0.0], [Some(1), Some(1)]),
            junction(0, 3, [0.0, 0.01, 0.0], [Some(0), Some(0)]),
        ];
        let lines = [
            line([0.0, 0.0, 0.0], [0.0, 0.03, 0.0]),
            line([-1.0, 0.0, 0.0], [0.0, 0.0, 0.0]),
            line([0.0, 0.03, 1.0], [0.0, 0.03, 0.0]),
            line([0.0, 0.01, 0.0], [0.0, 0.01, 1.0]),
        ];
        let corners = cluster(&junctions, &[0, 1, 2], &lines, 3.0, 5.0);
        let lines: Vec<Vec<usize>> = corners.iter().map(|c| c.lines.clone()).collect();
        assert_eq!(lines, vec![vec![0, 1, 3], vec![0, 2]]);
    }

    #[test]
    fn parallel_lines_leaving_the_same_way_are_not_one_corner_and_an_end_keeps_the_nearer() {
        // A frame's sill (line 0) and the glazing's 3 cm behind it (line 1) both reach the jamb's end (line 2): the
        // glazing's junction is within reach of the frame's corner but not the same corner, and the jamb's end
        // stays with the corner it lies at, which leaves the glazing's end free.
        let lines = [
            line([-1.0, 0.0, 0.0], [0.0, 0.0, 0.0]),
            line([-1.0, 0.03, 0.0], [0.0, 0.03, 0.0]),
            line([0.0, 0.0, 0.0], [0.0, 0.0, 1.0]),
        ];
        let junctions = [
            junction(0, 2, [0.0, 0.0, 0.0], [Some(1), Some(0)]),
            junction(1, 2, [0.0, 0.015, 0.0], [Some(1), Some(0)]),
        ];
        let corners = cluster(&junctions, &[0, 1], &lines, 3.0, 5.0);
        assert_eq!(corners.len(), 1);
        assert_eq!(
            (corners[0].lines.clone(), corners[0].ends.clone()),
            (vec![0, 2], vec![(0, 1), (2, 0)])
        );
    }
}
