//! Normalised cross-correlation of object-space patches through summed-area tables, so that every window mode and
//! every point of a line costs a handful of lookups instead of a pass over its samples.

/// A summed-area table over a `width × height` lattice (row-major), with a zero border row and column.
#[derive(Debug, Clone, Default)]
pub struct Sat {
    width: usize,
    data: Vec<f64>,
}

impl Sat {
    /// Builds the table of `value(k)` for lattice index `k`, reusing this table's storage.
    pub fn build(&mut self, width: usize, height: usize, value: impl Fn(usize) -> f64) {
        self.width = width;
        let stride = width + 1;
        self.data.clear();
        self.data.resize(stride * (height + 1), 0.0);
        for r in 0..height {
            let mut row_sum = 0.0;
            for c in 0..width {
                row_sum += value(r * width + c);
                self.data[(r + 1) * stride + c + 1] = self.data[r * stride + c + 1] + row_sum;
            }
        }
    }

    /// Sum over the inclusive rectangle `cols.0..=cols.1` × `rows.0..=rows.1` (lattice indices, in range).
    #[inline]
    pub fn sum(&self, cols: (usize, usize), rows: (usize, usize)) -> f64 {
        let s = self.width + 1;
        let (c0, c1, r0, r1) = (cols.0, cols.1 + 1, rows.0, rows.1 + 1);
        self.data[r1 * s + c1] - self.data[r0 * s + c1] - self.data[r1 * s + c0] + self.data[r0 * s + c0]
    }
}

/// The tables of one patch (master or slave): values, squares and the count of valid samples.
#[derive(Debug, Clone, Default)]
pub struct PatchSats {
    /// Σ g.
    pub sum: Sat,
    /// Σ g².
    pub sq: Sat,
    /// Number of valid (non-NaN) samples.
    pub valid: Sat,
}

impl PatchSats {
    /// Builds the tables of a lattice patch (NaN = invalid sample), all three in one pass.
    pub fn build(&mut self, width: usize, height: usize, g: &[f32]) {
        let stride = width + 1;
        for t in [&mut self.sum, &mut self.sq, &mut self.valid] {
            t.width = width;
            t.data.clear();
            t.data.resize(stride * (height + 1), 0.0);
        }
        for r in 0..height {
            let (mut s, mut q, mut n) = (0.0, 0.0, 0.0);
            for c in 0..width {
                let x = g[r * width + c];
                if !x.is_nan() {
                    let x = x as f64;
                    s += x;
                    q += x * x;
                    n += 1.0;
                }
                let (above, here) = (r * stride + c + 1, (r + 1) * stride + c + 1);
                self.sum.data[here] = self.sum.data[above] + s;
                self.sq.data[here] = self.sq.data[above] + q;
                self.valid.data[here] = self.valid.data[above] + n;
            }
        }
    }
}

/// Smallest variance per sample (grey levels²) of a patch that carries information: below it a patch is flat (the
/// thesis's zero-variance case), and its correlation is noise.
pub const MIN_VARIANCE: f64 = 1.0;

/// NCC (eq. 17) of the master and one slave over a window, from their tables and the table of products; `None`
/// when either patch has an invalid sample in the window. A flat slave patch correlates 0; a flat master patch is
/// reported as `None` by the caller's check of [`master_is_textured`].
#[inline]
pub fn ncc(master: &PatchSats, slave: &PatchSats, cross: &Sat, cols: (usize, usize), rows: (usize, usize)) -> Option<f64> {
    let n = ((cols.1 - cols.0 + 1) * (rows.1 - rows.0 + 1)) as f64;
    if slave.valid.sum(cols, rows) < n - 0.5 {
        return None;
    }
    let (sm, ss) = (master.sum.sum(cols, rows), slave.sum.sum(cols, rows));
    let vm = master.sq.sum(cols, rows) - sm * sm / n;
    let vs = slave.sq.sum(cols, rows) - ss * ss / n;
    if vs < MIN_VARIANCE * n {
        return Some(0.0);
    }
    let cov = cross.sum(cols, rows) - sm * ss / n;
    Some((cov / (vm * vs).sqrt()).clamp(-1.0, 1.0))
}

/// Whether the master's window is complete and carries texture.
#[inline]
pub fn master_is_textured(master: &PatchSats, cols: (usize, usize), rows: (usize, usize)) -> bool {
    let n = ((cols.1 - cols.0 + 1) * (rows.1 - rows.0 + 1)) as f64;
    if master.valid.sum(cols, rows) < n - 0.5 {
        return false;
    }
    let sm = master.sum.sum(cols, rows);
    master.sq.sum(cols, rows) - sm * sm / n >= MIN_VARIANCE * n
}

#[cfg(test)]
mod tests {
    use super::*;

    fn direct(a: &[f32], b: &[f32]) -> f64 {
        let n = a.len() as f64;
        let (ma, mb) = (
            a.iter().map(|&x| x as f64).sum::<f64>() / n,
            b.iter().map(|&x| x as f64).sum::<f64>() / n,
        );
        let cov: f64 = a.iter().zip(b).map(|(&x, &y)| (x as f64 - ma) * (y as f64 - mb)).sum();
        let va: f64 = a.iter().map(|&x| (x as f64 - ma).powi(2)).sum();
        let vb: f64 = b.iter().map(|&y| (y as f64 - mb).powi(2)).sum();
        cov / (va * vb).sqrt()
    }

    #[test]
    fn windowed_ncc_equals_the_direct_formula() {
        let (w, h) = (13, 9);
        let m: Vec<f32> = (0..w * h).map(|k| ((k * 37 % 101) as f32).sin() * 50.0 + 100.0).collect();
        let s: Vec<f32> = m.iter().enumerate().map(|(k, &x)| 0.7 * x + 20.0 + ((k * 11 % 7) as f32)).collect();
        let (mut pm, mut ps, mut cross) = (PatchSats::default(), PatchSats::default(), Sat::default());
        pm.build(w, h, &m);
        ps.build(w, h, &s);
        cross.build(w, h, |k| m[k] as f64 * s[k] as f64);
        let (cols, rows) = ((2, 10), (1, 7));
        let pick = |g: &[f32]| -> Vec<f32> {
            (rows.0..=rows.1)
                .flat_map(|r| (cols.0..=cols.1).map(move |c| (r, c)))
                .map(|(r, c)| g[r * w + c])
                .collect()
        };
        let expected = direct(&pick(&m), &pick(&s));
        let got = ncc(&pm, &ps, &cross, cols, rows).unwrap();
        assert!((got - expected).abs() < 1e-9, "{got} vs {expected}");
        assert!(master_is_textured(&pm, cols, rows));
    }

    #[test]
    fn an_invalid_sample_drops_the_slave_and_a_flat_slave_correlates_zero() {
        let (w, h) = (5, 5);
        let m: Vec<f32> = (0..25).map(|k| k as f32).collect();
        let mut s = m.clone();
        s[12] = f32::NAN;
        let (mut pm, mut ps, mut cross) = (PatchSats::default(), PatchSats::default(), Sat::default());
        pm.build(w, h, &m);
        ps.build(w, h, &s);
        cross.build(w, h, |k| if s[k].is_nan() { 0.0 } else { (m[k] * s[k]) as f64 });
        assert_eq!(ncc(&pm, &ps, &cross, (0, 4), (0, 4)), None);
        assert!(ncc(&pm, &ps, &cross, (0, 4), (0, 1)).unwrap() > 0.999);
        let flat = vec![7.0f32; 25];
        ps.build(w, h, &flat);
        cross.build(w, h, |k| (m[k] * 7.0) as f64);
        assert_eq!(ncc(&pm, &ps, &cross, (0, 4), (0, 4)), Some(0.0));
    }
}
