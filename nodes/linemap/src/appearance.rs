//! The images' verdict on a line's depth. Among repeated parallel lines (brick courses, glazing bars) a line
//! matched one line off between two strips lies at a wrong depth that every image's segments confirm alike; only
//! the grey values can tell. A thin ribbon of object space along the line, a few pixels to either side, is sampled
//! in the image that sees the line longest and in every other image given (the caller passes those that see at
//! least half of it; each is compared on the part it shows): at the right
//! depth each image shows the same pattern there (the bricks above and below a course, with their joints and
//! tints), at a wrong one the images of the other strip show the neighbouring course. Each side of the line is
//! compared on its own, and the better side counts, because an edge between two surfaces may have its far side
//! hidden, or seen against another background, from some of the images.
use lineflow_photogrammetry::{median, Camera, Vec3};

use lineflow_linegeom::photo::{ncc, sample_rows, variance};

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
        .map(|r| variance(&base, grid.cols, r.clone()).0 >= p.min_variance)
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

    /// The ribbon's grey values in `view` (NaN where its photo does not show the point), if it has a photo.
    fn sample(&self, camera: &Camera, view: &View) -> Option<Vec<f32>> {
        let photo = view.photo.as_deref()?;
        Some(sample_rows(photo, self.points.len(), self.cols, |k| {
            view.pose.project(camera, &self.points[k])
        }))
    }
}
