//! Descriptor matching: nearest neighbours with the ratio test, the sign-of-Laplacian check and mutual consistency
//! (seed 000 §2.4, matching).
use rayon::prelude::*;

/// The features of one image as the matcher needs them.
#[derive(Debug, Clone, Default)]
pub struct FrameFeatures {
    /// Keypoint positions, measured pixels.
    pub px: Vec<[f64; 2]>,
    /// Sign of the Laplacian per keypoint (0 where the detector has none).
    pub signs: Vec<i32>,
    /// One descriptor per keypoint.
    pub descriptors: Descriptors,
}

/// The descriptors of one image's keypoints, of the kind the detector makes.
#[derive(Debug, Clone)]
pub enum Descriptors {
    /// Unit float descriptors (SURF), `len` values each, compared by Euclidean distance.
    Float {
        /// `len` values per keypoint.
        values: Vec<f32>,
        /// Values per descriptor.
        len: usize,
    },
    /// Binary descriptors (ORB), `len` bytes each, compared by Hamming distance.
    Binary {
        /// `len` bytes per keypoint.
        bytes: Vec<u8>,
        /// Bytes per descriptor.
        len: usize,
    },
}

impl Default for Descriptors {
    fn default() -> Self {
        Descriptors::Float {
            values: Vec::new(),
            len: 0,
        }
    }
}

impl Descriptors {
    /// Whether descriptors of `self` and `other` can be compared: the same kind and length.
    fn comparable(&self, other: &Descriptors) -> bool {
        match (self, other) {
            (Descriptors::Float { len: a, .. }, Descriptors::Float { len: b, .. }) => a == b,
            (Descriptors::Binary { len: a, .. }, Descriptors::Binary { len: b, .. }) => a == b,
            _ => false,
        }
    }

    /// The first `n` descriptors.
    fn first(&self, n: usize) -> Descriptors {
        match self {
            Descriptors::Float { values, len } => Descriptors::Float {
                values: values[..n * len].to_vec(),
                len: *len,
            },
            Descriptors::Binary { bytes, len } => Descriptors::Binary {
                bytes: bytes[..n * len].to_vec(),
                len: *len,
            },
        }
    }
}

impl FrameFeatures {
    /// Number of keypoints.
    pub fn count(&self) -> usize {
        self.px.len()
    }

    /// The first `n` keypoints (the strongest, as the features stage orders them).
    pub fn strongest(&self, n: usize) -> FrameFeatures {
        let n = n.min(self.count());
        FrameFeatures {
            px: self.px[..n].to_vec(),
            signs: self.signs[..n].to_vec(),
            descriptors: self.descriptors.first(n),
        }
    }
}

/// Squared Euclidean distance of two float descriptors, in eight lanes so that the compiler can use SIMD (a single
/// running sum is a chain of dependent additions).
#[inline]
fn float_distance(x: &[f32], y: &[f32]) -> f32 {
    let mut lanes = [0f32; 8];
    let (xc, yc) = (x.chunks_exact(8), y.chunks_exact(8));
    let tail: f32 = xc.remainder().iter().zip(yc.remainder()).map(|(p, q)| (p - q) * (p - q)).sum();
    for (cx, cy) in xc.zip(yc) {
        for k in 0..8 {
            let d = cx[k] - cy[k];
            lanes[k] += d * d;
        }
    }
    lanes.iter().sum::<f32>() + tail
}

/// A binary descriptor of `L` bits counts as the unit vector of ±1/√L per bit, so that a Hamming distance `H` is
/// the squared distance `4H / L`.
#[inline]
fn binary_distance(x: &[u8], y: &[u8]) -> f32 {
    let hamming: u32 = x.iter().zip(y).map(|(p, q)| (p ^ q).count_ones()).sum();
    4.0 * hamming as f32 / (8 * x.len()).max(1) as f32
}

/// Squared descriptor distance between keypoint `i` of `a` and keypoint `j` of `b` (comparable kinds): unrelated
/// descriptors lie near 2 (orthogonal unit vectors) for both kinds, and the ratio and distance thresholds mean the
/// same for SURF and ORB.
fn squared_distance(a: &FrameFeatures, i: usize, b: &FrameFeatures, j: usize) -> f32 {
    match (&a.descriptors, &b.descriptors) {
        (Descriptors::Float { values: x, len }, Descriptors::Float { values: y, .. }) => {
            float_distance(&x[i * len..(i + 1) * len], &y[j * len..(j + 1) * len])
        }
        (Descriptors::Binary { bytes: x, len }, Descriptors::Binary { bytes: y, .. }) => {
            binary_distance(&x[i * len..(i + 1) * len], &y[j * len..(j + 1) * len])
        }
        _ => f32::INFINITY,
    }
}

/// Descriptor distance between keypoint `i` of `a` and keypoint `j` of `b`.
pub fn distance(a: &FrameFeatures, i: usize, b: &FrameFeatures, j: usize) -> f32 {
    squared_distance(a, i, b, j).sqrt()
}

/// The nearest and second-nearest candidate of one keypoint: the smallest squared distance (ties to the lower
/// index), its index, and the second smallest distance (equal to the smallest when two candidates tie).
#[derive(Debug, Clone, Copy)]
struct Nearest {
    best: f32,
    second: f32,
    at: usize,
}

impl Nearest {
    const NONE: Nearest = Nearest {
        best: f32::INFINITY,
        second: f32::INFINITY,
        at: usize::MAX,
    };

    #[inline]
    fn offer(&mut self, d: f32, j: usize) {
        if d < self.best || (d == self.best && j < self.at) {
            self.second = self.best;
            self.best = d;
            self.at = j;
        } else if d < self.second {
            self.second = d;
        }
    }

    /// The nearest over the union of two candidate sets; the order of merging does not change the result.
    fn merge(self, other: Nearest) -> Nearest {
        let (lo, hi) = if (self.best, self.at) <= (other.best, other.at) {
            (self, other)
        } else {
            (other, self)
        };
        Nearest {
            second: lo.second.min(hi.best),
            ..lo
        }
    }

    /// The match, when there was a second candidate and the best is clearly closer (squared ratio `r2`).
    fn passes_ratio(&self, r2: f32) -> Option<usize> {
        (self.second.is_finite() && self.best < r2 * self.second).then_some(self.at)
    }
}

/// Rows of `a` per parallel task of [`nearest_both_ways`].
const ROWS_PER_TASK: usize = 128;

/// For every keypoint of `a` its nearest candidates in `b`, and for every keypoint of `b` its nearest in `a`, from
/// one pass over the distance matrix; only keypoints with the same Laplacian sign are compared.
fn nearest_both_ways(a: &FrameFeatures, b: &FrameFeatures, distance: impl Fn(usize, usize) -> f32 + Sync) -> (Vec<Nearest>, Vec<Nearest>) {
    let mut by_sign: Vec<(i32, Vec<usize>)> = Vec::new();
    for (j, &s) in b.signs.iter().enumerate() {
        match by_sign.iter_mut().find(|(t, _)| *t == s) {
            Some((_, v)) => v.push(j),
            None => by_sign.push((s, vec![j])),
        }
    }
    let rows: Vec<usize> = (0..a.count()).collect();
    let tasks: Vec<(Vec<Nearest>, Vec<Nearest>)> = rows
        .par_chunks(ROWS_PER_TASK)
        .map(|chunk| {
            let mut columns = vec![Nearest::NONE; b.count()];
            let rows = chunk
                .iter()
                .map(|&i| {
                    let mut row = Nearest::NONE;
                    let same_sign = by_sign.iter().find(|(s, _)| *s == a.signs[i]).map_or(&[][..], |(_, v)| v);
                    for &j in same_sign {
                        let d = distance(i, j);
                        row.offer(d, j);
                        columns[j].offer(d, i);
                    }
                    row
                })
                .collect();
            (rows, columns)
        })
        .collect();
    let mut of_a = Vec::with_capacity(a.count());
    let mut of_b = vec![Nearest::NONE; b.count()];
    for (rows, columns) in tasks {
        of_a.extend(rows);
        for (acc, c) in of_b.iter_mut().zip(columns) {
            *acc = acc.merge(c);
        }
    }
    (of_a, of_b)
}

/// Matches `a` to `b`: ratio test both ways and mutual consistency. Pairs of indices, ordered by `a`'s index.
pub fn match_features(a: &FrameFeatures, b: &FrameFeatures, ratio: f32) -> Vec<(usize, usize)> {
    if !a.descriptors.comparable(&b.descriptors) {
        return Vec::new();
    }
    let (ab, ba) = match (&a.descriptors, &b.descriptors) {
        (Descriptors::Float { values: x, len }, Descriptors::Float { values: y, .. }) => {
            nearest_both_ways(a, b, |i, j| float_distance(&x[i * len..(i + 1) * len], &y[j * len..(j + 1) * len]))
        }
        (Descriptors::Binary { bytes: x, len }, Descriptors::Binary { bytes: y, .. }) => {
            nearest_both_ways(a, b, |i, j| binary_distance(&x[i * len..(i + 1) * len], &y[j * len..(j + 1) * len]))
        }
        _ => return Vec::new(),
    };
    let r2 = ratio * ratio;
    ab.iter()
        .enumerate()
        .filter_map(|(i, n)| n.passes_ratio(r2).filter(|&j| ba[j].passes_ratio(r2) == Some(i)).map(|j| (i, j)))
        .collect()
}

/// Guided matching: each keypoint `i` of `a` whose position in `b` is predicted (`predicted[i]`, in the units of
/// `b_at`) is compared only with the keypoints of `b` within `radius` of the prediction that have the same Laplacian
/// sign. The ratio test then runs among those few candidates, both ways, and matches must be mutual. Repeated
/// texture (bricks, window rows) defeats the global ratio test; inside a radius smaller than its period the
/// repetitions are not candidates at all. A lone candidate is accepted when its descriptor distance is below
/// `max_distance`.
pub fn guided_match(
    a: &FrameFeatures,
    b: &FrameFeatures,
    predicted: &[Option<[f64; 2]>],
    b_at: &[[f64; 2]],
    radius: f64,
    ratio: f32,
    max_distance: f32,
) -> Vec<(usize, usize)> {
    if !a.descriptors.comparable(&b.descriptors) || radius <= 0.0 || b.count() == 0 {
        return Vec::new();
    }
    let cell = |p: [f64; 2]| ((p[0] / radius).floor() as i64, (p[1] / radius).floor() as i64);
    let mut grid: std::collections::HashMap<(i64, i64), Vec<usize>> = std::collections::HashMap::new();
    for (j, &p) in b_at.iter().enumerate() {
        grid.entry(cell(p)).or_default().push(j);
    }
    let r2 = radius * radius;
    // Every candidate pair with its squared descriptor distance, per keypoint of `a`.
    let candidates: Vec<Vec<(f32, usize)>> = (0..a.count())
        .into_par_iter()
        .map(|i| {
            let Some(p) = predicted.get(i).copied().flatten() else {
                return Vec::new();
            };
            let (cx, cy) = cell(p);
            let mut out = Vec::new();
            for gx in cx - 1..=cx + 1 {
                for gy in cy - 1..=cy + 1 {
                    for &j in grid.get(&(gx, gy)).map(Vec::as_slice).unwrap_or(&[]) {
                        let q = b_at[j];
                        if b.signs[j] == a.signs[i] && (q[0] - p[0]).powi(2) + (q[1] - p[1]).powi(2) <= r2 {
                            out.push((squared_distance(a, i, b, j), j));
                        }
                    }
                }
            }
            out
        })
        .collect();
    let (r2d, max2) = (ratio * ratio, max_distance * max_distance);
    let passes = |n: &Nearest| n.best < max2 && (n.second.is_infinite() || n.best < r2d * n.second);
    // Best and second-best per keypoint of `b`, over the keypoints of `a` that chose it as a candidate.
    let mut of_b = vec![Nearest::NONE; b.count()];
    for (i, list) in candidates.iter().enumerate() {
        for &(d, j) in list {
            of_b[j].offer(d, i);
        }
    }
    candidates
        .iter()
        .enumerate()
        .filter_map(|(i, list)| {
            let mut row = Nearest::NONE;
            for &(d, j) in list {
                row.offer(d, j);
            }
            let back = of_b.get(row.at)?;
            (passes(&row) && back.at == i && passes(back)).then_some((i, row.at))
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn features(descs: &[[f32; 2]], signs: &[i32]) -> FrameFeatures {
        FrameFeatures {
            px: descs.iter().map(|d| [d[0] as f64, d[1] as f64]).collect(),
            signs: signs.to_vec(),
            descriptors: Descriptors::Float {
                values: descs.iter().flatten().copied().collect(),
                len: 2,
            },
        }
    }

    #[test]
    fn mutual_nearest_neighbours_with_a_clear_margin_match() {
        let a = features(&[[0.0, 1.0], [1.0, 0.0], [0.7, 0.7]], &[1, 1, 1]);
        let b = features(&[[1.0, 0.05], [0.05, 1.0], [0.71, 0.69]], &[1, 1, 1]);
        assert_eq!(match_features(&a, &b, 0.8), vec![(0, 1), (1, 0), (2, 2)]);
    }

    #[test]
    fn binary_descriptors_match_by_hamming_distance_and_never_against_float_ones() {
        let binary = |rows: &[[u8; 4]]| FrameFeatures {
            px: vec![[0.0; 2]; rows.len()],
            signs: vec![0; rows.len()],
            descriptors: Descriptors::Binary {
                bytes: rows.iter().flatten().copied().collect(),
                len: 4,
            },
        };
        let a = binary(&[[0x00, 0xFF, 0x0F, 0xF0], [0xAA, 0x55, 0xAA, 0x55]]);
        // One bit off each, swapped order.
        let b = binary(&[[0xAB, 0x55, 0xAA, 0x55], [0x00, 0xFF, 0x0F, 0xF1]]);
        assert_eq!(match_features(&a, &b, 0.8), vec![(0, 1), (1, 0)]);
        // 1 bit of 32: 4 · 1 / 32.
        assert!((distance(&a, 0, &b, 1) - (0.125f32).sqrt()).abs() < 1e-6);
        let float = features(&[[1.0, 0.0], [0.0, 1.0]], &[0, 0]);
        assert!(match_features(&a, &float, 0.8).is_empty());
    }

    #[test]
    fn the_one_pass_both_ways_agrees_with_two_separate_searches() {
        // Coarse random descriptors (many exact ties) and mixed signs, more rows than one parallel task holds.
        let mut state = 7u64;
        let mut next = || {
            state = state.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
            (state >> 60) as f32 / 4.0
        };
        let mut make = |n: usize| FrameFeatures {
            px: vec![[0.0; 2]; n],
            signs: (0..n).map(|i| if i % 3 == 0 { -1 } else { 1 }).collect(),
            descriptors: Descriptors::Float {
                values: (0..n * 3).map(|_| next()).collect(),
                len: 3,
            },
        };
        let (a, b) = (make(300), make(270));
        let naive = |x: &FrameFeatures, y: &FrameFeatures| -> Vec<Option<usize>> {
            (0..x.count())
                .map(|i| {
                    let mut n = Nearest::NONE;
                    for j in (0..y.count()).filter(|&j| y.signs[j] == x.signs[i]) {
                        n.offer(squared_distance(x, i, y, j), j);
                    }
                    n.passes_ratio(0.64)
                })
                .collect()
        };
        let (ab, ba) = (naive(&a, &b), naive(&b, &a));
        let expected: Vec<(usize, usize)> = (0..a.count())
            .filter_map(|i| ab[i].filter(|&j| ba[j] == Some(i)).map(|j| (i, j)))
            .collect();
        assert!(expected.len() > 10, "{}", expected.len());
        assert_eq!(match_features(&a, &b, 0.8), expected);
    }

    #[test]
    fn ambiguous_and_opposite_sign_candidates_do_not_match() {
        // Two near-equal candidates: the ratio test refuses.
        let a = features(&[[1.0, 0.0]], &[1]);
        let b = features(&[[0.99, 0.1], [0.99, -0.1]], &[1, 1]);
        assert!(match_features(&a, &b, 0.8).is_empty());
        // The only close candidate has the other Laplacian sign.
        let b = features(&[[1.0, 0.0], [0.0, 1.0]], &[-1, 1]);
        assert!(match_features(&a, &b, 0.8).is_empty());
    }
}
