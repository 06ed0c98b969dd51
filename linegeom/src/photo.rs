//! An image's grey values as the appearance tests sample them, and the correlation of two grids of samples.
use std::ops::Range;

/// An image's 8-bit grey values, row-major.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Photo {
    width: usize,
    height: usize,
    gray: Vec<u8>,
}

impl Photo {
    /// The photo of `gray`, if it holds `width × height` values.
    pub fn new(width: usize, height: usize, gray: Vec<u8>) -> Option<Self> {
        (width >= 2 && height >= 2 && gray.len() == width * height).then_some(Photo { width, height, gray })
    }

    /// Bilinear grey value at pixel position `px` (pixel centres at integer values, as in the conventions), if
    /// inside the image.
    pub fn sample(&self, px: [f64; 2]) -> Option<f32> {
        let v = lineflow_imaging::bilinear(&self.gray, self.width, self.height, px[0] as f32, px[1] as f32);
        (!v.is_nan()).then_some(v)
    }
}

/// Every `KNOT`-th sample of a grid's row is projected through the camera model and those between are
/// interpolated: over a few pixels the projection bends too little to matter, and the full model costs most of an
/// appearance test.
const KNOT: usize = 8;

/// The grey values of a grid of `len` object points in rows of `cols` (`len` a multiple of `cols`), the points
/// of a row along a straight line, where `project(k)` puts point `k` in `photo` (NaN where it does not show it). Only
/// every [`KNOT`]-th point of a row and its last are projected; the rest are interpolated between them.
pub fn sample_rows(photo: &Photo, len: usize, cols: usize, project: impl Fn(usize) -> Option<[f64; 2]>) -> Vec<f32> {
    let value = |px: Option<[f64; 2]>| px.and_then(|q| photo.sample(q)).unwrap_or(f32::NAN);
    let mut out = Vec::with_capacity(len);
    for first in (0..len).step_by(cols.max(1)) {
        let knots = (0..cols).step_by(KNOT).chain(std::iter::once(cols - 1));
        let mut from = 0;
        let mut a = project(first);
        out.push(value(a));
        for to in knots.skip(1) {
            if to == from {
                continue;
            }
            let b = project(first + to);
            for c in from + 1..=to {
                let f = (c - from) as f64 / (to - from) as f64;
                out.push(value(a.zip(b).map(|(a, b)| [a[0] + f * (b[0] - a[0]), a[1] + f * (b[1] - a[1])])));
            }
            (from, a) = (to, b);
        }
    }
    out
}

/// The variance of the finite values among the rows `rows` of a grid of `cols` columns, and how many there are
/// (0 for fewer than two).
pub fn variance(values: &[f32], cols: usize, rows: Range<usize>) -> (f32, usize) {
    let v = values[rows.start * cols..rows.end * cols].iter().filter(|x| x.is_finite());
    let (sum, n) = v.clone().fold((0.0, 0), |(s, n), x| (s + x, n + 1));
    if n < 2 {
        return (0.0, n);
    }
    let mean = sum / n as f32;
    (v.map(|x| (x - mean) * (x - mean)).sum::<f32>() / n as f32, n)
}

/// Normalised cross-correlation of the rows `ra` of grid `a` with the rows `rb` (as many) of grid `b`, over the
/// samples both show (not NaN). None when they share less than half of them, or either is flat there: an image
/// that sees part of a line still has its say on that part.
pub fn ncc(a: &[f32], ra: Range<usize>, b: &[f32], rb: Range<usize>, cols: usize) -> Option<f64> {
    let (a, b) = (&a[ra.start * cols..ra.end * cols], &b[rb.start * cols..rb.end * cols]);
    let both = || a.iter().zip(b).filter(|(x, y)| x.is_finite() && y.is_finite());
    let n = both().count();
    if n < 4 || 2 * n < a.len() {
        return None;
    }
    let (sa, sb) = both().fold((0.0, 0.0), |(sa, sb), (&x, &y)| (sa + x as f64, sb + y as f64));
    let (ma, mb) = (sa / n as f64, sb / n as f64);
    let (mut sab, mut saa, mut sbb) = (0.0, 0.0, 0.0);
    for (&x, &y) in both() {
        let (dx, dy) = (x as f64 - ma, y as f64 - mb);
        sab += dx * dy;
        saa += dx * dx;
        sbb += dy * dy;
    }
    (saa > 1e-9 && sbb > 1e-9).then(|| sab / (saa * sbb).sqrt())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bilinear_samples_at_pixel_centres_and_between() {
        let p = Photo::new(2, 2, vec![0, 100, 200, 50]).unwrap();
        assert_eq!(p.sample([0.0, 0.0]), Some(0.0));
        assert_eq!(p.sample([0.5, 0.0]), Some(50.0));
        assert!((p.sample([0.5, 0.5]).unwrap() - 87.5).abs() < 1e-4);
        assert_eq!(p.sample([-0.1, 0.0]), None);
        assert_eq!(p.sample([1.0, 1.0]), None, "the last centre has no neighbour to interpolate with");
        assert!(Photo::new(3, 2, vec![0; 5]).is_none());
    }

    #[test]
    fn correlation_of_a_pattern_with_itself_its_negative_and_a_flat_grid() {
        let a: Vec<f32> = (0..12).map(|i| (i * 7 % 5) as f32).collect();
        let neg: Vec<f32> = a.iter().map(|x| 10.0 - x).collect();
        assert!((ncc(&a, 0..3, &a, 0..3, 4).unwrap() - 1.0).abs() < 1e-12);
        assert!((ncc(&a, 0..3, &neg, 0..3, 4).unwrap() + 1.0).abs() < 1e-12);
        assert!(ncc(&a, 0..3, &[3.0; 12], 0..3, 4).is_none());
        // Half of `b` unseen: compared on the rest; more than half unseen: no say.
        let mut half: Vec<f32> = a.clone();
        half[..6].fill(f32::NAN);
        assert!((ncc(&a, 0..3, &half, 0..3, 4).unwrap() - 1.0).abs() < 1e-12);
        half[6] = f32::NAN;
        assert!(ncc(&a, 0..3, &half, 0..3, 4).is_none());
        // Row 1 of `a` is row 0 of `b`: the two match best one row apart.
        let b: Vec<f32> = a[4..].iter().chain(&a[..4]).copied().collect();
        assert!((ncc(&a, 1..3, &b, 0..2, 4).unwrap() - 1.0).abs() < 1e-12);
        assert_eq!(variance(&[1.0, 3.0, 5.0, 7.0], 2, 0..1), (1.0, 2));
        let (v, n) = variance(&[1.0, f32::NAN, 5.0, 7.0], 2, 0..2);
        assert!((v - 56.0 / 9.0).abs() < 1e-5 && n == 3, "the NaN left out: {v} of {n}");
    }
}
