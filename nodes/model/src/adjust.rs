//! Shape (seed 003 §3.4.1): the corners of one object adjusted from all its lines at once, in the Gauss-Helmert
//! model with the line parameters as observations and the corner coordinates as unknowns.
//!
//! The seed's two-plane form (aX + bY + 1 = 0, cY + dZ + 1 = 0) breaks for lines parallel to X, vertical lines and
//! lines whose projections pass near the origin, which a façade is full of. Each line is instead written on its
//! dominant axis k, reduced to its own midpoint c: X_j = c_j + a_j + b_j (X_k − c_k) for the two other axes j,
//! four parameters that are well conditioned for every direction. The seed's equation 3 lacks the inverse on
//! N_bb and its equation 4 counts the redundancy as n − u; both are corrected (r = c − u).
use nalgebra::{DMatrix, DVector, Matrix2, Matrix3};

use lineflow_photogrammetry::Vec3;

use crate::ModelLine;

/// A line as an observation: its dominant axis, reduction point, parameters and their covariance.
#[derive(Debug, Clone)]
struct LineObservation {
    axis: usize,
    others: [usize; 2],
    centre: Vec3,
    /// (a, b) per other axis, as observed.
    observed: [[f64; 2]; 2],
    /// Covariance of (a, b) per other axis, m² (the two axes are independent).
    cov: [Matrix2<f64>; 2],
}

impl LineObservation {
    fn new(l: &ModelLine) -> Self {
        let d = l.end - l.start;
        let axis = d.iamax();
        let others = [(axis + 1) % 3, (axis + 2) % 3];
        let centre = l.midpoint();
        let len_k = d[axis];
        let mut observed = [[0.0; 2]; 2];
        let mut cov = [Matrix2::zeros(); 2];
        for (m, &j) in others.iter().enumerate() {
            let s2 = l.sigma_along(j).powi(2);
            let b = d[j] / len_k;
            observed[m] = [0.0, b];
            // First-order propagation of isotropic endpoint errors (σ per coordinate) into (a, b); the cross term
            // vanishes at the midpoint.
            cov[m] = Matrix2::new(s2 * (1.0 + b * b) / 2.0, 0.0, 0.0, 2.0 * s2 * (1.0 + b * b) / (len_k * len_k));
            if l.regular.fixes(j) {
                // A slope made exact by regularisation: held, not freed (a zero would make N_bb singular).
                cov[m][(1, 1)] *= 1e-8;
            }
        }
        LineObservation {
            axis,
            others,
            centre,
            observed,
            cov,
        }
    }
}

/// Adjusted corners of one object.
#[derive(Debug, Clone)]
pub struct Adjusted {
    /// Corner coordinates, metres.
    pub corners: Vec<Vec3>,
    /// Posterior standard deviations (σ̂0-scaled) per corner, metres.
    pub sigmas: Vec<Vec3>,
    /// Adjusted line parameters per line: a point and a unit direction.
    pub lines: Vec<(Vec3, Vec3)>,
    /// A-posteriori standard deviation of unit weight, if there is redundancy.
    pub sigma0: Option<f64>,
    /// Redundancy r = c − u.
    pub redundancy: i64,
    pub iterations: usize,
}

/// Adjusts `corners` (initial values) given `lines` and incidences `(corner, line)`. Every corner needs two
/// non-parallel lines; `None` when the normal equations are singular.
pub fn adjust(lines: &[ModelLine], corners: &[Vec3], incidences: &[(usize, usize)]) -> Option<Adjusted> {
    let obs: Vec<LineObservation> = lines.iter().map(LineObservation::new).collect();
    // Incidences grouped by line (N_bb is block diagonal by line).
    let mut by_line: Vec<Vec<usize>> = vec![Vec::new(); lines.len()];
    for &(c, l) in incidences {
        by_line[l].push(c);
    }
    let u = 3 * corners.len();
    let n_conditions = 2 * incidences.len();
    let mut x: Vec<Vec3> = corners.to_vec();
    let mut adjusted: Vec<[[f64; 2]; 2]> = obs.iter().map(|o| o.observed).collect();
    let mut iterations = 0;
    let mut n_aa = DMatrix::zeros(u, u);
    let mut residual_energy = 0.0;
    for iteration in 0..20 {
        iterations = iteration + 1;
        n_aa.fill(0.0);
        let mut rhs = DVector::zeros(u);
        // Per line: the reduced system pieces, kept to compute residuals after ξ is known.
        let mut pieces = Vec::with_capacity(lines.len());
        for (l, o) in obs.iter().enumerate() {
            let cs = &by_line[l];
            if cs.is_empty() {
                pieces.push(None);
                continue;
            }
            // A restricted to the corners on this line (3 columns each): the rest of its row is zero.
            let rows = 2 * cs.len();
            let mut a = DMatrix::zeros(rows, 3 * cs.len());
            let mut b = DMatrix::zeros(rows, 4);
            let mut w = DVector::zeros(rows);
            for (r, &c) in cs.iter().enumerate() {
                let xk = x[c][o.axis] - o.centre[o.axis];
                for m in 0..2 {
                    let j = o.others[m];
                    let [ah, bh] = adjusted[l][m];
                    let g = x[c][j] - o.centre[j] - ah - bh * xk;
                    let row = 2 * r + m;
                    a[(row, 3 * r + j)] = 1.0;
                    a[(row, 3 * r + o.axis)] = -bh;
                    b[(row, 2 * m)] = -1.0;
                    b[(row, 2 * m + 1)] = -xk;
                    // w = −g(l̂, x) − B (l − l̂)
                    let [a0, b0] = o.observed[m];
                    w[row] = -g - (-(a0 - ah) - xk * (b0 - bh));
                }
            }
            let mut q = DMatrix::zeros(4, 4);
            for m in 0..2 {
                q.view_mut((2 * m, 2 * m), (2, 2)).copy_from(&o.cov[m]);
            }
            let n_bb = &b * &q * b.transpose();
            let n_bb_inv = n_bb.try_inverse()?;
            let at_n = a.transpose() * &n_bb_inv;
            let block = &at_n * &a;
            let part = &at_n * &w;
            for (r1, &c1) in cs.iter().enumerate() {
                for (r2, &c2) in cs.iter().enumerate() {
                    let mut target = n_aa.view_mut((3 * c1, 3 * c2), (3, 3));
                    target += block.view((3 * r1, 3 * r2), (3, 3));
                }
                let mut target = rhs.rows_mut(3 * c1, 3);
                target += part.rows(3 * r1, 3);
            }
            pieces.push(Some((a, b, w, q, n_bb_inv)));
        }
        let chol = n_aa.clone().cholesky()?;
        let xi = chol.solve(&rhs);
        residual_energy = 0.0;
        for (l, piece) in pieces.iter().enumerate() {
            let Some((a, b, w, q, n_bb_inv)) = piece else { continue };
            let mut xi_here = DVector::zeros(3 * by_line[l].len());
            for (r, &c) in by_line[l].iter().enumerate() {
                xi_here.rows_mut(3 * r, 3).copy_from(&xi.rows(3 * c, 3));
            }
            let k = n_bb_inv * (w - a * xi_here);
            let e = q * b.transpose() * &k;
            // eᵀ P e with P = Q⁻¹ equals kᵀ B Q Bᵀ k.
            residual_energy += e.dot(&(b.transpose() * &k));
            for m in 0..2 {
                adjusted[l][m] = [obs[l].observed[m][0] + e[2 * m], obs[l].observed[m][1] + e[2 * m + 1]];
            }
        }
        for (c, p) in x.iter_mut().enumerate() {
            *p += Vec3::new(xi[3 * c], xi[3 * c + 1], xi[3 * c + 2]);
        }
        if xi.amax() < 1e-7 {
            break;
        }
    }
    let redundancy = n_conditions as i64 - u as i64;
    let sigma0 = (redundancy > 0).then(|| (residual_energy / redundancy as f64).sqrt());
    let inv = n_aa.cholesky()?.inverse();
    let scale = sigma0.unwrap_or(1.0);
    let sigmas = (0..corners.len())
        .map(|c| {
            let block: Matrix3<f64> = inv.fixed_view::<3, 3>(3 * c, 3 * c).into_owned();
            Vec3::new(block[(0, 0)].sqrt(), block[(1, 1)].sqrt(), block[(2, 2)].sqrt()) * scale
        })
        .collect();
    let lines_out = obs
        .iter()
        .zip(&adjusted)
        .map(|(o, p)| {
            let mut point = o.centre;
            let mut dir = Vec3::zeros();
            dir[o.axis] = 1.0;
            for m in 0..2 {
                point[o.others[m]] += p[m][0];
                dir[o.others[m]] = p[m][1];
            }
            (point, dir.normalize())
        })
        .collect();
    Some(Adjusted {
        corners: x,
        sigmas,
        lines: lines_out,
        sigma0,
        redundancy,
        iterations,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn noise_free_rectangle_returns_its_corners_with_zero_residuals() {
        let p = [[0.0, 0.0, 0.0], [2.0, 0.0, 0.0], [2.0, 0.0, 1.5], [0.0, 0.0, 1.5]].map(Vec3::from);
        let lines: Vec<ModelLine> = (0..4).map(|k| ModelLine::new(p[k], p[(k + 1) % 4], 0.01)).collect();
        let start: Vec<Vec3> = p.iter().map(|q| q + Vec3::new(0.02, -0.01, 0.015)).collect();
        let inc: Vec<(usize, usize)> = (0..4).flat_map(|c| [(c, c), (c, (c + 3) % 4)]).collect();
        let r = adjust(&lines, &start, &inc).expect("regular");
        for (a, b) in r.corners.iter().zip(&p) {
            assert!((a - b).norm() < 1e-6, "{a} vs {b}");
        }
        assert!(r.sigma0.is_none_or(|s| s < 1e-6));
    }

    #[test]
    fn a_corner_of_three_noisy_lines_is_better_than_its_lines() {
        // Three lines of a box corner, each shifted across itself by 1 cm in a different direction.
        let lines = vec![
            ModelLine::new(Vec3::new(0.0, 0.01, 0.0), Vec3::new(1.0, 0.01, 0.0), 0.01),
            ModelLine::new(Vec3::new(0.0, 0.0, 0.01), Vec3::new(0.0, 1.0, 0.01), 0.01),
            ModelLine::new(Vec3::new(0.01, 0.0, 0.0), Vec3::new(0.01, 0.0, 1.0), 0.01),
        ];
        let inc = [(0, 0), (0, 1), (0, 2)];
        let r = adjust(&lines, &[Vec3::zeros()], &inc).expect("regular");
        // Each coordinate is observed by two lines with errors 1 cm and 0 and equal weights: the adjustment splits
        // it (to within the weights' dependence on where along the lines the corner lands).
        for k in 0..3 {
            assert!((r.corners[0][k] - 0.005).abs() < 1e-4, "{}", r.corners[0]);
        }
        assert_eq!(r.redundancy, 3);
        assert!(r.sigmas[0].x < 0.01);
    }
}
