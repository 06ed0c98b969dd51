//! Rule two: a rectangle of edges behind the wall, two sides standing and two lying, widened to the frame
//! around it, where no recessed face closed.
use super::*;

/// Rectangles of the edges behind a wall: two standing sides an opening's width apart ([`OpeningSizes`]) and two
/// lying ones at their ends, at one depth, covered by their edges over [`MIN_STANDING_COVER`] and
/// [`MIN_LYING_COVER`] of their length. Where the frame's edge on one side is hidden (beyond a strip's end the
/// reveal hides the side away from the cameras, and a sill the foot of an opening above them), the opening's own
/// edge on the wall may stand in for it, if at least one standing and one lying side lie behind the wall: brick
/// courses on the wall alone would make openings anywhere. Largest first (of one size, those with fewer sides on the
/// wall); one inside another already taken (the panes of a frame) is left out. Each with its depth and a σ.
///
/// A nearly flush opening (its frame closer to the wall than the smallest recess, [`OpeningSizes`]) shows all four sides on the
/// wall: there the rectangle of the wall's own edges is the opening where the courses of the wall do not run through
/// it ([`WallView::courses_within`]).
pub(super) fn from_rectangles(view: &WallView, centres: &[Vec3]) -> Vec<(Rect, f64, Option<Vec3>)> {
    let on_wall = |s: &Side| s.depth < view.sizes.recess_m.0;
    let size_ok = |d: f64| (view.sizes.opening_m.0..=view.sizes.opening_m.1).contains(&d);
    let mut standing: Vec<&Side> = view.standing.iter().chain(&view.standing_on_wall).collect();
    standing.sort_by(|a, b| a.at.total_cmp(&b.at).then(a.depth.total_cmp(&b.depth)));
    let lying: Vec<&Side> = view.lying.iter().chain(&view.lying_on_wall).collect();
    let mut found: Vec<(Rect, f64, Option<Vec3>)> = Vec::new();
    for (i, l) in standing.iter().enumerate() {
        for r in &standing[i + 1..] {
            let width = r.at - l.at;
            let depth = match (on_wall(l), on_wall(r)) {
                (false, false) if (r.depth - l.depth).abs() <= DEPTH_TOLERANCE_M => (l.depth + r.depth) / 2.0,
                (false, true) => l.depth,
                (true, false) => r.depth,
                (true, true) => 0.0,
                _ => continue,
            };
            let flush = on_wall(l) && on_wall(r);
            if !size_ok(width) {
                continue;
            }
            // A lying side behind the wall ends where the standing sides behind it end (a hidden foot is seen
            // higher on the frame than on the wall); one on the wall, where any does. Behind the wall preferred:
            // the wall's own lying sides may be brick courses or a sill's back edge beside the opening's edge.
            let ends = |from: &[&Side]| {
                from.iter()
                    .map(|s| s.extent())
                    .fold((f64::INFINITY, f64::NEG_INFINITY), |a, e| (a.0.min(e.0), a.1.max(e.1)))
            };
            let recessed: Vec<&Side> = [*l, *r].into_iter().filter(|s| !on_wall(s)).collect();
            let (behind_ends, all_ends) = (ends(&recessed), ends(&[*l, *r]));
            let end = |top: bool| {
                let pick = |e: (f64, f64)| if top { e.1 } else { e.0 };
                let reach = if flush { FLUSH_END_REACH_M } else { 3.0 * SIDE_TOLERANCE_M };
                // A flush opening's foot and top end at its sides: a course of the wall runs on past them (and its
                // sides end at its foot and top: a pipe or a corner runs on).
                let ends_at_sides = move |s: &Side| !flush || ends_within(s, l.at, r.at);
                let near = move |at: f64| {
                    move |s: &&&Side| (s.at - at).abs() <= reach && s.cover(l.at, r.at) >= MIN_LYING_COVER && ends_at_sides(s)
                };
                let behind = |s: &&&Side| !on_wall(s) && (s.depth - depth).abs() <= DEPTH_TOLERANCE_M;
                let on = |s: &&&Side| on_wall(s);
                let nearest = |at: f64| move |a: &&&Side, b: &&&Side| (a.at - at).abs().total_cmp(&(b.at - at).abs());
                let (b, w) = (pick(behind_ends), pick(all_ends));
                (lying.iter().filter(near(b)).filter(behind).min_by(nearest(b)))
                    .or_else(|| lying.iter().filter(near(w)).filter(on).min_by(nearest(w)))
            };
            // A flush opening's foot or top may be hidden (a sill in front of the foot) or unmatched: where both
            // standing sides end together there, their ends are that side.
            let jambs_end = |top: bool| {
                let pick = |s: &Side| if top { s.extent().1 } else { s.extent().0 };
                let (a, b) = (pick(l), pick(r));
                (flush && (a - b).abs() <= FLUSH_END_REACH_M).then_some(((a + b) / 2.0, true))
            };
            let (top, foot) = (end(true), end(false));
            let side = |found: Option<&&Side>, top: bool| found.map(|s| (s.at, on_wall(s))).or_else(|| jambs_end(top));
            let (Some((z1, top_on_wall)), Some((z0, bottom_on_wall))) = (side(top, true), side(foot, false)) else {
                continue;
            };
            if (top.is_none() && foot.is_none())
                || (top_on_wall && bottom_on_wall && !flush)
                || !size_ok(z1 - z0)
                || l.cover(z0, z1) < MIN_STANDING_COVER
                || r.cover(z0, z1) < MIN_STANDING_COVER
                || (flush && !(ends_within(l, z0, z1) && ends_within(r, z0, z1)))
            {
                continue;
            }
            let rect = Rect {
                bounds: [l.at, r.at, z0, z1],
                on_wall: [on_wall(l), on_wall(r), bottom_on_wall, top_on_wall],
            };
            if flush && (view.courses_within(rect.bounds, FLUSH_END_REACH_M / 2.0) > MAX_FLUSH_LEVELS) {
                continue;
            }
            found.push((rect, depth, l.sigma.or(r.sigma)));
        }
    }
    found.sort_by(|a, b| {
        let (p, q) = (&a.0.bounds, &b.0.bounds);
        let area = |r: &[f64; 4]| (r[1] - r[0]) * (r[3] - r[2]);
        let sides_on_wall = |r: &Rect| r.on_wall.iter().filter(|&&w| w).count();
        area(q)
            .total_cmp(&area(p))
            .then(sides_on_wall(&a.0).cmp(&sides_on_wall(&b.0)))
            .then(p[0].total_cmp(&q[0]))
            .then(p[2].total_cmp(&q[2]))
    });
    let rects: Vec<[f64; 4]> = found.iter().map(|f| f.0.bounds).collect();
    let mut kept: Vec<(Rect, f64, Option<Vec3>)> = Vec::new();
    for (rect, depth, sigma) in found {
        if holds_another_beside(rect.bounds, &rects, view.sizes.frame_m.1, view.sizes.opening_m.0) {
            continue;
        }
        let candidate = (widened_to_frame(rect, depth, view, centres).unwrap_or(rect), depth, sigma);
        let [x0, x1, z0, z1] = candidate.0.bounds;
        let (cx, cz) = ((x0 + x1) / 2.0, (z0 + z1) / 2.0);
        if !kept.iter().any(|(k, _, _)| {
            let k = k.bounds;
            k[0] <= cx && cx <= k[1] && k[2] <= cz && cz <= k[3]
        }) {
            kept.push(candidate);
        }
    }
    kept
}

/// Whether another rectangle of `rects` lies inside `outer` (within `reach`, a frame's width) and leaves beside it, or
/// above or below it, room for a pier of [`MIN_PIER_M`] and another opening of `smallest` metres: then `outer` spans
/// two openings and the wall between them, which the largest-first choice would take for one wide opening (lines
/// along the heads of a row of windows, or along two storeys' jambs, cover its sides).
pub(super) fn holds_another_beside(outer: [f64; 4], rects: &[[f64; 4]], reach: f64, smallest: f64) -> bool {
    let room = MIN_PIER_M + smallest;
    rects.iter().filter(|r| **r != outer).any(|r| {
        let inside = r[0] >= outer[0] - reach && r[1] <= outer[1] + reach && r[2] >= outer[2] - reach && r[3] <= outer[3] + reach;
        inside && (r[0] - outer[0] >= room || outer[1] - r[1] >= room || r[2] - outer[2] >= room || outer[3] - r[3] >= room)
    })
}

/// What a standing side of a rectangle is, told by the frame's other standing edge beside it.
pub(super) enum FrameSide {
    /// The glazing: the frame's outer edge lies this far outside, at this position, from and to these heights.
    Glazing { width: f64, outer: f64, ends: (f64, f64) },
    /// Already the frame's outer edge: the glazing lies this far inside.
    Outer { width: f64 },
    /// The opening's own edge on the wall.
    OnWall,
    /// Nothing beside it tells.
    Unknown,
}

/// What the side of a rectangle at `at` is, looking `outward` (±1 along the wall) for the frame's outer edge and
/// inward for its glazing: standing edges within `frame_m` ([`OpeningSizes`]) of it, at its depth, along [`MIN_OUTER_COVER`] of the
/// rectangle's height `[z0, z1]`, the nearest first.
pub(super) fn frame_side(at: f64, outward: f64, depth: f64, [z0, z1]: [f64; 2], standing: &[Side], frame_m: (f64, f64)) -> FrameSide {
    let nearest = |direction: f64| {
        standing
            .iter()
            .filter(|s| (s.depth - depth).abs() <= DEPTH_TOLERANCE_M && s.cover(z0, z1) >= MIN_OUTER_COVER)
            .map(|s| (s, (s.at - at) * direction))
            .filter(|(_, d)| (frame_m.0..=frame_m.1).contains(d))
            .min_by(|a, b| a.1.total_cmp(&b.1))
    };
    if let Some((s, width)) = nearest(outward) {
        FrameSide::Glazing {
            width,
            outer: s.at,
            ends: s.extent(),
        }
    } else if let Some((_, width)) = nearest(-outward) {
        FrameSide::Outer { width }
    } else {
        FrameSide::Unknown
    }
}

/// Where the frame's outer standing edges lie just outside a rectangle, the rectangle is the glazing inside the
/// frame, or part of it: a ground-floor frame's top and foot lie a pixel from the opening's outline in every image
/// of a street-level strip, and only the glazing's outline is found. Each side found to be glazing ([`frame_side`])
/// moves out to the frame's outer edge. A side that nothing beside it tells moves out by the frame's width found
/// on the other side, a frame being as wide on both sides: where the other side is glazing, or where no camera
/// could see that side's outer edge (beyond a strip's end the reveal hides it, [`hidden_sides`]). A side on the
/// wall is the opening's edge already. The rectangle's sides behind the wall then run from where the outer sides
/// start to where they end (both within 5 cm of each other where there are two). None where nothing moves.
pub(super) fn widened_to_frame(rect: Rect, depth: f64, view: &WallView, centres: &[Vec3]) -> Option<Rect> {
    use FrameSide::{Glazing, OnWall, Outer, Unknown};
    let [x0, x1, z0, z1] = rect.bounds;
    let hidden = hidden_sides(&view.wall, rect.bounds, centres);
    let side = |k: usize, at: f64, outward: f64| {
        if rect.on_wall[k] {
            OnWall
        } else {
            frame_side(at, outward, depth, [z0, z1], &view.standing, view.sizes.frame_m)
        }
    };
    let (left, right) = (side(0, x0, -1.0), side(1, x1, 1.0));
    // A side already on the frame's outer edge tells the frame's width only for a side whose outer edge no camera
    // saw: elsewhere a neighbour showing no glazing is as likely the outer edge too, its glazing edge unseen.
    let width = |side: &FrameSide, other_hidden: bool| match side {
        Glazing { width, .. } => Some(*width),
        Outer { width } if other_hidden => Some(*width),
        Outer { .. } | OnWall | Unknown => None,
    };
    let moved = |side: &FrameSide, from: f64, outward: f64, other_width: Option<f64>| match side {
        Glazing { outer, .. } => *outer,
        Outer { .. } | OnWall => from,
        Unknown => other_width.map_or(from, |w| from + outward * w),
    };
    let (l, r) = (
        moved(&left, x0, -1.0, width(&right, hidden[0])),
        moved(&right, x1, 1.0, width(&left, hidden[1])),
    );
    let (ends0, ends1) = match (&left, &right) {
        (Glazing { ends: (l0, l1), .. }, Glazing { ends: (r0, r1), .. }) => {
            if (l0 - r0).abs() > 0.05 || (l1 - r1).abs() > 0.05 {
                return None;
            }
            ((l0 + r0) / 2.0, (l1 + r1) / 2.0)
        }
        (Glazing { ends, .. }, _) | (_, Glazing { ends, .. }) => *ends,
        _ => (z0, z1),
    };
    // A lying side behind the wall with the frame's outer edge just beyond it is the glazing's too. Where no
    // camera saw that outer edge (a foot above them all: the sill hides the frame's foot rail), the opening's own
    // edge on the wall a frame's width beyond it is the foot.
    let frame_width = width(&left, true).or(width(&right, true));
    let mut on_wall = rect.on_wall;
    let mut lying_side = |k: usize, at: f64, outward: f64| {
        if on_wall[k] {
            return at;
        }
        if let Glazing { outer, .. } = frame_side(at, outward, depth, [l, r], &view.lying, view.sizes.frame_m) {
            return outer;
        }
        let wall_edge = frame_width.filter(|_| hidden[k]).and_then(|w| {
            let expected = at + outward * w;
            view.lying_on_wall
                .iter()
                .filter(|s| (s.at - expected).abs() <= SIDE_TOLERANCE_M && s.cover(l, r) >= MIN_LYING_COVER)
                .min_by(|a, b| (a.at - expected).abs().total_cmp(&(b.at - expected).abs()))
        });
        match wall_edge {
            Some(s) => {
                on_wall[k] = true;
                s.at
            }
            None => at,
        }
    };
    let z0 = lying_side(2, ends0, -1.0);
    let z1 = lying_side(3, ends1, 1.0);
    let bounds = [l, r, z0, z1];
    (bounds != rect.bounds).then_some(Rect { bounds, on_wall })
}

/// Whether `side` ends within [`MAX_SIDE_GAP_M`] beyond `lo` and `hi` along its direction.
pub(super) fn ends_within(side: &Side, lo: f64, hi: f64) -> bool {
    let (from, to) = side.extent();
    from >= lo - MAX_SIDE_GAP_M && to <= hi + MAX_SIDE_GAP_M
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_rectangle_over_an_opening_and_the_pier_beside_it_is_two_openings_not_one() {
        // Two windows 1.16 m wide with a 1.57 m pier between them, and the rectangle along both heads and feet.
        let left = [11.69, 12.85, 0.80, 2.03];
        let wide = [11.78, 15.50, 0.88, 1.92];
        assert!(holds_another_beside(wide, &[wide, left], 0.15, 0.8));
        // The window itself holds its frame's glazing (a frame's width inside) and nothing beside it.
        let glazing = [11.75, 12.79, 0.86, 1.97];
        assert!(!holds_another_beside(left, &[left, glazing], 0.15, 0.8));
        // A storey above is beside it too; a rectangle farther than a frame's width outside is not inside.
        let tall = [11.69, 12.85, 0.80, 6.0];
        assert!(holds_another_beside(tall, &[tall, left], 0.15, 0.8));
        let off = [11.40, 12.85, 0.80, 2.03];
        assert!(!holds_another_beside(wide, &[wide, off], 0.15, 0.8));
    }
}
