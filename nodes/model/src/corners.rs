//! Construct, part 2: accepted junctions clustered into corners (seed 003 §3.3.3: junctions of one corner are
//! scattered by random error), and lines grouped into objects through their corners (§3.3.2).
use lineflow_photogrammetry::Vec3;

use crate::junction::Junction;

/// A corner before adjustment.
#[derive(Debug, Clone)]
pub struct Corner {
    /// Mean of its junctions.
    pub point: Vec3,
    /// The lines through it, ascending.
    pub lines: Vec<usize>,
}

/// Disjoint sets over `0..n`, smallest member as representative so that results do not depend on merge order.
pub struct DisjointSets(Vec<usize>);

impl DisjointSets {
    pub fn new(n: usize) -> Self {
        DisjointSets((0..n).collect())
    }
    pub fn find(&mut self, mut x: usize) -> usize {
        while self.0[x] != x {
            self.0[x] = self.0[self.0[x]];
            x = self.0[x];
        }
        x
    }
    pub fn union(&mut self, a: usize, b: usize) {
        let (a, b) = (self.find(a), self.find(b));
        let (lo, hi) = (a.min(b), a.max(b));
        self.0[hi] = lo;
    }
}

/// Single-linkage clusters of the accepted junctions: two junctions are one corner when they are closer than
/// `radius_k` times their joint standard deviation.
pub fn cluster(junctions: &[Junction], accepted: &[usize], radius_k: f64) -> Vec<Corner> {
    let mut sets = DisjointSets::new(accepted.len());
    for a in 0..accepted.len() {
        for b in a + 1..accepted.len() {
            let (ja, jb) = (&junctions[accepted[a]], &junctions[accepted[b]]);
            let radius = radius_k * ja.sigma.hypot(jb.sigma);
            if (ja.point - jb.point).norm() < radius {
                sets.union(a, b);
            }
        }
    }
    let mut groups: std::collections::BTreeMap<usize, Vec<usize>> = Default::default();
    for (a, &junction) in accepted.iter().enumerate() {
        groups.entry(sets.find(a)).or_default().push(junction);
    }
    groups
        .into_values()
        .map(|members| {
            let point = members.iter().map(|&k| junctions[k].point).sum::<Vec3>() / members.len() as f64;
            let mut lines: Vec<usize> = members.iter().flat_map(|&k| [junctions[k].i, junctions[k].j]).collect();
            lines.sort_unstable();
            lines.dedup();
            Corner { point, lines }
        })
        .collect()
}

/// Objects: the lines connected through corners. Returns, per line, its object's index (objects numbered by their
/// smallest line, so the numbering does not depend on input order beyond the lines' own order).
pub fn objects(n_lines: usize, corners: &[Corner]) -> Vec<usize> {
    let mut sets = DisjointSets::new(n_lines);
    for c in corners {
        for w in c.lines.windows(2) {
            sets.union(w[0], w[1]);
        }
    }
    let roots: Vec<usize> = (0..n_lines).map(|l| sets.find(l)).collect();
    let mut numbering = std::collections::BTreeMap::new();
    roots
        .iter()
        .map(|r| {
            let next = numbering.len();
            *numbering.entry(*r).or_insert(next)
        })
        .collect()
}
