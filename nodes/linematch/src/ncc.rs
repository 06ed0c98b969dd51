//! Normalised cross-correlation of object-space patches through column prefix sums over fixed bands of rows.
//!
//! Every window of a line's search spans one of a few row ranges (the line lies along a lattice row; the C, U and B
//! windows reach above and below it by fixed amounts), so instead of a full summed-area table each quantity keeps,
//! per row band, its column sums and their prefix along the columns: any window then costs two lookups per
//! quantity, and building the tables is a vectorisable pass of additions down the rows instead of a 2-D recurrence.

/// The row bands of a lattice: inclusive row ranges, and the sorted row boundaries at which running column sums
/// are taken.
#[derive(Debug, Clone, Default)]
pub struct Bands {
    ranges: Vec<(usize, usize)>,
    /// Sorted distinct boundaries: every band's first row and one past its last.
    boundaries: Vec<usize>,
    /// For each band, the indices into `boundaries` of its first row and of one past its last.
    ends: Vec<(usize, usize)>,
}

impl Bands {
    /// Forgets every band.
    pub fn clear(&mut self) {
        self.ranges.clear();
        self.boundaries.clear();
        self.ends.clear();
    }

    /// The index of the band `rows.0..=rows.1`, added when new.
    pub fn index(&mut self, rows: (usize, usize)) -> usize {
        match self.ranges.iter().position(|&b| b == rows) {
            Some(i) => i,
            None => {
                self.ranges.push(rows);
                self.ranges.len() - 1
            }
        }
    }

    /// Number of bands.
    pub fn len(&self) -> usize {
        self.ranges.len()
    }

    /// Whether there is no band.
    pub fn is_empty(&self) -> bool {
        self.ranges.is_empty()
    }

    /// Rows in band `b`.
    pub fn rows(&self, b: usize) -> usize {
        self.ranges[b].1 - self.ranges[b].0 + 1
    }

    /// Fixes the boundaries once every band is known; call before building tables.
    pub fn seal(&mut self) {
        self.boundaries.clear();
        self.boundaries.extend(self.ranges.iter().flat_map(|&(a, b)| [a, b + 1]));
        self.boundaries.sort_unstable();
        self.boundaries.dedup();
        let at = |r: usize| self.boundaries.binary_search(&r).unwrap_or(0);
        self.ends = self.ranges.iter().map(|&(a, b)| (at(a), at(b + 1))).collect();
    }
}

/// Column prefix sums of one quantity over each band: `data[band · (width + 1) + c]` is the band's sum over the
/// columns `0..c`.
#[derive(Debug, Clone, Default)]
pub struct BandSums {
    width: usize,
    data: Vec<f64>,
}

impl BandSums {
    /// Sum over the band `band` and the inclusive columns `cols.0..=cols.1` (in range).
    #[inline]
    pub fn sum(&self, band: usize, cols: (usize, usize)) -> f64 {
        let row = band * (self.width + 1);
        self.data[row + cols.1 + 1] - self.data[row + cols.0]
    }
}

/// Reused buffers of the table builds.
#[derive(Debug, Clone, Default)]
pub struct BandScratch<const Q: usize> {
    running: Vec<[f64; Q]>,
    snapshots: Vec<[f64; Q]>,
}

/// Builds the band tables of `Q` quantities of a `width × height` lattice (row-major), `value(k)` giving them for
/// lattice index `k`. The bands, sealed, must lie within the lattice.
pub fn build_bands<const Q: usize>(
    width: usize,
    height: usize,
    bands: &Bands,
    scratch: &mut BandScratch<Q>,
    value: impl Fn(usize) -> [f64; Q],
    out: [&mut BandSums; Q],
) {
    debug_assert!(bands.ranges.iter().all(|&(a, b)| a <= b && b < height), "bands outside the lattice");
    let BandScratch { running, snapshots } = scratch;
    running.clear();
    running.resize(width, [0.0; Q]);
    snapshots.clear();
    let last = bands.boundaries.last().copied().unwrap_or(0).min(height);
    let mut next = 0;
    for r in 0..=last {
        if bands.boundaries.get(next) == Some(&r) {
            snapshots.extend_from_slice(running);
            next += 1;
        }
        if r == last {
            break;
        }
        for (c, acc) in running.iter_mut().enumerate() {
            let v = value(r * width + c);
            for q in 0..Q {
                acc[q] += v[q];
            }
        }
    }
    let stride = width + 1;
    for (q, table) in out.into_iter().enumerate() {
        table.width = width;
        table.data.clear();
        table.data.resize(stride * bands.len(), 0.0);
        for (b, &(top, bottom)) in bands.ends.iter().enumerate() {
            let (top, bottom) = (&snapshots[top * width..][..width], &snapshots[bottom * width..][..width]);
            let row = &mut table.data[b * stride..][..stride];
            let mut total = 0.0;
            for c in 0..width {
                total += bottom[c][q] - top[c][q];
                row[c + 1] = total;
            }
        }
    }
}

/// The tables of one patch (master or slave): values, squares and the count of valid samples.
#[derive(Debug, Clone, Default)]
pub struct PatchSums {
    /// Σ g.
    pub sum: BandSums,
    /// Σ g².
    pub sq: BandSums,
    /// Number of valid (non-NaN) samples.
    pub valid: BandSums,
}

/// Grey values are summed about mid-grey: NCC does not change, and the sums of squares stay small enough that the
/// variance of a window loses nothing to cancellation.
const MID_GREY: f64 = 128.0;

impl PatchSums {
    /// Builds the tables of a lattice patch (NaN = invalid sample), all three in one pass.
    pub fn build(&mut self, width: usize, height: usize, bands: &Bands, scratch: &mut BandScratch<3>, g: &[f32]) {
        let value = |k: usize| {
            let x = g[k];
            if x.is_nan() {
                [0.0; 3]
            } else {
                let x = x as f64 - MID_GREY;
                [x, x * x, 1.0]
            }
        };
        build_bands(width, height, bands, scratch, value, [&mut self.sum, &mut self.sq, &mut self.valid]);
    }
}

/// Builds the table of the products of the master patch `m` and a slave patch `g` (about mid-grey; 0 where either
/// is invalid).
pub fn build_cross(width: usize, height: usize, bands: &Bands, scratch: &mut BandScratch<1>, m: &[f32], g: &[f32], out: &mut BandSums) {
    let value = |k: usize| {
        let x = (m[k] as f64 - MID_GREY) * (g[k] as f64 - MID_GREY);
        [if x.is_nan() { 0.0 } else { x }]
    };
    build_bands(width, height, bands, scratch, value, [out]);
}

/// Smallest variance per sample (grey levels²) of a patch that carries information: below it a patch is flat (the
/// thesis's zero-variance case), and its correlation is noise.
pub const MIN_VARIANCE: f64 = 1.0;

/// The same for the thin strips, whose few rows on a near-uniform surface (a painted frame, glass) correlate best
/// with whatever structure the edge's blur or the sensor noise leaves: 3 grey levels of standard deviation.
pub const STRIP_MIN_VARIANCE: f64 = 9.0;

/// The master's side of one window: its band and columns, sample count, sum and variance (times `n`).
#[derive(Debug, Clone, Copy)]
pub struct MasterWindow {
    band: usize,
    cols: (usize, usize),
    n: f64,
    sum: f64,
    variance_n: f64,
}

/// The master's window of band `band` and columns `cols` when it is complete and carries texture (the thesis's
/// zero-variance case is `None`): computed once per window, shared by every slave's NCC.
#[inline]
pub fn master_window(master: &PatchSums, band: usize, cols: (usize, usize), rows: usize, min_variance: f64) -> Option<MasterWindow> {
    let n = ((cols.1 - cols.0 + 1) * rows) as f64;
    if master.valid.sum(band, cols) < n - 0.5 {
        return None;
    }
    let sum = master.sum.sum(band, cols);
    let variance_n = master.sq.sum(band, cols) - sum * sum / n;
    (variance_n >= min_variance * n).then_some(MasterWindow {
        band,
        cols,
        n,
        sum,
        variance_n,
    })
}

/// NCC (eq. 17) of the master's window and one slave, from the slave's tables and the table of products; `None`
/// when the slave has an invalid sample in the window. A flat slave patch correlates 0.
#[inline]
pub fn ncc(master: &MasterWindow, slave: &PatchSums, cross: &BandSums) -> Option<f64> {
    let MasterWindow {
        band,
        cols,
        n,
        sum: sm,
        variance_n: vm,
    } = *master;
    if slave.valid.sum(band, cols) < n - 0.5 {
        return None;
    }
    let ss = slave.sum.sum(band, cols);
    let vs = slave.sq.sum(band, cols) - ss * ss / n;
    if vs < MIN_VARIANCE * n {
        return Some(0.0);
    }
    let cov = cross.sum(band, cols) - sm * ss / n;
    Some((cov / (vm * vs).sqrt()).clamp(-1.0, 1.0))
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

    struct Tables {
        bands: Bands,
        m: PatchSums,
        s: PatchSums,
        cross: BandSums,
    }

    fn tables(w: usize, h: usize, rows: &[(usize, usize)], m: &[f32], s: &[f32]) -> Tables {
        let mut bands = Bands::default();
        for &r in rows {
            bands.index(r);
        }
        bands.seal();
        let (mut s3, mut s1) = (BandScratch::default(), BandScratch::default());
        let mut t = Tables {
            bands: Bands::default(),
            m: PatchSums::default(),
            s: PatchSums::default(),
            cross: BandSums::default(),
        };
        t.m.build(w, h, &bands, &mut s3, m);
        t.s.build(w, h, &bands, &mut s3, s);
        build_cross(w, h, &bands, &mut s1, m, s, &mut t.cross);
        t.bands = bands;
        t
    }

    #[test]
    fn windowed_ncc_equals_the_direct_formula_in_every_band() {
        let (w, h) = (13, 9);
        let m: Vec<f32> = (0..w * h).map(|k| ((k * 37 % 101) as f32).sin() * 50.0 + 100.0).collect();
        let s: Vec<f32> = m.iter().enumerate().map(|(k, &x)| 0.7 * x + 20.0 + ((k * 11 % 7) as f32)).collect();
        let rows = [(1, 7), (0, 3), (4, 8), (2, 2)];
        let t = tables(w, h, &rows, &m, &s);
        for (band, &rows) in rows.iter().enumerate() {
            let cols = (2, 10);
            let pick = |g: &[f32]| -> Vec<f32> {
                (rows.0..=rows.1)
                    .flat_map(|r| (cols.0..=cols.1).map(move |c| (r, c)))
                    .map(|(r, c)| g[r * w + c])
                    .collect()
            };
            let expected = direct(&pick(&m), &pick(&s));
            let window = master_window(&t.m, band, cols, t.bands.rows(band), MIN_VARIANCE).expect("textured");
            let got = ncc(&window, &t.s, &t.cross).unwrap();
            assert!((got - expected).abs() < 1e-9, "band {rows:?}: {got} vs {expected}");
        }
    }

    #[test]
    fn an_invalid_sample_drops_the_slave_and_a_flat_slave_correlates_zero() {
        let (w, h) = (5, 5);
        let m: Vec<f32> = (0..25).map(|k| k as f32).collect();
        let mut s = m.clone();
        s[12] = f32::NAN;
        let t = tables(w, h, &[(0, 4), (0, 1)], &m, &s);
        let (whole, top) = (
            master_window(&t.m, 0, (0, 4), 5, MIN_VARIANCE).unwrap(),
            master_window(&t.m, 1, (0, 4), 2, MIN_VARIANCE).unwrap(),
        );
        assert_eq!(ncc(&whole, &t.s, &t.cross), None);
        assert!(ncc(&top, &t.s, &t.cross).unwrap() > 0.999);
        let t = tables(w, h, &[(0, 4)], &m, &[7.0f32; 25]);
        assert_eq!(ncc(&whole, &t.s, &t.cross), Some(0.0));
        // A flat master window carries nothing to correlate.
        let flat = tables(w, h, &[(0, 4)], &[7.0f32; 25], &m);
        assert!(master_window(&flat.m, 0, (0, 4), 5, MIN_VARIANCE).is_none());
    }
}
