//! The images' verdict on a line's depth. Among repeated parallel lines (brick courses, glazing bars) a line
//! matched one line off between two strips lies at a wrong depth that every image's segments confirm alike; only
//! the grey values can tell. A thin ribbon of object space along the line, a few pixels to either side, is sampled
//! in the image that sees the line longest and in every other image given (the caller passes those that see at
//! least half of it; each is compared on the part it shows): at the right
//! depth each image shows the same pattern there (the bricks above and below a course, with their joints and
//! tints), at a wrong one the images of the other strip show the neighbouring course. Each side of the line is
//! compared on its own, and the better side counts, because an edge between two surfaces may have its far side
//! hidden, or seen against another background, from some of the images.
use lineflow_photogrammetry::{Camera, Vec3};

use crate::views::View;

/// Settings of the test.
#[derive(Debug, Clone, Copy)]
pub struct AppearanceParams {
    /// Rows of the ribbon on either side of the line, pixels of the reference image.
    pub half_width_px: usize,
    /// Most samples along the line (a longer line is sampled more sparsely).
    pub max_samples: usize,
    /// Grey-value variance a side needs in the reference image to be compared at all.
    pub min_variance: f32,
    /// The other images' ribbons are also compared shifted by up to this many rows either way, to find where they
    /// match best (a line at a slightly wrong depth matches best off its own position in the images that see its
    /// depth).
    pub search_px: usize,
}

impl Default for AppearanceParams {
    fn default() -> Self {
        AppearanceParams {
            half_width_px: 3,
            max_samples: 64,
            min_variance: 4.0,
            search_px: 2,
        }
    }
}

/// What the images say of a line: for each image compared with the reference, the better side's normalised
/// cross-correlation.
#[derive(Debug, Clone, PartialEq)]
pub struct Verdict {
    /// The reference view (index into the views).
    pub reference: usize,
    /// (view, correlation) of every other image with a photo that shows at least half of the ribbon.
    pub correlations: Vec<(usize, f64)>,
    /// The shift across the line, reference pixels, at which each of those images matches best.
    pub shifts: Vec<i32>,
}

impl Verdict {
    /// The median correlation, if any image was compared.
    pub fn median(&self) -> Option<f64> {
        median(self.correlations.iter().map(|&(_, c)| c).collect())
    }

    /// The median distance of the best match from the line, pixels, if any image was compared.
    pub fn median_offset(&self) -> Option<f64> {
        median(self.shifts.iter().map(|&d| d.unsigned_abs() as f64).collect())
    }
}

/// Compares the ribbon along `ends` in the views `seen_by` (indices into `views`; the stage passes those that see
/// at least half of the line). None when fewer than two of them have a photo, or the reference shows too little texture on both
/// sides to compare: no verdict.
pub fn compare(camera: &Camera, views: &[View], seen_by: &[usize], ends: &[Vec3; 2], p: &AppearanceParams) -> Option<Verdict> {
    compare_until(camera, views, seen_by, ends, p, None)
}

/// Whether the images agree along `ends` (as [`compare`]): the median correlation reaches `min_correlation` and the
/// median best shift is within `max_offset_px`, or there is no verdict. Stops comparing once the answer is no.
pub fn agrees(
    camera: &Camera,
    views: &[View],
    seen_by: &[usize],
    ends: &[Vec3; 2],
    p: &AppearanceParams,
    min_correlation: f64,
    max_offset_px: f64,
) -> bool {
    compare_until(camera, views, seen_by, ends, p, Some((min_correlation, max_offset_px)))
        .is_none_or(|v| v.median().is_none_or(|c| c >= min_correlation) && v.median_offset().is_none_or(|d| d <= max_offset_px))
}

/// [`compare`], stopping early once more than half of the images fall below `stop`'s correlation or beyond its
/// offset (the medians then reject whatever the rest say).
fn compare_until(
    camera: &Camera,
    views: &[View],
    seen_by: &[usize],
    ends: &[Vec3; 2],
    p: &AppearanceParams,
    stop: Option<(f64, f64)>,
) -> Option<Verdict> {
    let with_photo: Vec<usize> = seen_by.iter().copied().filter(|&k| views[k].photo.is_some()).collect();
    if with_photo.len() < 2 {
        return None;
    }
    let projected_px = |k: usize| -> f64 {
        let v = &views[k];
        match (v.pose.project(camera, &ends[0]), v.pose.project(camera, &ends[1])) {
            (Some(a), Some(b)) => (b[0] - a[0]).hypot(b[1] - a[1]),
            _ => 0.0,
        }
    };
    // The reference is the image that sees the line longest and shows its whole ribbon; ties go to the lowest
    // index, so that the verdict does not depend on the order of `seen_by`.
    let mut by_length: Vec<(usize, f64)> = with_photo.iter().map(|&k| (k, projected_px(k))).collect();
    by_length.sort_by(|a, b| b.1.total_cmp(&a.1).then(a.0.cmp(&b.0)));
    let (reference, grid, base) = by_length.iter().find_map(|&(k, len)| {
        let grid = Ribbon::new(camera, &views[k], ends, len, p)?;
        let base = grid.sample(camera, &views[k])?;
        base.iter().all(|v| v.is_finite()).then_some((k, grid, base))
    })?;
    let sample = |k: usize| grid.sample(camera, &views[k]);
    let (h, search) = (p.half_width_px, p.search_px);
    // Rows of the two sides (each with the line's own row) in the unshifted window.
    let sides = [search..search + h + 1, search + h..search + 2 * h + 1];
    let textured: Vec<bool> = sides
        .iter()
        .map(|r| variance(&base, grid.cols, r.clone()) >= p.min_variance)
        .collect();
    if !textured.iter().any(|&t| t) {
        return None;
    }
    let others: Vec<usize> = with_photo.iter().copied().filter(|&k| k != reference).collect();
    let mut compared: Vec<(usize, f64, i32)> = Vec::with_capacity(others.len());
    let (mut low, mut off) = (0, 0);
    for &k in &others {
        let Some(other) = sample(k) else { continue };
        let at = |shift: i32| {
            sides
                .iter()
                .zip(&textured)
                .filter(|(_, &t)| t)
                .filter_map(|(r, _)| {
                    let moved = (r.start as i32 + shift) as usize..(r.end as i32 + shift) as usize;
                    ncc(&base, r.clone(), &other, moved, grid.cols)
                })
                .fold(f64::NEG_INFINITY, f64::max)
        };
        let here = at(0);
        if !here.is_finite() {
            continue;
        }
        // Smallest shift first, so that a tie keeps the line where it is.
        let (shift, _) = (1..=search as i32)
            .flat_map(|d| [-d, d])
            .map(|d| (d, at(d)))
            .fold((0, here), |best, c| if c.1 > best.1 { c } else { best });
        compared.push((k, here, shift));
        // More than half of every image that could still be compared already rejects: so does the median, of
        // these and of all.
        if let Some((min_correlation, max_offset)) = stop {
            low += (here < min_correlation) as usize;
            off += (shift.unsigned_abs() as f64 > max_offset) as usize;
            if 2 * low.max(off) > others.len() {
                break;
            }
        }
    }
    Some(Verdict {
        reference,
        correlations: compared.iter().map(|&(k, c, _)| (k, c)).collect(),
        shifts: compared.iter().map(|&(_, _, d)| d).collect(),
    })
}

fn median(mut values: Vec<f64>) -> Option<f64> {
    values.sort_by(f64::total_cmp);
    let n = values.len();
    (n > 0).then(|| {
        if n % 2 == 1 {
            values[n / 2]
        } else {
            0.5 * (values[n / 2 - 1] + values[n / 2])
        }
    })
}

/// The object-space sample points: `cols` along the line, `2·(half_width + search) + 1` rows across it, one
/// reference pixel apart across, in the plane through the line that faces the reference image.
struct Ribbon {
    points: Vec<Vec3>,
    cols: usize,
}

impl Ribbon {
    fn new(camera: &Camera, reference: &View, ends: &[Vec3; 2], length_px: f64, p: &AppearanceParams) -> Option<Self> {
        let along = ends[1] - ends[0];
        let mid = (ends[0] + ends[1]) * 0.5;
        let across = along.cross(&(mid - reference.pose.center)).try_normalize(1e-12)?;
        let step = reference.metres_per_px(camera, &mid);
        let cols = (length_px.floor() as usize).clamp(2, p.max_samples);
        let half = p.half_width_px + p.search_px;
        let h = half as f64;
        let points = (0..2 * half + 1)
            .flat_map(|r| {
                let offset = across * ((r as f64 - h) * step);
                (0..cols).map(move |c| ends[0] + along * ((c as f64 + 0.5) / cols as f64) + offset)
            })
            .collect();
        Some(Ribbon { points, cols })
    }

    /// The ribbon's grey values in `view` (NaN where its photo does not show the point), if it has a photo. Every
    /// `KNOT`-th point of a row is projected through the camera model and the points between are interpolated:
    /// the projection bends too little over a few pixels to matter, and the full model costs most of the test.
    fn sample(&self, camera: &Camera, view: &View) -> Option<Vec<f32>> {
        const KNOT: usize = 8;
        let photo = view.photo.as_deref()?;
        let value = |px: Option<[f64; 2]>| px.and_then(|q| photo.sample(q)).unwrap_or(f32::NAN);
        let mut out = Vec::with_capacity(self.points.len());
        for row in self.points.chunks(self.cols) {
            let knots = (0..self.cols).step_by(KNOT).chain(std::iter::once(self.cols - 1));
            let mut from = 0;
            let mut a = view.pose.project(camera, &row[0]);
            out.push(value(a));
            for to in knots.skip(1) {
                if to == from {
                    continue;
                }
                let b = view.pose.project(camera, &row[to]);
                for c in from + 1..=to {
                    let f = (c - from) as f64 / (to - from) as f64;
                    out.push(value(a.zip(b).map(|(a, b)| [a[0] + f * (b[0] - a[0]), a[1] + f * (b[1] - a[1])])));
                }
                (from, a) = (to, b);
            }
        }
        Some(out)
    }
}

fn variance(values: &[f32], cols: usize, rows: std::ops::Range<usize>) -> f32 {
    let v = &values[rows.start * cols..rows.end * cols];
    let n = v.len() as f32;
    let mean = v.iter().sum::<f32>() / n;
    v.iter().map(|x| (x - mean) * (x - mean)).sum::<f32>() / n
}

/// Normalised cross-correlation of the rows `ra` of grid `a` with the rows `rb` (as many) of grid `b`, over the
/// samples both show (not NaN). None when they share less than half of them, or either is flat there: an image
/// that sees part of a line still has its say on that part.
fn ncc(a: &[f32], ra: std::ops::Range<usize>, b: &[f32], rb: std::ops::Range<usize>, cols: usize) -> Option<f64> {
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
    }
}
