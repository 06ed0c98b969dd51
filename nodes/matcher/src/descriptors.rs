//! Descriptor matching: nearest neighbours with the ratio test, the sign-of-Laplacian check and mutual consistency
//! (seed 000 §2.4, matching).
use rayon::prelude::*;

/// The features of one image as the matcher needs them.
#[derive(Debug, Clone, Default)]
pub struct FrameFeatures {
    /// Keypoint positions, measured pixels.
    pub px: Vec<[f64; 2]>,
    /// Sign of the Laplacian per keypoint.
    pub signs: Vec<i32>,
    /// Unit descriptors, `len` values per keypoint.
    pub descriptors: Vec<f32>,
    /// Values per descriptor.
    pub len: usize,
}

impl FrameFeatures {
    /// Number of keypoints.
    pub fn count(&self) -> usize {
        self.px.len()
    }
    fn descriptor(&self, i: usize) -> &[f32] {
        &self.descriptors[i * self.len..(i + 1) * self.len]
    }
    /// The first `n` keypoints (the strongest, as the features stage orders them).
    pub fn strongest(&self, n: usize) -> FrameFeatures {
        let n = n.min(self.count());
        FrameFeatures {
            px: self.px[..n].to_vec(),
            signs: self.signs[..n].to_vec(),
            descriptors: self.descriptors[..n * self.len].to_vec(),
            len: self.len,
        }
    }
}

fn squared_distance(a: &[f32], b: &[f32]) -> f32 {
    a.iter().zip(b).map(|(x, y)| (x - y) * (x - y)).sum()
}

/// For each keypoint of `a`, its nearest neighbour in `b` with the same Laplacian sign, when the nearest is
/// clearly closer than the second (distance ratio below `ratio`).
fn nearest(a: &FrameFeatures, b: &FrameFeatures, ratio: f32) -> Vec<Option<usize>> {
    let r2 = ratio * ratio;
    (0..a.count())
        .into_par_iter()
        .map(|i| {
            let da = a.descriptor(i);
            let (mut best, mut second, mut at) = (f32::INFINITY, f32::INFINITY, usize::MAX);
            for j in 0..b.count() {
                if b.signs[j] != a.signs[i] {
                    continue;
                }
                let d = squared_distance(da, b.descriptor(j));
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
    if a.len != b.len {
        return Vec::new();
    }
    let ab = nearest(a, b, ratio);
    let ba = nearest(b, a, ratio);
    ab.iter()
        .enumerate()
        .filter_map(|(i, j)| j.filter(|&j| ba[j] == Some(i)).map(|j| (i, j)))
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn features(descs: &[[f32; 2]], signs: &[i32]) -> FrameFeatures {
        FrameFeatures {
            px: descs.iter().map(|d| [d[0] as f64, d[1] as f64]).collect(),
            signs: signs.to_vec(),
            descriptors: descs.iter().flatten().copied().collect(),
            len: 2,
        }
    }

    #[test]
    fn mutual_nearest_neighbours_with_a_clear_margin_match() {
        let a = features(&[[0.0, 1.0], [1.0, 0.0], [0.7, 0.7]], &[1, 1, 1]);
        let b = features(&[[1.0, 0.05], [0.05, 1.0], [0.71, 0.69]], &[1, 1, 1]);
        assert_eq!(match_features(&a, &b, 0.8), vec![(0, 1), (1, 0), (2, 2)]);
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
