//! The repetition of a façade in one image: the displacements between keypoints that look alike (the bay, the
//! storey). A pair of images of repeated bays can be matched one period off as a whole, consistently enough to pass
//! every two-view test; where the true transfer never showed among the pair's hypotheses (its mutual matches are few
//! because two strips see each storey from another height, while a storey off is seen from the same one), shifting
//! a found transfer by these periods is what brings it in.
use std::collections::HashMap;

use crate::descriptors::{distance, FrameFeatures};

/// The two periods of the lattice the first `n` keypoints repeat on, each with both signs: the most frequent
/// displacement from a keypoint to the keypoint most like it (same Laplacian sign, another place), and the most
/// frequent one at least 30° from it (a façade's bays repeat more often than its storeys, and a multiple of the bay
/// would otherwise come second). Each is at least `min_length` long and supported by `min_support` keypoints.
/// Positions `at` are in any planar units (normalised image coordinates here); `bin` is the clustering tolerance in
/// those units.
pub fn repetition_periods(
    features: &FrameFeatures,
    at: &[[f64; 2]],
    n: usize,
    bin: f64,
    min_length: f64,
    min_support: usize,
) -> Vec<[f64; 2]> {
    let modes = displacement_modes(features, at, n, bin, min_length, min_support);
    let Some(&first) = modes.first() else { return Vec::new() };
    let across = |d: &[f64; 2]| {
        let cross = first[0] * d[1] - first[1] * d[0];
        cross.abs() > 0.5 * first[0].hypot(first[1]) * d[0].hypot(d[1])
    };
    let mut periods = vec![first, [-first[0], -first[1]]];
    if let Some(second) = modes.iter().find(|d| across(d)) {
        periods.extend([*second, [-second[0], -second[1]]]);
    }
    periods
}

/// The lattice steps one period away along each period and diagonally: every `i·a + j·b` with `i`, `j` in −1…1
/// but the origin, for the periods `[a, −a, b, −b]` of [`repetition_periods`] (only `±a` without `b`).
pub fn lattice_steps(periods: &[[f64; 2]]) -> Vec<[f64; 2]> {
    let (a, b) = match periods {
        [a, _, b, ..] => (*a, *b),
        [a, ..] => (*a, [0.0; 2]),
        [] => return Vec::new(),
    };
    let js: &[i32] = if periods.len() >= 4 { &[-1, 0, 1] } else { &[0] };
    let mut steps = Vec::new();
    for i in -1..=1 {
        for &j in js {
            if (i, j) != (0, 0) {
                steps.push([i as f64 * a[0] + j as f64 * b[0], i as f64 * a[1] + j as f64 * b[1]]);
            }
        }
    }
    steps
}

/// The displacements between alike keypoints, most frequent first (see [`repetition_periods`]).
fn displacement_modes(features: &FrameFeatures, at: &[[f64; 2]], n: usize, bin: f64, min_length: f64, min_support: usize) -> Vec<[f64; 2]> {
    let n = n.min(features.count()).min(at.len());
    if bin <= 0.0 || n < 2 {
        return Vec::new();
    }
    let mut votes: HashMap<(i64, i64), (usize, [f64; 2])> = HashMap::new();
    for i in 0..n {
        let nearest = (0..n)
            .filter(|&j| j != i && features.signs[j] == features.signs[i])
            .map(|j| (distance(features, i, features, j), j))
            .filter(|(d, _)| d.is_finite())
            .min_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
        let Some((_, j)) = nearest else { continue };
        let d = [at[j][0] - at[i][0], at[j][1] - at[i][1]];
        if d[0].hypot(d[1]) < min_length {
            continue;
        }
        let key = ((d[0] / bin).round() as i64, (d[1] / bin).round() as i64);
        let e = votes.entry(key).or_insert((0, [0.0; 2]));
        e.0 += 1;
        e.1 = [e.1[0] + d[0], e.1[1] + d[1]];
    }
    // Each bin's support with its neighbours' (a period falls across bin borders), the mean displacement of the
    // bin itself; a bin is a mode when no neighbour has more.
    let support = |k: (i64, i64)| -> usize {
        (-1..=1)
            .flat_map(|a| (-1..=1).map(move |b| (k.0 + a, k.1 + b)))
            .filter_map(|q| votes.get(&q).map(|v| v.0))
            .sum()
    };
    let mut modes: Vec<(usize, (i64, i64), [f64; 2])> = votes
        .iter()
        .filter(|(k, v)| {
            let own = support(**k);
            own >= min_support
                && (-1..=1)
                    .flat_map(|a| (-1..=1).map(move |b| (k.0 + a, k.1 + b)))
                    .filter(|q| q != *k)
                    .all(|q| votes.get(&q).is_none_or(|w| (w.0, q) < (v.0, **k)))
        })
        .map(|(k, v)| (support(*k), *k, [v.1[0] / v.0 as f64, v.1[1] / v.0 as f64]))
        .collect();
    // Deterministic: most support first, then the bin.
    modes.sort_by(|a, b| b.0.cmp(&a.0).then(a.1.cmp(&b.1)));
    modes.into_iter().map(|m| m.2).collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::descriptors::Descriptors;

    /// Keypoints on a lattice of bays 40 wide and storeys 30 high, each bay's keypoints alike (the descriptor says
    /// which of five features of the bay it is), plus unique keypoints.
    fn facade() -> (FrameFeatures, Vec<[f64; 2]>) {
        let mut px = Vec::new();
        let mut values = Vec::new();
        for bay in 0..6 {
            for storey in 0..4 {
                for kind in 0..5 {
                    px.push([
                        bay as f64 * 40.0 + kind as f64 * 6.0 + 0.3 * storey as f64,
                        storey as f64 * 30.0 + kind as f64 * 2.0,
                    ]);
                    let mut d = vec![0.0f32; 8];
                    d[kind] = 1.0;
                    // Some features look most like the one a storey away, others like the one a bay away.
                    d[5] = if kind % 2 == 0 { 0.0008 } else { 0.003 } * storey as f32;
                    // Neighbouring bays alike most (perspective changes slowly along a façade).
                    d[6] = 0.001 * bay as f32;
                    values.extend(d);
                }
            }
        }
        let count = px.len();
        let features = FrameFeatures {
            px: px.clone(),
            signs: vec![1; count],
            descriptors: Descriptors::Float { values, len: 8 },
        };
        (features, px)
    }

    #[test]
    fn the_bay_and_the_storey_are_the_periods_of_a_lattice_of_alike_keypoints() {
        let (features, at) = facade();
        let periods = repetition_periods(&features, &at, features.count(), 2.0, 5.0, 4);
        let is = |p: &[f64; 2], x: f64, y: f64| (p[0] - x).abs() < 2.0 && (p[1] - y).abs() < 2.0;
        assert_eq!(periods.len(), 4, "{periods:?}");
        let bay = |p: &[f64; 2]| is(p, 40.0, 0.0) || is(p, -40.0, 0.0);
        let storey = |p: &[f64; 2]| is(p, 0.0, 30.0) || is(p, 0.0, -30.0);
        assert!(
            storey(&periods[0]) && storey(&periods[1]),
            "the storey is the more frequent here: {periods:?}"
        );
        assert!(bay(&periods[2]) && bay(&periods[3]), "{periods:?}");
        // Deterministic.
        assert_eq!(periods, repetition_periods(&features, &at, features.count(), 2.0, 5.0, 4));
        let steps = lattice_steps(&periods);
        assert_eq!(steps.len(), 8);
        assert!(
            steps.iter().any(|s| is(s, 40.0, 30.0)) && steps.iter().any(|s| is(s, -40.0, -30.0)),
            "{steps:?}"
        );
        assert_eq!(lattice_steps(&periods[..2]).len(), 2);
        // Nothing alike, no period.
        let none = repetition_periods(&features, &at, 1, 2.0, 5.0, 4);
        assert!(none.is_empty());
    }
}
