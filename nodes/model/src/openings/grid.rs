//! Rule three: the rows and columns of the openings found on a wall predict the ones missed. A façade repeats its
//! openings: the windows of a storey share their head and foot, those of a bay their sides. Where the lines of one
//! opening did not make a rectangle (a side unmatched, a foot hidden by its sill), the row and column it sits in say
//! where its outline is, and the edges seen there (the 3-D lines', or the images' 2-D lines where the 3-D lines
//! missed a side: [`super::evidence`]) decide.
use super::*;

/// The openings predicted on `view`'s wall by the rows and columns of those already `taken` there (bounds
/// `[x0, x1, z0, z1]` in the wall's coordinates): every cell of a column (openings whose sides lie within
/// [`GRID_TOLERANCE_M`]) and a row (likewise their foot and top) that overlaps no opening, and where at least three
/// of the four sides are seen ([`seen_sides`]: by the 3-D lines, or where they missed a side, by the images'
/// 2-D lines when `evidence` is given) and the wall's courses do not run through it
/// ([`WallView::courses_within`]). A cell takes the mean sides of its column and row. `near` is a point near the
/// wall (the cameras' mean centre).
pub(super) fn from_grid(view: &WallView, taken: &[[f64; 4]], near: &Vec3, evidence: Option<&Evidence>) -> Vec<Rect> {
    let standing = view.standing.iter().chain(&view.standing_on_wall);
    let across = span(standing.map(|s| s.at));
    let columns = repeated(
        ranges(taken.iter().map(|b| [b[0], b[1]])).into_iter().map(|(r, _)| r).collect(),
        across,
        view.sizes.opening_m.0,
    );
    // A storey is known from two of its openings; one alone may be anything at the height of nothing else (a
    // balcony's rail, the panes above a door), so its cells need all four sides seen.
    let rows = ranges(taken.iter().map(|b| [b[2], b[3]]));
    let overlaps = |a: &[f64; 4], b: &[f64; 4]| a[0] < b[1] && b[0] < a[1] && a[2] < b[3] && b[2] < a[3];
    let mut out: Vec<Rect> = Vec::new();
    for &[x0, x1] in &columns {
        for &([z0, z1], openings) in &rows {
            let bounds = [x0, x1, z0, z1];
            if taken.iter().chain(out.iter().map(|r| &r.bounds)).any(|b| overlaps(b, &bounds)) {
                continue;
            }
            let seen = seen_sides(view, bounds, near, evidence);
            if seen >= if openings >= 2 { 3 } else { 4 } && view.courses_within(bounds, FLUSH_END_REACH_M / 2.0) <= MAX_FLUSH_LEVELS {
                out.push(Rect {
                    bounds,
                    on_wall: [true; 4],
                });
            }
        }
    }
    out
}

/// The distinct intervals among `intervals`: those whose ends both lie within [`GRID_TOLERANCE_M`] of a group's
/// first are one, at their mean. In order of their start.
fn ranges(intervals: impl Iterator<Item = [f64; 2]>) -> Vec<([f64; 2], usize)> {
    let mut sorted: Vec<[f64; 2]> = intervals.collect();
    sorted.sort_by(|a, b| a[0].total_cmp(&b[0]).then(a[1].total_cmp(&b[1])));
    let mut groups: Vec<([f64; 2], [f64; 2], f64)> = Vec::new();
    for r in sorted {
        let near =
            |g: &&mut ([f64; 2], [f64; 2], f64)| (g.0[0] - r[0]).abs() <= GRID_TOLERANCE_M && (g.0[1] - r[1]).abs() <= GRID_TOLERANCE_M;
        match groups.iter_mut().find(near) {
            Some(g) => {
                g.1 = [g.1[0] + r[0], g.1[1] + r[1]];
                g.2 += 1.0;
            }
            None => groups.push((r, r, 1.0)),
        }
    }
    groups
        .into_iter()
        .map(|(_, sum, n)| ([sum[0] / n, sum[1] / n], n as usize))
        .collect()
}

/// The smallest and largest of `values`.
fn span(values: impl Iterator<Item = f64>) -> [f64; 2] {
    values.fold([f64::INFINITY, f64::NEG_INFINITY], |[lo, hi], v| [lo.min(v), hi.max(v)])
}

/// `ranges` and the ones their spacing predicts within `within`: where the gaps between consecutive ranges are all
/// whole multiples (within [`GRID_TOLERANCE_M`]) of one period of at least `min_period` (bays of windows, a
/// storey's height), the ranges the missing multiples stand for, at the ranges' mean size. As found where the gaps
/// share no period.
fn repeated(ranges: Vec<[f64; 2]>, [lo, hi]: [f64; 2], min_period: f64) -> Vec<[f64; 2]> {
    // Centres, not starts: a range found on the glazing and one on the opening's edge share their centre.
    let centres: Vec<f64> = ranges.iter().map(|r| (r[0] + r[1]) / 2.0).collect();
    let Some(period) = period(&centres, min_period) else {
        return ranges;
    };
    let half = ranges.iter().map(|r| r[1] - r[0]).sum::<f64>() / ranges.len() as f64 / 2.0;
    let mut centre = centres[0] - ((centres[0] - half - lo) / period).floor() * period;
    let mut out = ranges.clone();
    while centre + half <= hi + GRID_TOLERANCE_M {
        if !centres.iter().any(|c| (c - centre).abs() <= GRID_TOLERANCE_M) {
            out.push([centre - half, centre + half]);
        }
        centre += period;
    }
    out.sort_by(|a, b| a[0].total_cmp(&b[0]));
    out
}

/// The period of the sorted `starts` (centres): the longest p of at least `min_period` that every gap between
/// neighbours is a whole multiple of (within [`GRID_TOLERANCE_M`]), from the shortest gap divided by 1 to 6
/// and refined by least squares over all the gaps. None for fewer than two starts.
pub(super) fn period(starts: &[f64], min_period: f64) -> Option<f64> {
    if starts.len() < 2 {
        return None;
    }
    let gaps: Vec<f64> = starts.windows(2).map(|w| w[1] - w[0]).collect();
    let shortest = gaps.iter().copied().fold(f64::INFINITY, f64::min);
    (1..=6).map(|k| shortest / k as f64).take_while(|&p| p >= min_period).find_map(|p| {
        let multiples: Vec<f64> = gaps.iter().map(|g| (g / p).round()).collect();
        let refined = gaps.iter().zip(&multiples).map(|(g, n)| g * n).sum::<f64>() / multiples.iter().map(|n| n * n).sum::<f64>();
        let fits = gaps
            .iter()
            .zip(&multiples)
            .all(|(g, n)| (g - n * refined).abs() <= GRID_TOLERANCE_M);
        fits.then_some(refined)
    })
}

/// How many sides of the rectangle `[x0, x1, z0, z1]` are seen: edges on the wall or behind it run along the
/// side (within [`GRID_TOLERANCE_M`] across, over at least [`MIN_STANDING_COVER`] of the side, and ending within
/// [`MAX_SIDE_GAP_M`] of its ends: a course running across the wall past the opening is none of its sides), or,
/// where none does, the images show it within [`GRID_TOLERANCE_M`] ([`Evidence::measure`]). The sides stay where
/// the grid predicts them: the images' strongest lines at an opening are often the glazing's, a frame's width in.
fn seen_sides(view: &WallView, [x0, x1, z0, z1]: [f64; 4], near: &Vec3, evidence: Option<&Evidence>) -> usize {
    let in_3d = |sides: &[&Vec<Side>], at: f64, lo: f64, hi: f64| {
        sides
            .iter()
            .flat_map(|s| s.iter())
            .any(|s| (s.at - at).abs() <= GRID_TOLERANCE_M && s.cover(lo, hi) >= MIN_STANDING_COVER && ends_within(s, lo, hi))
    };
    let wall = &view.wall;
    let in_images = |a: (f64, f64), b: (f64, f64), across: Vec3| {
        evidence.is_some_and(|e| {
            e.measure(&wall.point(a.0, a.1, near), &wall.point(b.0, b.1, near), &across, GRID_TOLERANCE_M)
                .seen()
        })
    };
    let standing = [&view.standing, &view.standing_on_wall];
    let lying = [&view.lying, &view.lying_on_wall];
    [
        in_3d(&standing, x0, z0, z1) || in_images((x0, z0), (x0, z1), wall.across),
        in_3d(&standing, x1, z0, z1) || in_images((x1, z0), (x1, z1), wall.across),
        in_3d(&lying, z0, x0, x1) || in_images((x0, z0), (x1, z0), Vec3::z()),
        in_3d(&lying, z1, x0, x1) || in_images((x0, z1), (x1, z1), Vec3::z()),
    ]
    .into_iter()
    .filter(|&s| s)
    .count()
}
