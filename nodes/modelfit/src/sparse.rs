//! The normal equations of a large wire-frame: symmetric, sparse (a pixel ties the parameters of one edge's two
//! vertices), solved by conjugate gradients with a block-Jacobi preconditioner. A façade with hundreds of
//! vertices in one connected component would need an O(n³) dense factorisation; this is O(edges) per step.
use nalgebra::{Matrix3, Vector3};

/// A symmetric matrix with a fixed pattern, stored by rows (both triangles).
#[derive(Debug, Clone)]
pub struct SparseSym {
    n: usize,
    starts: Vec<usize>,
    cols: Vec<usize>,
    vals: Vec<f64>,
}

impl SparseSym {
    /// The pattern holding every pair of parameters of each group (plus the diagonal).
    pub fn with_pattern(n: usize, groups: impl Iterator<Item = Vec<usize>>) -> Self {
        let mut rows: Vec<Vec<usize>> = (0..n).map(|i| vec![i]).collect();
        for g in groups {
            for &i in &g {
                rows[i].extend_from_slice(&g);
            }
        }
        let mut starts = Vec::with_capacity(n + 1);
        let mut cols = Vec::new();
        starts.push(0);
        for mut r in rows {
            r.sort_unstable();
            r.dedup();
            cols.extend(r);
            starts.push(cols.len());
        }
        let vals = vec![0.0; cols.len()];
        Self { n, starts, cols, vals }
    }

    /// Size.
    pub fn n(&self) -> usize {
        self.n
    }

    /// Sets every entry to zero, keeping the pattern.
    pub fn clear(&mut self) {
        self.vals.iter_mut().for_each(|v| *v = 0.0);
    }

    /// Adds `v` at (i, j); the entry must be in the pattern.
    #[inline]
    pub fn add(&mut self, i: usize, j: usize, v: f64) {
        let row = &self.cols[self.starts[i]..self.starts[i + 1]];
        let k = row.binary_search(&j).expect("entry outside the sparsity pattern");
        self.vals[self.starts[i] + k] += v;
    }

    /// Entry (i, j), zero outside the pattern.
    pub fn get(&self, i: usize, j: usize) -> f64 {
        let row = &self.cols[self.starts[i]..self.starts[i + 1]];
        row.binary_search(&j).map_or(0.0, |k| self.vals[self.starts[i] + k])
    }

    fn mul(&self, x: &[f64], y: &mut [f64]) {
        for (i, yi) in y.iter_mut().enumerate() {
            let r = self.starts[i]..self.starts[i + 1];
            *yi = self.cols[r.clone()].iter().zip(&self.vals[r]).map(|(&j, v)| v * x[j]).sum();
        }
    }

    /// The inverses of the 3×3 diagonal blocks (parameters 3k..3k+3), `None` where a block is singular.
    pub fn block_inverses(&self) -> Vec<Option<Matrix3<f64>>> {
        (0..self.n / 3)
            .map(|b| {
                let m = Matrix3::from_fn(|r, c| self.get(3 * b + r, 3 * b + c));
                m.try_inverse()
            })
            .collect()
    }

    /// Solves A x = b by preconditioned conjugate gradients to a relative residual of `tol`; `None` if a block
    /// is singular or the iteration breaks down (A not positive definite).
    pub fn solve(&self, b: &[f64], tol: f64, max_iter: usize) -> Option<Vec<f64>> {
        let n = self.n;
        if !n.is_multiple_of(3) {
            return None;
        }
        let inv: Vec<Matrix3<f64>> = self.block_inverses().into_iter().collect::<Option<_>>()?;
        let precondition = |r: &[f64], z: &mut [f64]| {
            for (k, m) in inv.iter().enumerate() {
                let v = m * Vector3::new(r[3 * k], r[3 * k + 1], r[3 * k + 2]);
                z[3 * k..3 * k + 3].copy_from_slice(v.as_slice());
            }
        };
        let dot = |a: &[f64], b: &[f64]| a.iter().zip(b).map(|(x, y)| x * y).sum::<f64>();
        let mut x = vec![0.0; n];
        let mut r = b.to_vec();
        let mut z = vec![0.0; n];
        precondition(&r, &mut z);
        let mut p = z.clone();
        let mut rz = dot(&r, &z);
        let norm_b = dot(b, b).sqrt();
        if norm_b == 0.0 {
            return Some(x);
        }
        let mut ap = vec![0.0; n];
        for _ in 0..max_iter {
            self.mul(&p, &mut ap);
            let pap = dot(&p, &ap);
            if pap.is_nan() || pap <= 0.0 {
                return None;
            }
            let alpha = rz / pap;
            for i in 0..n {
                x[i] += alpha * p[i];
                r[i] -= alpha * ap[i];
            }
            if dot(&r, &r).sqrt() <= tol * norm_b {
                break;
            }
            precondition(&r, &mut z);
            let rz_new = dot(&r, &z);
            let beta = rz_new / rz;
            rz = rz_new;
            for i in 0..n {
                p[i] = z[i] + beta * p[i];
            }
        }
        Some(x)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn conjugate_gradients_match_a_dense_solve() {
        // A chain of 5 vertices (15 parameters), neighbouring vertices coupled.
        let n = 15;
        let groups: Vec<Vec<usize>> = (0..4).map(|v| (3 * v..3 * v + 6).collect()).collect();
        let mut a = SparseSym::with_pattern(n, groups.clone().into_iter());
        let mut dense = nalgebra::DMatrix::<f64>::zeros(n, n);
        for (k, g) in groups.iter().enumerate() {
            let row: Vec<f64> = g.iter().map(|&i| ((i * 7 + k * 3) % 5) as f64 - 2.0).collect();
            for (x, &i) in g.iter().enumerate() {
                for (y, &j) in g.iter().enumerate() {
                    a.add(i, j, row[x] * row[y]);
                    dense[(i, j)] += row[x] * row[y];
                }
            }
        }
        for i in 0..n {
            a.add(i, i, 0.5);
            dense[(i, i)] += 0.5;
        }
        let b: Vec<f64> = (0..n).map(|i| (i as f64).sin()).collect();
        let x = a.solve(&b, 1e-12, 200).unwrap();
        let want = dense.cholesky().unwrap().solve(&nalgebra::DVector::from_vec(b));
        for i in 0..n {
            assert!((x[i] - want[i]).abs() < 1e-8, "{i}: {} vs {}", x[i], want[i]);
        }
    }
}
