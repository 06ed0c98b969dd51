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

/// Squared descriptor distance between keypoint `i` of `a` and keypoint `j` of `b` (comparable kinds). A binary
/// descriptor of `L` bits counts as the unit vector of ±1/√L per bit, so that a Hamming distance `H` is `4H / L`:
/// unrelated descriptors lie near 2 (orthogonal unit vectors) for both kinds, and the ratio and distance thresholds
/// mean the same for SURF and ORB.
fn squared_distance(a: &FrameFeatures, i: usize, b: &FrameFeatures, j: usize) -> f32 {
    match (&a.descriptors, &b.descriptors) {
        (Descriptors::Float { values: x, len }, Descriptors::Float { values: y, .. }) => {
            let (x, y) = (&x[i * len..(i + 1) * len], &y[j * len..(j + 1) * len]);
            x.iter().zip(y).map(|(p, q)| (p - q) * (p - q)).sum()
        }
        (Descriptors::Binary { bytes: x, len }, Descriptors::Binary { bytes: y, .. }) => {
            let (x, y) = (&x[i * len..(i + 1) * len], &y[j * len..(j + 1) * len]);
            let hamming: u32 = x.iter().zip(y).map(|(p, q)| (p ^ q).count_ones()).sum();
            4.0 * hamming as f32 / (8 * len).max(1) as f32
        }
        _ => f32::INFINITY,
    }
}

/// Descriptor distance between keypoint `i` of `a` and keypoint `j` of `b`.
pub fn distance(a: &FrameFeatures, i: usize, b: &FrameFeatures, j: usize) -> f32 {
    squared_distance(a, i, b, j).sqrt()
}

/// For each keypoint of `a`, its nearest neighbour in `b` with the same Laplacian sign, when the nearest is
/// clearly closer than the second (distance ratio below `ratio`).
fn nearest(a: &FrameFeatures, b: &FrameFeatures, ratio: f32) -> Vec<Option<usize>> {
    let r2 = ratio * ratio;
    (0..a.count())
        .into_par_iter()
        .map(|i| {
            let (mut best, mut second, mut at) = (f32::INFINITY, f32::INFINITY, usize::MAX);
            for j in 0..b.count() {
                if b.signs[j] != a.signs[i] {
                    continue;
                }
                let d = squared_distance(a, i, b, j);
                if d < best {
                    second = best;
                    best = d;
                    at = j;
                } else if d < second {
                    second = d;
                }
            }
            // Without a second candidate there is no ratio to test: no match.
            (second.is_finite() && best < r2 * second).then_some(at)
        })
        .collect()
}

/// Matches `a` to `b`: ratio test both ways and mutual consistency. Pairs of indices, ordered by `a`'s index.
pub fn match_features(a: &FrameFeatures, b: &FrameFeatures, ratio: f32) -> Vec<(usize, usize)> {
    if !a.descriptors.comparable(&b.descriptors) {
        return Vec::new();
    }
    let ab = nearest(a, b, ratio);
    let ba = nearest(b, a, ratio);
    ab.iter()
        .enumerate()
        .filter_map(|(i, j)| j.filter(|&j| ba[j] == Some(i)).map(|j| (i, j)))
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
    let passes = |best: f32, second: f32| best < max2 && (second.is_infinite() || best < r2d * second);
    // Best and second-best per keypoint of `b`, over the keypoints of `a` that chose it as a candidate.
    let mut of_b = vec![(f32::INFINITY, f32::INFINITY, usize::MAX); b.count()];
    for (i, list) in candidates.iter().enumerate() {
        for &(d, j) in list {
            let e = &mut of_b[j];
            if d < e.0 || (d == e.0 && i < e.2) {
                *e = (d, e.0, i);
            } else if d < e.1 {
                e.1 = d;
            }
        }
    }
    candidates
        .iter()
        .enumerate()
        .filter_map(|(i, list)| {
            let (mut best, mut second, mut at) = (f32::INFINITY, f32::INFINITY, usize::MAX);
            for &(d, j) in list {
                if d < best || (d == best && j < at) {
                    second = best;
                    best = d;
                    at = j;
                } else if d < second {
                    second = d;
                }
            }
            let back = of_b.get(at)?;
            (passes(best, second) && back.2 == i && passes(back.0, back.1)).then_some((i, at))
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
