//! One 3-D line per point group: the thesis's direction clustering with the principal piercing plane (seed 000
//! §2.16), and robust total least squares (two-point RANSAC, then principal-axis refits of the inliers).
use lineflow_photogrammetry::random::Rng;
use lineflow_photogrammetry::ransac::{best_of_samples, best_scored, Sampling};
use lineflow_photogrammetry::{Mat3, Vec3};
use serde::Deserialize;

/// How a group's points become a line.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Method {
    /// Robust total least squares (default).
    Tls,
    /// The thesis: clustered pair directions, piercing points on the principal axis plane, first/last points.
    Thesis,
}

/// A fitted segment.
#[derive(Debug, Clone, PartialEq)]
pub struct Fitted {
    /// First endpoint.
    pub start: Vec3,
    /// Second endpoint.
    pub end: Vec3,
    /// Indices of the inliers in the group.
    pub inliers: Vec<usize>,
    /// RMS distance of the inliers from the line, metres.
    pub rms_m: f64,
}

impl Fitted {
    /// Unit direction.
    pub fn direction(&self) -> Vec3 {
        (self.end - self.start).normalize()
    }

    /// Length, metres.
    pub fn length(&self) -> f64 {
        (self.end - self.start).norm()
    }
}

/// Centroid and unit principal direction of points.
pub fn principal_axis(points: &[Vec3]) -> Option<(Vec3, Vec3)> {
    if points.len() < 2 {
        return None;
    }
    let c = points.iter().sum::<Vec3>() / points.len() as f64;
    let mut cov = Mat3::zeros();
    for p in points {
        let d = p - c;
        cov += d * d.transpose();
    }
    let eig = cov.symmetric_eigen();
    let d = eig.eigenvectors.column(eig.eigenvalues.imax()).into_owned();
    d.try_normalize(1e-12).map(|d| (c, d))
}

fn distance(p: &Vec3, origin: &Vec3, dir: &Vec3) -> f64 {
    let v = p - origin;
    (v - dir * v.dot(dir)).norm()
}

/// The segment over the inliers' projections, with their RMS distance.
fn segment_of(points: &[Vec3], inliers: Vec<usize>, origin: Vec3, dir: Vec3) -> Option<Fitted> {
    let ts = inliers.iter().map(|&i| (points[i] - origin).dot(&dir));
    let (lo, hi) = ts.fold((f64::INFINITY, f64::NEG_INFINITY), |(l, h), t| (l.min(t), h.max(t)));
    let rms = (inliers.iter().map(|&i| distance(&points[i], &origin, &dir).powi(2)).sum::<f64>() / inliers.len().max(1) as f64).sqrt();
    (hi > lo).then(|| Fitted {
        start: origin + dir * lo,
        end: origin + dir * hi,
        inliers,
        rms_m: rms,
    })
}

/// Robust total least squares: the two-point line with most points within `tolerance`, then two refits of the
/// principal axis to the points within `tolerance` of the current line.
pub fn fit_tls(points: &[Vec3], tolerance: f64, iterations: usize) -> Option<Fitted> {
    let n = points.len();
    if n < 2 {
        return None;
    }
    let through = |i: usize, j: usize| (points[j] - points[i]).try_normalize(1e-9).map(|dir| (points[i], dir));
    let near = |(origin, dir): &(Vec3, Vec3)| points.iter().filter(|p| distance(p, origin, dir) <= tolerance).count();
    let ((mut origin, mut dir), _) = if n * (n - 1) / 2 <= iterations {
        // Few enough points to try every pair.
        let pairs = (0..n).flat_map(|i| (i + 1..n).map(move |j| (i, j)));
        best_scored(pairs.filter_map(|(i, j)| through(i, j)), near)?
    } else {
        let sampling = Sampling {
            iterations,
            seed: 0x5851_F42D_4C95_7F2D ^ n as u64,
        };
        best_of_samples(n, 2, sampling, |s| through(s[0], s[1]), near)?
    };
    for _ in 0..3 {
        let chosen: Vec<Vec3> = points.iter().filter(|p| distance(p, &origin, &dir) <= tolerance).copied().collect();
        let (c, d) = principal_axis(&chosen)?;
        origin = c;
        dir = d;
    }
    let inliers: Vec<usize> = (0..n).filter(|&i| distance(&points[i], &origin, &dir) <= tolerance).collect();
    if inliers.len() < 2 {
        return None;
    }
    segment_of(points, inliers, origin, dir)
}

/// Canonical sign of a direction: its largest component positive.
fn canonical(d: Vec3) -> Vec3 {
    if d[d.iamax()] < 0.0 {
        -d
    } else {
        d
    }
}

/// The thesis's line (seed 000 §2.16, with the spec's fills): directions of max(⌈n/2⌉, 200) random point pairs
/// clustered within 5°, the largest cluster's mean as the main direction; every point moved along it to the axis
/// plane it pierces most steeply (through the centroid, not the thesis's aX+bY+cZ = 1); piercing points beyond
/// max(3·MAD, `tolerance`) of their median rejected; the line through the inliers' mean; endpoints from the first
/// and last points of the chain.
pub fn fit_thesis(points: &[Vec3], tolerance: f64) -> Option<Fitted> {
    let n = points.len();
    if n < 2 {
        return None;
    }
    let mut rng = Rng::new(0x2545_F491_4F6C_DD1D, n as u64);
    let draws = n.div_ceil(2).max(200);
    let dirs: Vec<Vec3> = (0..draws)
        .filter_map(|_| (points[rng.below(n)] - points[rng.below(n)]).try_normalize(1e-9).map(canonical))
        .collect();
    let cos5 = 5f64.to_radians().cos();
    let (main_k, _) = dirs
        .iter()
        .enumerate()
        .map(|(k, d)| (k, dirs.iter().filter(|e| d.dot(e).abs() >= cos5).count()))
        .fold(None, |best: Option<(usize, usize)>, (k, c)| match best {
            Some((_, b)) if b >= c => best,
            _ => Some((k, c)),
        })?;
    let seed = dirs[main_k];
    let sum: Vec3 = dirs.iter().filter(|e| seed.dot(e) >= cos5).sum();
    let dir = sum.try_normalize(1e-12)?;
    let axis = dir.iamax();
    let centroid = points.iter().sum::<Vec3>() / n as f64;
    let pierce: Vec<Vec3> = points.iter().map(|p| p + dir * ((centroid[axis] - p[axis]) / dir[axis])).collect();
    let median = |v: &mut Vec<f64>| {
        v.sort_by(f64::total_cmp);
        v[v.len() / 2]
    };
    let (a, b) = ((axis + 1) % 3, (axis + 2) % 3);
    let mid = [
        median(&mut pierce.iter().map(|p| p[a]).collect()),
        median(&mut pierce.iter().map(|p| p[b]).collect()),
    ];
    let dist: Vec<f64> = pierce.iter().map(|p| (p[a] - mid[0]).hypot(p[b] - mid[1])).collect();
    let mad = median(&mut dist.clone());
    let limit = (3.0 * mad).max(tolerance);
    let inliers: Vec<usize> = (0..n).filter(|&i| dist[i] <= limit).collect();
    if inliers.len() < 2 {
        return None;
    }
    let origin = inliers.iter().map(|&i| pierce[i]).sum::<Vec3>() / inliers.len() as f64;
    let rms = (inliers.iter().map(|&i| distance(&points[i], &origin, &dir).powi(2)).sum::<f64>() / inliers.len() as f64).sqrt();
    let foot = |p: &Vec3| origin + dir * (p - origin).dot(&dir);
    Some(Fitted {
        start: foot(&points[0]),
        end: foot(&points[n - 1]),
        inliers,
        rms_m: rms,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Points along a line with a deterministic scatter and a share of gross outliers.
    fn group(a: Vec3, b: Vec3, n: usize, scatter: f64, outliers: usize) -> Vec<Vec3> {
        let mut rng = Rng::new(7, 0);
        let mut pts: Vec<Vec3> = (0..n)
            .map(|k| {
                let t = k as f64 / (n - 1) as f64;
                let e = Vec3::new(rng.below(1000) as f64, rng.below(1000) as f64, rng.below(1000) as f64) / 1000.0 - Vec3::repeat(0.5);
                a + (b - a) * t + e * scatter
            })
            .collect();
        for k in 0..outliers {
            pts[3 + 5 * k] += Vec3::new(0.0, -0.4 - 0.1 * k as f64, 0.0);
        }
        pts
    }

    fn angle_deg(f: &Fitted, a: Vec3, b: Vec3) -> f64 {
        f.direction().dot(&(b - a).normalize()).abs().min(1.0).acos().to_degrees()
    }

    #[test]
    fn total_least_squares_ignores_outliers_and_spans_the_inliers() {
        let (a, b) = (Vec3::new(2.0, 0.0, 3.0), Vec3::new(3.4, 0.0, 3.0));
        let pts = group(a, b, 40, 0.01, 6);
        let f = fit_tls(&pts, 0.03, 200).unwrap();
        assert_eq!(f.inliers.len(), 34);
        assert!(angle_deg(&f, a, b) < 0.5, "{}", angle_deg(&f, a, b));
        assert!((f.start - a).norm() < 0.02 && (f.end - b).norm() < 0.02 || (f.start - b).norm() < 0.02 && (f.end - a).norm() < 0.02);
        assert!(f.rms_m < 0.01);
        // Deterministic.
        assert_eq!(fit_tls(&pts, 0.03, 200), Some(f));
    }

    #[test]
    fn the_thesis_method_finds_the_direction_and_uses_the_first_and_last_points() {
        let (a, b) = (Vec3::new(1.0, -0.2, 0.5), Vec3::new(1.0, -0.2, 2.2));
        let pts = group(a, b, 30, 0.005, 3);
        let f = fit_thesis(&pts, 0.05).unwrap();
        assert!(angle_deg(&f, a, b) < 1.0, "{}", angle_deg(&f, a, b));
        assert!((f.start - a).norm() < 0.02 && (f.end - b).norm() < 0.02);
        assert_eq!(f.inliers.len(), 27);
    }
}
