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
    let columns = with_counts(ranges(taken.iter().map(|b| [b[0], b[1]])), |found| {
        repeated(found, across, view.sizes.opening_m.0)
    });
    // A storey is known from two of its openings (in any of its rows, [`storey_count`]); one alone may be anything
    // at the height of nothing else (a balcony's rail, the panes above a door), and one the storeys' spacing
    // predicts is known from none, so their cells need all four sides seen.
    let lying = view.lying.iter().chain(&view.lying_on_wall);
    let height = span(lying.map(|s| s.at));
    let rows = with_counts(ranges(taken.iter().map(|b| [b[2], b[3]])), |found| {
        repeated(found, height, view.sizes.opening_m.0)
    });
    let overlaps = |a: &[f64; 4], b: &[f64; 4]| a[0] < b[1] && b[0] < a[1] && a[2] < b[3] && b[2] < a[3];
    let mut out: Vec<Rect> = Vec::new();
    for &([x0, x1], _) in &columns {
        for &([z0, z1], _) in &rows {
            let openings = storey_count(&rows, [z0, z1]);
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

/// The openings found in the storey of row `range`: its own and those of every row sharing most of its height (a
/// foot found on a sill's lower edge, 9 cm below the others, makes a row of its own, yet the storey is known from
/// both).
fn storey_count(rows: &[([f64; 2], usize)], range: [f64; 2]) -> usize {
    let shared = |r: &[f64; 2]| r[1].min(range[1]) - r[0].max(range[0]);
    rows.iter()
        .filter(|(r, _)| shared(r) >= STOREY_SHARE * (r[1] - r[0]).min(range[1] - range[0]))
        .map(|(_, n)| n)
        .sum()
}

/// Rows sharing this much of the shorter one's height are one storey ([`storey_count`]).
pub(super) const STOREY_SHARE: f64 = 0.8;

/// The distinct intervals among `intervals`: those whose ends both lie within [`GRID_TOLERANCE_M`] of a group's
/// mean are one, at their mean. In order of their start.
fn ranges(intervals: impl Iterator<Item = [f64; 2]>) -> Vec<([f64; 2], usize)> {
    let mut sorted: Vec<[f64; 2]> = intervals.collect();
    sorted.sort_by(|a, b| a[0].total_cmp(&b[0]).then(a[1].total_cmp(&b[1])));
    let mut groups: Vec<([f64; 2], [f64; 2], f64)> = Vec::new();
    for r in sorted {
        // Against the group's mean, not its first: a cluster's first member may lie at its edge.
        let near = |g: &&mut ([f64; 2], [f64; 2], f64)| {
            (g.1[0] / g.2 - r[0]).abs() <= GRID_TOLERANCE_M && (g.1[1] / g.2 - r[1]).abs() <= GRID_TOLERANCE_M
        };
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

/// The ranges `extend` makes of the `found` ones, each with the number of openings found in it (none for those
/// it adds), those of more openings first: where two ranges of one storey or bay overlap (a foot found 8 cm lower
/// on two of its five windows), the cells take the one most openings share. A range's count is found by equality:
/// `extend` returns the ranges it is given unchanged ([`repeated`]).
fn with_counts(found: Vec<([f64; 2], usize)>, extend: impl FnOnce(Vec<[f64; 2]>) -> Vec<[f64; 2]>) -> Vec<([f64; 2], usize)> {
    let mut out: Vec<([f64; 2], usize)> = extend(found.iter().map(|f| f.0).collect())
        .into_iter()
        .map(|r| (r, found.iter().find(|f| f.0 == r).map_or(0, |f| f.1)))
        .collect();
    out.sort_by(|a, b| b.1.cmp(&a.1).then(a.0[0].total_cmp(&b.0[0])).then(a.0[1].total_cmp(&b.0[1])));
    out
}

/// The sorted `points` with those within [`GRID_TOLERANCE_M`] of their neighbour's group mean made one, at their
/// mean.
fn merged_points(points: &[f64]) -> Vec<f64> {
    let mut groups: Vec<(f64, f64)> = Vec::new();
    for &p in points {
        match groups.last_mut() {
            Some(g) if (g.0 / g.1 - p).abs() <= GRID_TOLERANCE_M => *g = (g.0 + p, g.1 + 1.0),
            _ => groups.push((p, 1.0)),
        }
    }
    groups.into_iter().map(|(sum, n)| sum / n).collect()
}

/// The smallest and largest of `values`.
fn span(values: impl Iterator<Item = f64>) -> [f64; 2] {
    values.fold([f64::INFINITY, f64::NEG_INFINITY], |[lo, hi], v| [lo.min(v), hi.max(v)])
}

/// `ranges` and the ones their spacing predicts within `[lo, hi]`: where the ranges' centres lie on a lattice of one
/// period of at least `min_period` (bays of windows, a storey's height; [`lattice`]), the ranges at the lattice's
/// empty places, at the ranges' mean size. As found where the centres share no period.
fn repeated(ranges: Vec<[f64; 2]>, [lo, hi]: [f64; 2], min_period: f64) -> Vec<[f64; 2]> {
    // Centres, not starts: a range found on the glazing and one on the opening's edge share their centre (and a
    // door and the windows above it, ranges of different widths). Centres within the tolerance are one.
    let mut centres: Vec<f64> = ranges.iter().map(|r| (r[0] + r[1]) / 2.0).collect();
    centres.sort_by(f64::total_cmp);
    let centres = merged_points(&centres);
    let Some(Lattice { period, phase }) = lattice(&centres, min_period) else {
        return ranges;
    };
    let half = ranges.iter().map(|r| r[1] - r[0]).sum::<f64>() / ranges.len() as f64 / 2.0;
    let mut centre = phase + ((lo + half - GRID_TOLERANCE_M - phase) / period).ceil() * period;
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

/// Places `phase + k · period`, integer k.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) struct Lattice {
    pub(super) period: f64,
    pub(super) phase: f64,
}

/// The lattice the sorted `centres` lie on: the longest period of at least `min_period`, among every gap between
/// two centres divided by 1 to 6, on whose places (within [`GRID_TOLERANCE_M`]) the most centres lie, refined by
/// least squares over them, with at least a third of its places between the first and the last of them taken. One
/// centre in four may lie off it (an opening found a few decimetres off, a door among windows); more, and there is
/// none. None for fewer than two centres.
pub(super) fn lattice(centres: &[f64], min_period: f64) -> Option<Lattice> {
    if centres.len() < 2 {
        return None;
    }
    let on = |l: &Lattice| -> Vec<(f64, f64)> {
        centres
            .iter()
            .map(|&c| ((c - l.phase) / l.period).round())
            .zip(centres)
            .filter(|&(k, &c)| (c - l.phase - k * l.period).abs() <= GRID_TOLERANCE_M)
            .map(|(k, &c)| (k, c))
            .collect()
    };
    // c = phase + k · period by least squares over the centres on the lattice.
    let refit = |l: Lattice| -> Lattice {
        let points = on(&l);
        let n = points.len() as f64;
        let (sk, sc) = points.iter().fold((0.0, 0.0), |(a, b), p| (a + p.0, b + p.1));
        let (skk, skc) = points.iter().fold((0.0, 0.0), |(a, b), p| (a + p.0 * p.0, b + p.0 * p.1));
        let det = n * skk - sk * sk;
        if points.len() < 2 || det.abs() < 1e-12 {
            return l;
        }
        let period = (n * skc - sk * sc) / det;
        Lattice {
            period,
            phase: (sc - period * sk) / n,
        }
    };
    let mut best: Option<(usize, Lattice)> = None;
    for (i, &a) in centres.iter().enumerate() {
        for &b in &centres[i + 1..] {
            for k in 1..=6 {
                let period = (b - a) / k as f64;
                if period < min_period {
                    break;
                }
                let l = refit(refit(Lattice { period, phase: a }));
                let places = on(&l);
                let count = places.len();
                // A third of the places between the first and last centre on it taken: a short period fits some
                // centres of any set by chance, leaving most of its places empty.
                let spanned = places.iter().map(|p| p.0).fold(f64::NEG_INFINITY, f64::max)
                    - places.iter().map(|p| p.0).fold(f64::INFINITY, f64::min)
                    + 1.0;
                if 3.0 * (count as f64) < spanned {
                    continue;
                }
                let better = match best {
                    None => true,
                    Some((n, old)) => count > n || (count == n && l.period > old.period + GRID_TOLERANCE_M),
                };
                if better && l.period >= min_period {
                    best = Some((count, l));
                }
            }
        }
    }
    let (count, l) = best?;
    (count >= 2 && 4 * count >= 3 * centres.len()).then_some(l)
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_storey_counts_the_openings_of_every_row_sharing_most_of_its_height() {
        // A ground floor found twice, once on the opening's foot and once on its sill's lower edge 9 cm below, and
        // the storey above it: the two lower rows are one storey of two openings, the upper row one of three.
        let rows = [([0.67, 1.95], 1), ([0.57, 1.95], 1), ([3.95, 5.28], 3)];
        assert_eq!(storey_count(&rows, [0.67, 1.95]), 2);
        assert_eq!(storey_count(&rows, [0.57, 1.95]), 2);
        assert_eq!(storey_count(&rows, [3.95, 5.28]), 3);
        // A row overlapping another by less than STOREY_SHARE of the shorter is another storey (a door beside
        // windows set higher).
        let rows = [([0.0, 2.2], 1), ([1.2, 2.5], 2)];
        assert_eq!(storey_count(&rows, [0.0, 2.2]), 1);
        assert_eq!(storey_count(&rows, [1.2, 2.5]), 2);
    }
}
