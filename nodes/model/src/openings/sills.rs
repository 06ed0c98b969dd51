//! Sills: the ledge under a window, standing proud of its wall. The 3-D lines hold its nose, one or two lying
//! edges in front of the wall just below the window's foot (its top and bottom arris), usually in pieces; its ends
//! and its thickness are seldom seen whole. Each wall's sills share their shape, so what the clearest of them show
//! (how far proud, how thick, how far past the window they reach) is taken for the others: a sill is built under
//! every window whose nose the lines show, as a box from the wall to its nose ([`add_sills`]).
use super::*;
use lineflow_photogrammetry::median;

/// The sills' rule (the model's parameters `sill_*`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct SillRule {
    /// How far in front of the wall a sill's nose lies, metres.
    pub(crate) proud_m: (f64, f64),
    /// How far below the window's foot the nose's top may lie, metres.
    pub(crate) reach_m: f64,
}

/// The nose's edges cover at least this share of the window's width.
const MIN_NOSE_COVER: f64 = 0.5;
/// Lying edges within this of each other in height are one arris of the nose, metres.
const LEVEL_TOLERANCE_M: f64 = 0.01;
/// The edges of a nose lie within this of each other in depth, metres.
const NOSE_DEPTH_TOLERANCE_M: f64 = 0.015;
/// A sill is at least this thick, metres (two arrises closer are one, seen twice)…
const MIN_THICKNESS_M: f64 = 0.02;
/// …and at most this.
const MAX_THICKNESS_M: f64 = 0.25;
/// How far above the window's foot the nose's top may lie, metres (the foot is a noisy corner too).
const ABOVE_FOOT_M: f64 = 0.02;
/// How far a sill reaches past its window on each side at most, metres.
const MAX_OVERHANG_M: f64 = 0.3;

/// What one window's lines show of its sill, in its wall's coordinates.
#[derive(Debug, Clone, PartialEq)]
struct Nose {
    /// The window's foot and its sides.
    foot: f64,
    x: (f64, f64),
    /// How far in front of the wall (positive).
    proud: f64,
    /// The heights of the nose's arrises: the upper one seen, and the one below it where it is seen too.
    arrises: (f64, Option<f64>),
    /// Lying edges behind the nose across the window's width: (height, depth) of each, the sill's line along the
    /// wall's face among them.
    along_wall: Vec<(f64, f64)>,
    /// How far the edges reach past the window's sides, where they do.
    overhang: [Option<f64>; 2],
}

/// The pieces gathered into levels from the top down: a piece joins the level above within
/// [`LEVEL_TOLERANCE_M`].
fn levels(mut pieces: Vec<&Piece>) -> Vec<Vec<&Piece>> {
    pieces.sort_by(|a, b| b.0.total_cmp(&a.0));
    let mut levels: Vec<Vec<&Piece>> = Vec::new();
    for p in pieces {
        match levels.last_mut() {
            Some(level) if level[0].0 - p.0 <= LEVEL_TOLERANCE_M => level.push(p),
            _ => levels.push(vec![p]),
        }
    }
    levels
}

/// The length-weighted mean of `f` over `pieces`.
fn weighted(pieces: &[&Piece], f: impl Fn(&Piece) -> f64) -> f64 {
    let length: f64 = pieces.iter().map(|p| p.3 - p.2).sum();
    pieces.iter().map(|p| f(p) * (p.3 - p.2)).sum::<f64>() / length
}

/// The nose under the window `[x0, x1, z0, z1]` among the lying pieces in front of its wall (`front`, depths
/// negative): the pieces below its foot within `rule.reach_m` overlapping it, at a depth whose edges cover
/// [`MIN_NOSE_COVER`] of its width, gathered into arrises by height; the arrises that cover as much count. The
/// depth is the one nearest `wall_proud` in front of the wall (its wall's sills' median) within twice
/// [`NOSE_DEPTH_TOLERANCE_M`], or without it the front-most (where the wall stands a little off its face, the
/// sill's line along the wall passes for a nose too, nearer the wall).
fn nose(front: &[Piece], on_wall: &[Piece], [x0, x1, z0, _]: [f64; 4], rule: SillRule, wall_proud: Option<f64>) -> Option<Nose> {
    let below: Vec<&Piece> = front
        .iter()
        .filter(|p| (z0 - rule.reach_m - MAX_THICKNESS_M..=z0 + ABOVE_FOOT_M).contains(&p.0) && p.3 > x0 && p.2 < x1)
        .filter(|p| (rule.proud_m.0..=rule.proud_m.1).contains(&-p.1))
        .collect();
    let cover = |ps: &[&Piece]| covered_share(&ps.iter().map(|p| (p.2, p.3)).collect::<Vec<_>>(), x0, x1);
    let at_depth = |d: f64| {
        below
            .iter()
            .copied()
            .filter(|p| (p.1 - d).abs() <= NOSE_DEPTH_TOLERANCE_M)
            .collect::<Vec<&Piece>>()
    };
    let mut depths: Vec<f64> = below.iter().map(|p| p.1).collect();
    depths.sort_by(f64::total_cmp);
    let mut covering = depths.into_iter().filter(|&d| cover(&at_depth(d)) >= MIN_NOSE_COVER);
    let depth = match wall_proud {
        Some(proud) => covering
            .filter(|d| (d + proud).abs() <= 2.0 * NOSE_DEPTH_TOLERANCE_M)
            .min_by(|a, b| (a + proud).abs().total_cmp(&(b + proud).abs()))?,
        None => covering.next()?,
    };
    let covering: Vec<Vec<&Piece>> = levels(at_depth(depth)).into_iter().filter(|l| cover(l) >= MIN_NOSE_COVER).collect();
    let top = covering.first()?;
    let upper = weighted(top, |p| p.0);
    if z0 - upper > rule.reach_m {
        return None;
    }
    let lower = covering[1..]
        .iter()
        .map(|level| (weighted(level, |p| p.0), level))
        .find(|(z, _)| (MIN_THICKNESS_M..=MAX_THICKNESS_M).contains(&(upper - z)));
    // A sill's top does not rise toward its nose. Where the line at which it meets the wall shows between the lower
    // arris and the upper one, below the foot, the upper one is no arris of the sill (the foot's own edge placed in
    // front of the wall: a lying line's depth is what a strip measures worst), and the top is at that line.
    let meets = lower.and_then(|(z, _)| {
        let band = on_wall
            .iter()
            .filter(|p| {
                (z + MIN_THICKNESS_M..=upper.min(z0) - LEVEL_TOLERANCE_M).contains(&p.0)
                    && p.2 >= x0 - MAX_OVERHANG_M
                    && p.3 <= x1 + MAX_OVERHANG_M
            })
            .collect();
        levels(band)
            .into_iter()
            .find(|l| cover(l) >= MIN_NOSE_COVER)
            .map(|l| weighted(&l, |p| p.0))
    });
    let (upper, proud) = match (meets, lower) {
        (Some(top), Some((_, level))) => (top, -weighted(level, |p| p.1)),
        _ => (upper, -weighted(top, |p| p.1)),
    };
    let lower = lower.map(|(z, _)| z);
    let along_wall = levels(below.iter().copied().filter(|p| p.1 - depth >= rule.proud_m.0).collect())
        .into_iter()
        .filter(|l| cover(l) >= MIN_NOSE_COVER)
        .map(|l| (weighted(&l, |p| p.0), weighted(&l, |p| p.1)))
        .collect();
    let used: Vec<&Piece> = covering.iter().flatten().copied().collect();
    let (lo, hi) = used
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), p| (lo.min(p.2), hi.max(p.3)));
    let past = |d: f64| (0.0..=MAX_OVERHANG_M).contains(&d).then_some(d);
    Some(Nose {
        foot: z0,
        x: (x0, x1),
        proud,
        arrises: (upper, lower),
        along_wall,
        overhang: [past(x0 - lo), past(hi - x1)],
    })
}

/// The sill boxes of one wall's windows (`windows`: their bounds), as their corners in the wall's coordinates
/// `[x0, x1, top, bottom, proud, back]`: each window whose nose the lines show gets one, shaped by the wall's sills
/// together. The sills that show both arrises give the thickness and how far below the foot the top lies (their
/// medians); a nose seen at one arris is the top or the bottom, whichever that places nearer. The back is the
/// sill's line along the wall where one is seen at the height of an arris (the wall's face), else the wall. The
/// sides reach past the window by the median of what the noses show. None on a wall where no sill shows both
/// arrises: how thick they are is unknown.
fn sill_boxes(front: &[Piece], on_wall: &[Piece], windows: &[[f64; 4]], rule: SillRule) -> Vec<[f64; 6]> {
    // Each nose where its wall's sills stand proud together: a line further out under one window (a lamp, a sign)
    // is no sill.
    let first: Vec<Nose> = windows.iter().filter_map(|&w| nose(front, on_wall, w, rule, None)).collect();
    let proud = median(first.iter().map(|n| n.proud).collect());
    let noses: Vec<Nose> = windows.iter().filter_map(|&w| nose(front, on_wall, w, rule, proud)).collect();
    let both = || noses.iter().filter_map(|n| Some((n.foot, n.arrises.0, n.arrises.1?)));
    let (Some(thickness), Some(drop)) = (
        median(both().map(|(_, a, b)| a - b).collect()),
        median(both().map(|(f, a, _)| f - a).collect()),
    ) else {
        return Vec::new();
    };
    let overhang = median(noses.iter().flat_map(|n| n.overhang).flatten().collect()).unwrap_or(0.0);
    noses
        .iter()
        .map(|n| {
            let (top, bottom) = match n.arrises {
                (upper, Some(lower)) => (upper, lower),
                (seen, None) if ((n.foot - seen) - drop).abs() <= ((n.foot - seen) - drop - thickness).abs() => (seen, seen - thickness),
                (seen, None) => (seen + thickness, seen),
            };
            let back = n
                .along_wall
                .iter()
                .find(|(z, _)| [top, bottom].iter().any(|a| (z - a).abs() <= LEVEL_TOLERANCE_M))
                .map_or(0.0, |l| l.1);
            [n.x.0 - overhang, n.x.1 + overhang, top, bottom, n.proud, back]
        })
        .collect()
}

/// Adds a sill under every window of the model that shows one ([`sill_boxes`]): its eight corners and twelve
/// edges, inferred. A door has none.
pub(crate) fn add_sills(
    walls: &[WallView],
    rule: SillRule,
    cos_par: f64,
    vertices: &mut Vec<Vertex>,
    edges: &mut Vec<Edge>,
    faces: &[Face],
) {
    let outlines = Outline::of_faces(faces, vertices);
    for view in walls {
        let wall = &view.wall;
        let front = pieces(
            wall,
            vertices,
            edges,
            false,
            (-rule.proud_m.1 - DEPTH_TOLERANCE_M, -rule.proud_m.0 + DEPTH_TOLERANCE_M),
        );
        let windows: Vec<[f64; 4]> = faces
            .iter()
            .zip(&outlines)
            .filter(|(f, o)| {
                f.kind == SurfaceKind::Window && f.normal.dot(&wall.out) > cos_par && wall.depth(&o.centroid).abs() < DEPTH_TOLERANCE_M
            })
            .map(|(_, o)| o.bounds_in(wall))
            .collect();
        // A window inside another is a pane of its frame.
        let inside =
            |[a0, a1, b0, b1]: [f64; 4], [x0, x1, z0, z1]: [f64; 4]| (a0, b0) != (x0, z0) && a0 >= x0 && a1 <= x1 && b0 >= z0 && b1 <= z1;
        let bounds: Vec<[f64; 4]> = windows
            .iter()
            .copied()
            .filter(|&b| !windows.iter().any(|&o| inside(b, o)))
            .collect();
        for [x0, x1, top, bottom, proud, back] in sill_boxes(&front, &view.lying_pieces_on_wall, &bounds, rule) {
            let first = vertices.len();
            for (x, z, out) in [
                (x0, top, -back),
                (x1, top, -back),
                (x1, bottom, -back),
                (x0, bottom, -back),
                (x0, top, proud),
                (x1, top, proud),
                (x1, bottom, proud),
                (x0, bottom, proud),
            ] {
                vertices.push(Vertex {
                    point: wall.point(x, z, &Vec3::zeros()) + wall.out * out,
                    sigma: None,
                });
            }
            let ring = |k: usize| [first + k, first + (k + 1) % 4];
            let pairs = (0..4)
                .map(ring)
                .chain((0..4).map(|k| ring(k).map(|v| v + 4)))
                .chain((0..4).map(|k| [first + k, first + k + 4]));
            edges.extend(pairs.map(|[a, b]| Edge {
                a,
                b,
                line: usize::MAX,
                origin: EdgeOrigin::Inferred,
            }));
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const RULE: SillRule = SillRule {
        proud_m: (0.02, 0.3),
        reach_m: 0.3,
    };

    /// A lying piece at height `z`, `proud` in front of the wall, from `a` to `b` along it.
    fn piece(z: f64, proud: f64, a: f64, b: f64) -> Piece {
        (z, -proud, a, b, None)
    }

    #[test]
    fn a_nose_seen_at_both_arrises_gives_its_sill() {
        // A window 1 to 2 m across, its foot at 1 m; its sill 6 cm proud, 3 cm below the foot, 6 cm thick,
        // reaching 5 cm past the window; the top arris in two pieces, the bottom one whole.
        let front = [
            piece(0.97, 0.06, 0.95, 1.4),
            piece(0.971, 0.06, 1.5, 2.05),
            piece(0.91, 0.061, 0.95, 2.05),
        ];
        let boxes = sill_boxes(&front, &[], &[[1.0, 2.0, 1.0, 2.5]], RULE);
        assert_eq!(boxes.len(), 1);
        let [x0, x1, top, bottom, proud, back] = boxes[0];
        assert!((x0 - 0.95).abs() < 1e-9 && (x1 - 2.05).abs() < 1e-9, "{boxes:?}");
        assert!((top - 0.9705).abs() < 1e-3 && (top - bottom - 0.06).abs() < 2e-3, "{boxes:?}");
        assert!((proud - 0.06).abs() < 1e-3 && back == 0.0, "{boxes:?}");
    }

    #[test]
    fn a_line_in_front_of_the_wall_at_the_foots_height_is_no_top_arris_where_the_sills_top_meets_the_wall_below() {
        // The sill as in the first test; the window's foot edge placed 7 cm in front of the wall (a lying line's
        // depth is a strip's weakest), the top arris not seen, the sill's top seen where it meets the wall.
        let front = [piece(1.005, 0.07, 0.95, 2.05), piece(0.91, 0.06, 0.95, 2.05)];
        let on_wall = [piece(0.97, 0.0, 0.95, 2.05), piece(1.0, 0.0, 1.0, 2.0)];
        let boxes = sill_boxes(&front, &on_wall, &[[1.0, 2.0, 1.0, 2.5]], RULE);
        assert_eq!(boxes.len(), 1);
        let [_, _, top, bottom, proud, _] = boxes[0];
        assert!((top - 0.97).abs() < 1e-9 && (bottom - 0.91).abs() < 1e-9, "{boxes:?}");
        assert!((proud - 0.06).abs() < 1e-9, "the nose's depth is the lower arris's: {boxes:?}");
        // Without the line along the wall, the two lines in front are the arrises.
        let boxes = sill_boxes(&front, &on_wall[1..], &[[1.0, 2.0, 1.0, 2.5]], RULE);
        assert!((boxes[0][2] - 1.005).abs() < 1e-9, "{boxes:?}");
    }

    #[test]
    fn a_window_showing_only_its_top_arris_takes_the_thickness_of_its_neighbours() {
        let front = [
            piece(0.97, 0.06, 0.95, 2.05),
            piece(0.91, 0.06, 0.95, 2.05),
            piece(0.97, 0.06, 3.2, 3.9),
        ];
        let boxes = sill_boxes(&front, &[], &[[1.0, 2.0, 1.0, 2.5], [3.0, 4.0, 1.0, 2.5]], RULE);
        assert_eq!(boxes.len(), 2);
        assert!((boxes[1][2] - boxes[1][3] - 0.06).abs() < 1e-9, "{boxes:?}");
        assert!((boxes[1][0] - 2.95).abs() < 1e-9, "the first sill's overhang: {boxes:?}");
    }

    #[test]
    fn the_nose_is_where_most_of_its_length_lies_not_the_sills_line_along_the_wall() {
        // The wall stands 2 cm behind its face: the sill's top along the wall seems 2.5 cm proud, its nose 8 cm.
        let front = [
            piece(0.97, 0.025, 0.95, 2.05),
            piece(0.91, 0.08, 0.95, 1.5),
            piece(0.91, 0.081, 1.6, 2.05),
            piece(0.97, 0.08, 1.1, 1.9),
        ];
        let boxes = sill_boxes(&front, &[], &[[1.0, 2.0, 1.0, 2.5]], RULE);
        assert_eq!(boxes.len(), 1);
        assert!((boxes[0][4] - 0.0805).abs() < 2e-3, "{boxes:?}");
        assert!((boxes[0][5] + 0.025).abs() < 1e-9, "its back on the line along the wall: {boxes:?}");
    }

    #[test]
    fn a_line_far_in_front_of_one_window_is_no_sill_where_the_walls_sills_stand_less_proud() {
        let sill = |x0: f64| [piece(0.97, 0.06, x0 - 0.05, x0 + 1.05), piece(0.91, 0.06, x0 - 0.05, x0 + 1.05)];
        let mut front: Vec<Piece> = [1.0, 3.0, 5.0].iter().flat_map(|&x| sill(x)).collect();
        // Under the middle window something 25 cm out, across it.
        front.extend([piece(0.95, 0.25, 2.9, 4.1), piece(0.9, 0.25, 2.9, 4.1)]);
        let windows: Vec<[f64; 4]> = [1.0, 3.0, 5.0].iter().map(|&x| [x, x + 1.0, 1.0, 2.5]).collect();
        let boxes = sill_boxes(&front, &[], &windows, RULE);
        assert_eq!(boxes.len(), 3);
        assert!(boxes.iter().all(|b| (b[4] - 0.06).abs() < 1e-9), "{boxes:?}");
    }

    #[test]
    fn no_sill_without_a_nose_across_the_window_or_with_its_thickness_unknown() {
        // Half the width is not enough; a nose too far below the foot is something else (a string course).
        assert!(sill_boxes(
            &[piece(0.97, 0.06, 1.0, 1.4), piece(0.91, 0.06, 1.0, 1.4)],
            &[],
            &[[1.0, 2.0, 1.0, 2.5]],
            RULE
        )
        .is_empty());
        assert!(sill_boxes(
            &[piece(0.5, 0.06, 1.0, 2.0), piece(0.45, 0.06, 1.0, 2.0)],
            &[],
            &[[1.0, 2.0, 1.0, 2.5]],
            RULE
        )
        .is_empty());
        // One arris alone on the whole wall: how thick the sills are is unknown.
        assert!(sill_boxes(&[piece(0.97, 0.06, 1.0, 2.0)], &[], &[[1.0, 2.0, 1.0, 2.5]], RULE).is_empty());
        // Flush with the wall: no sill.
        assert!(sill_boxes(
            &[piece(0.97, 0.005, 1.0, 2.0), piece(0.91, 0.005, 1.0, 2.0)],
            &[],
            &[[1.0, 2.0, 1.0, 2.5]],
            RULE
        )
        .is_empty());
    }
}
