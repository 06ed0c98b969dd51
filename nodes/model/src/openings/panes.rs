//! The panes of a window's frame. A frame holds its glazing in panes, a grid of mullions and transoms; the 3-D lines
//! show the panes' sides in the frame's plane, but a rail's line often runs on across a mullion, and the faces of
//! few panes close. The windows of a wall are of a few kinds, each with one layout of panes: the layout the lines
//! show clearly at some windows of a size is given to every window of that size on the wall ([`add_panes`]).
use super::glass::densest;
use super::*;
use lineflow_photogrammetry::median;

/// A pane's sides cover at least this share of the window's height (standing) or width (lying).
const MIN_PANE_SIDE_COVER: f64 = 0.3;
/// The sides of panes lie at least this far inside the window's outline, metres (the frame's own width).
const MIN_INSIDE_M: f64 = 0.01;
/// A pane is at least this wide and high, metres…
const MIN_PANE_M: f64 = 0.15;
/// Windows within this of each other in width and height are of one size, metres.
const SIZE_TOLERANCE_M: f64 = 0.04;

/// The panes' sides across one direction `[lo, hi]` of a window: pairs (a pane's two sides) with at most `bar_m` (a
/// mullion or transom) between one pair and the next, at least [`MIN_PANE_M`] within a pair, and the panes filling
/// the window: the first side and the last at most `bar_m` (the frame's width) inside its outline. None where the
/// positions do not pair up so; where some sides were not seen, the rest often pair up into too few panes (one rail
/// and the far side of a mullion make one wide pane), and the frame's width tells.
fn pair_up(positions: &[f64], [lo, hi]: [f64; 2], bar_m: f64) -> Option<Vec<(f64, f64)>> {
    if positions.len() < 2 || positions.len() % 2 == 1 {
        return None;
    }
    let pairs: Vec<(f64, f64)> = positions.chunks(2).map(|c| (c[0], c[1])).collect();
    let wide = pairs.iter().all(|p| p.1 - p.0 >= MIN_PANE_M);
    let bars = pairs.windows(2).all(|w| w[1].0 - w[0].1 <= bar_m);
    let fills = positions[0] - lo <= bar_m && hi - positions[positions.len() - 1] <= bar_m;
    (wide && bars && fills).then_some(pairs)
}

/// The positions of the panes' sides inside `[lo, hi]` from the sides in the frame's plane (`at`, cover of the
/// other direction's extent), in order, merged within [`SIDE_TOLERANCE_M`].
fn positions(sides: &[(f64, f64)], lo: f64, hi: f64) -> Vec<f64> {
    let mut at: Vec<f64> = sides
        .iter()
        .filter(|s| s.0 > lo + MIN_INSIDE_M && s.0 < hi - MIN_INSIDE_M && s.1 >= MIN_PANE_SIDE_COVER)
        .map(|s| s.0)
        .collect();
    at.sort_by(f64::total_cmp);
    at.dedup_by(|b, a| *b - *a <= SIDE_TOLERANCE_M);
    at
}

/// A window's layout of panes: the pairs across (x) and up (z), as offsets from its outline's first corner.
type Layout = (Vec<(f64, f64)>, Vec<(f64, f64)>);

/// The layouts of a wall's windows (`windows`: bounds and the frame's depth), from the standing and lying sides
/// behind the wall at each frame's depth: a window's own where its lines pair up, else the one most windows of its
/// size show (their median offsets), else the one the sides of its size's windows show together ([`pooled`]), else
/// none.
fn layouts(windows: &[([f64; 4], f64)], standing: &[Side], lying: &[Side], bar_m: f64) -> Vec<Option<Layout>> {
    // Each window's panes' sides across and up, as offsets from its outline's first corner.
    let sides: Vec<(Vec<f64>, Vec<f64>)> = windows
        .iter()
        .map(|&([x0, x1, z0, z1], depth)| {
            let at = |sides: &[Side], lo: f64, hi: f64| -> Vec<(f64, f64)> {
                sides
                    .iter()
                    .filter(|s| (s.depth - depth).abs() <= DEPTH_TOLERANCE_M / 2.0)
                    .map(|s| (s.at, s.cover(lo, hi)))
                    .collect()
            };
            let offsets = |positions: Vec<f64>, from: f64| positions.into_iter().map(|p| p - from).collect();
            (
                offsets(positions(&at(standing, z0, z1), x0, x1), x0),
                offsets(positions(&at(lying, x0, x1), z0, z1), z0),
            )
        })
        .collect();
    let size = |b: &[f64; 4]| (b[1] - b[0], b[3] - b[2]);
    let own: Vec<Option<Layout>> = windows
        .iter()
        .zip(&sides)
        .map(|((bounds, _), (across, up))| {
            let (w, h) = size(bounds);
            Some((pair_up(across, [0.0, w], bar_m)?, pair_up(up, [0.0, h], bar_m)?))
        })
        .collect();
    windows
        .iter()
        .zip(&own)
        .map(|((bounds, _), mine)| {
            mine.clone().or_else(|| {
                let (w, h) = size(bounds);
                let alike: Vec<usize> = (0..windows.len())
                    .filter(|&k| {
                        let (bw, bh) = size(&windows[k].0);
                        (bw - w).abs() <= SIZE_TOLERANCE_M && (bh - h).abs() <= SIZE_TOLERANCE_M
                    })
                    .collect();
                let layouts: Vec<&Layout> = alike.iter().filter_map(|&k| own[k].as_ref()).collect();
                common(&layouts).or_else(|| {
                    let across: Vec<&[f64]> = alike.iter().map(|&k| sides[k].0.as_slice()).collect();
                    let up: Vec<&[f64]> = alike.iter().map(|&k| sides[k].1.as_slice()).collect();
                    Some((
                        pair_up(&pooled(&across)?, [0.0, w], bar_m)?,
                        pair_up(&pooled(&up)?, [0.0, h], bar_m)?,
                    ))
                })
            })
        })
        .collect()
}

/// The panes' sides (offsets) that the windows of one size show together, where no window shows them all: the
/// densest runs, one after another, of the windows' offsets within twice [`SIDE_TOLERANCE_M`] (the outlines' own
/// noise adds to the sides'), each at its median, while at least a quarter of the windows (and two) show it. The
/// windows of a wall share their layout, and a side hidden at one (behind its reveal, in a shadow) is seen at others.
fn pooled(windows: &[&[f64]]) -> Option<Vec<f64>> {
    let mut left: Vec<f64> = windows.iter().flat_map(|w| w.iter().copied()).collect();
    let needed = (windows.len() / 4).max(2);
    let mut sides = Vec::new();
    while let Some(run) = densest(left.clone(), 2.0 * SIDE_TOLERANCE_M).filter(|run| run.len() >= needed) {
        left.retain(|v| !run.contains(v));
        sides.push(median(run)?);
    }
    sides.sort_by(f64::total_cmp);
    (!sides.is_empty()).then_some(sides)
}

/// The layout most of `layouts` share (the same numbers of panes across and up), with each offset their median;
/// none without a majority.
fn common(layouts: &[&Layout]) -> Option<Layout> {
    let shape = |l: &Layout| (l.0.len(), l.1.len());
    let best = layouts
        .iter()
        .map(|l| shape(l))
        .max_by_key(|s| layouts.iter().filter(|l| shape(l) == *s).count())?;
    let same: Vec<&&Layout> = layouts.iter().filter(|l| shape(l) == best).collect();
    if 2 * same.len() <= layouts.len() {
        return None;
    }
    let median = |f: &dyn Fn(&Layout) -> f64| median(same.iter().map(|l| f(l)).collect()).unwrap_or(f64::NAN);
    let pairs = |n: usize, pick: fn(&Layout) -> &Vec<(f64, f64)>| -> Vec<(f64, f64)> {
        (0..n).map(|k| (median(&|l| pick(l)[k].0), median(&|l| pick(l)[k].1))).collect()
    };
    Some((pairs(best.0, |l| &l.0), pairs(best.1, |l| &l.1)))
}

/// A window of a wall with its frame: its bounds, the frame's depth, and the bounds of the panes it has.
type Framed = ([f64; 4], f64, Vec<[f64; 4]>);

/// The depth of a window's panes (`bounds`, `layout`): the median of the sides its 3-D lines show where the layout
/// puts the panes' sides. The frame's own depth comes from its outer sides, often few; the glazing's edges are many
/// (and where the glass lies a little behind the frame, one line stands for both, between them).
fn pane_depth(bounds: &[f64; 4], (across, up): &Layout, standing: &[Side], lying: &[Side]) -> Option<f64> {
    let [x0, x1, z0, z1] = *bounds;
    let at = |sides: &[Side], from: f64, pairs: &[(f64, f64)], lo: f64, hi: f64| -> Vec<f64> {
        let positions: Vec<f64> = pairs.iter().flat_map(|&(a, b)| [from + a, from + b]).collect();
        sides
            .iter()
            .filter(|s| positions.iter().any(|p| (s.at - p).abs() <= SIDE_TOLERANCE_M) && s.cover(lo, hi) >= MIN_PANE_SIDE_COVER / 2.0)
            .map(|s| s.depth)
            .collect()
    };
    let mut depths = at(standing, x0, across, z0, z1);
    depths.extend(at(lying, z0, up, x0, x1));
    median(depths)
}

/// The panes the windows' layouts ([`layouts`]) give them that they do not have yet: (window, the pane's bounds, its
/// depth behind the wall: [`pane_depth`], else the frame's).
fn missing_panes(windows: &[Framed], standing: &[Side], lying: &[Side], bar_m: f64) -> Vec<(usize, [f64; 4], f64)> {
    let frames: Vec<([f64; 4], f64)> = windows.iter().map(|w| (w.0, w.1)).collect();
    let mut out = Vec::new();
    for (k, ((bounds, frame, present), layout)) in windows.iter().zip(layouts(&frames, standing, lying, bar_m)).enumerate() {
        let Some(layout) = layout else { continue };
        let missing: Vec<[f64; 4]> = layout
            .0
            .iter()
            .flat_map(|&(a, b)| {
                layout
                    .1
                    .iter()
                    .map(move |&(c, d)| [bounds[0] + a, bounds[0] + b, bounds[2] + c, bounds[2] + d])
            })
            .filter(|pane| !present.iter().any(|p| same_pane(p, pane)))
            .collect();
        if missing.is_empty() {
            continue;
        }
        // Never in front of the frame that holds them.
        let depth = pane_depth(bounds, &layout, standing, lying).map_or(*frame, |d| d.max(*frame));
        out.extend(missing.into_iter().map(|pane| (k, pane, depth)));
    }
    out
}

/// Whether two panes' bounds are one pane: each one's centre lies inside the other.
fn same_pane(p: &[f64; 4], q: &[f64; 4]) -> bool {
    let inside = |b: &[f64; 4], c: &[f64; 4]| {
        let (x, z) = ((c[0] + c[1]) / 2.0, (c[2] + c[3]) / 2.0);
        (b[0]..=b[1]).contains(&x) && (b[2]..=b[3]).contains(&z)
    };
    inside(p, q) || inside(q, p)
}

/// Gives every window of a wall whose frame's depth the model knows (a face behind it: its frame or panes) the panes
/// its layout shows ([`layouts`]), as window faces in the frame's plane with inferred outlines, where it has
/// none of its own there yet (a pane whose face closed stays as it is). Runs after [`super::add_frames`].
pub(crate) fn add_panes(
    walls: &[WallView],
    params: &ModelParams,
    vertices: &mut Vec<Vertex>,
    edges: &mut Vec<Edge>,
    faces: &mut Vec<Face>,
) {
    let cos_par = params.plane_angle_deg.to_radians().cos();
    let sizes = params.opening_sizes();
    let outlines = Outline::of_faces(faces, vertices);
    let mut new = Vec::new();
    for view in walls {
        let wall = &view.wall;
        let windows: Vec<(Framed, Vec3)> = faces
            .iter()
            .zip(&outlines)
            .filter(|(f, o)| {
                f.kind == SurfaceKind::Window && o.normal.dot(&wall.out) > cos_par && wall.depth(&o.centroid).abs() < FLUSH_MIN_M
            })
            .filter_map(|(_, o)| {
                let bounds = o.bounds_in(wall);
                let behind = face_behind(&outlines, wall, bounds, sizes, cos_par)?;
                // The frame behind it gives the panes' plane; the panes already there stay.
                behind.spans.then_some(((bounds, behind.depth, behind.panes), o.normal))
            })
            .collect();
        let deepest = sizes.recess_m.1;
        let standing = sides(wall, vertices, edges, true, (FLUSH_MIN_M, deepest));
        let lying = sides(wall, vertices, edges, false, (FLUSH_MIN_M, deepest));
        let framed: Vec<Framed> = windows.iter().map(|w| w.0.clone()).collect();
        for (k, [x0, x1, z0, z1], depth) in missing_panes(&framed, &standing, &lying, sizes.frame_m.1) {
            let (_, normal) = &windows[k];
            let corner = |x: f64, z: f64| Vertex {
                point: wall.point(x, z, &Vec3::zeros()) - wall.out * depth,
                sigma: None,
            };
            new.push((vec![corner(x0, z0), corner(x1, z0), corner(x1, z1), corner(x0, z1)], *normal));
        }
    }
    for (corners, normal) in new {
        add_face(corners, normal, SurfaceKind::Window, vertices, edges, faces);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn side(at: f64, depth: f64, lo: f64, hi: f64) -> Side {
        Side {
            at,
            depth,
            spans: vec![(lo, hi)],
            sigma: None,
        }
    }

    /// A window 1 to 2 m across and up, its frame 0.12 behind the wall, two panes across (mullion at 1.47–1.53)
    /// and two up (transom at 1.6–1.65), frame 5 cm wide.
    fn window_lines(x0: f64, full: bool) -> (Vec<Side>, Vec<Side>) {
        let standing = [0.05, 0.47, 0.53, 0.95].iter().map(|&x| side(x0 + x, 0.12, 1.0, 2.0)).collect();
        let rails: &[f64] = if full { &[0.05, 0.6, 0.65, 0.95] } else { &[0.05, 0.6, 0.95] };
        let lying = rails.iter().map(|&z| side(1.0 + z, 0.12, x0, x0 + 1.0)).collect();
        (standing, lying)
    }

    #[test]
    fn a_window_whose_lines_pair_up_gets_its_panes_and_one_whose_lines_do_not_takes_those_of_its_size() {
        let (mut standing, mut lying) = window_lines(0.0, true);
        for x0 in [2.0, 4.0] {
            let (s, l) = window_lines(x0, x0 == 2.0);
            standing.extend(s);
            lying.extend(l);
        }
        let windows = [
            ([0.0, 1.0, 1.0, 2.0], 0.12),
            ([2.0, 3.0, 1.0, 2.0], 0.12),
            ([4.0, 5.0, 1.0, 2.0], 0.12),
        ];
        standing.sort_by(|a, b| a.at.total_cmp(&b.at));
        let found = layouts(&windows, &standing, &lying, 0.15);
        let expected: Layout = (vec![(0.05, 0.47), (0.53, 0.95)], vec![(0.05, 0.6), (0.65, 0.95)]);
        for (k, l) in found.iter().enumerate() {
            let l = l.as_ref().unwrap_or_else(|| panic!("window {k} has no layout"));
            for (got, want) in l.0.iter().chain(&l.1).zip(expected.0.iter().chain(&expected.1)) {
                assert!((got.0 - want.0).abs() < 1e-9 && (got.1 - want.1).abs() < 1e-9, "window {k}: {l:?}");
            }
        }
    }

    #[test]
    fn a_window_with_some_of_its_panes_gets_the_others_of_its_layout_and_a_whole_one_none() {
        // Window 0's lines pair up; windows 1 and 2 show three rails only, window 1 has its left column of panes
        // as faces already, window 2 all four.
        let (mut standing, mut lying) = (Vec::new(), Vec::new());
        for x0 in [0.0, 2.0, 4.0] {
            let (s, l) = window_lines(x0, x0 == 0.0);
            standing.extend(s);
            lying.extend(l);
        }
        standing.sort_by(|a, b| a.at.total_cmp(&b.at));
        let pane = |x0: f64, [a, b]: [f64; 2], [c, d]: [f64; 2]| [x0 + a, x0 + b, 1.0 + c, 1.0 + d];
        let (left, right, low, high) = ([0.05, 0.47], [0.53, 0.95], [0.05, 0.6], [0.65, 0.95]);
        let windows: Vec<Framed> = vec![
            ([0.0, 1.0, 1.0, 2.0], 0.12, Vec::new()),
            ([2.0, 3.0, 1.0, 2.0], 0.12, vec![pane(2.0, left, low), pane(2.0, left, high)]),
            (
                [4.0, 5.0, 1.0, 2.0],
                0.12,
                [left, right].iter().flat_map(|&x| [low, high].map(|z| pane(4.0, x, z))).collect(),
            ),
        ];
        let added = missing_panes(&windows, &standing, &lying, 0.15);
        assert!(added.iter().all(|a| (a.2 - 0.12).abs() < 1e-9), "{added:?}");
        let of = |k: usize| added.iter().filter(|a| a.0 == k).map(|a| a.1).collect::<Vec<_>>();
        assert_eq!(of(0).len(), 4, "{added:?}");
        let expected = [pane(2.0, right, low), pane(2.0, right, high)];
        assert_eq!(of(1).len(), 2, "{added:?}");
        for (got, want) in of(1).iter().zip(&expected) {
            assert!(got.iter().zip(want).all(|(g, w)| (g - w).abs() < 1e-9), "{got:?} against {want:?}");
        }
        assert!(of(2).is_empty(), "{added:?}");
    }

    #[test]
    fn the_panes_lie_where_the_lines_at_their_sides_are() {
        // The left sides of the panes 12 cm behind the wall, the right ones and the rails 15 cm; a mullion's
        // middle line (no side of a pane) 30 cm.
        let layout: Layout = (vec![(0.05, 0.47), (0.53, 0.95)], vec![(0.05, 0.95)]);
        let mut standing: Vec<Side> = [0.05, 0.53].iter().map(|&x| side(x, 0.12, 1.0, 2.0)).collect();
        standing.extend([0.47, 0.95].iter().map(|&x| side(x, 0.15, 1.0, 2.0)));
        standing.push(side(0.5, 0.3, 1.0, 2.0));
        let lying: Vec<Side> = [1.05, 1.95].iter().map(|&z| side(z, 0.15, 0.0, 1.0)).collect();
        assert_eq!(pane_depth(&[0.0, 1.0, 1.0, 2.0], &layout, &standing, &lying), Some(0.15));
        assert_eq!(pane_depth(&[0.0, 1.0, 1.0, 2.0], &layout, &[], &[]), None);
    }

    #[test]
    fn the_sides_no_window_shows_whole_are_pooled_from_its_size() {
        // Eight windows, each showing some of the sides 0.06, 0.67, 0.73 and 1.34 (a few millimetres off), one a
        // stray line at 0.4 as well: the four sides come back, the stray one does not.
        let seen: [&[f64]; 8] = [
            &[0.06, 0.67],
            &[0.061, 0.731, 1.342],
            &[0.668, 0.73],
            &[0.059, 1.338],
            &[0.4, 0.671, 1.341],
            &[0.062, 0.729],
            &[0.058, 0.672, 1.339],
            &[0.733],
        ];
        let sides = pooled(&seen).unwrap();
        let want = [0.06, 0.67, 0.73, 1.34];
        assert_eq!(sides.len(), 4, "{sides:?}");
        assert!(sides.iter().zip(want).all(|(s, w)| (s - w).abs() < 0.003), "{sides:?}");
        assert_eq!(pooled(&[&[0.4], &[1.0]]), None, "each seen once");
    }

    #[test]
    fn positions_that_do_not_pair_into_panes_give_no_layout() {
        // Three rails alone: odd; two sides 10 cm apart: no pane; a bar wider than a frame's: two windows.
        let window = [0.0, 1.0];
        assert!(pair_up(&[0.05, 0.6, 0.95], window, 0.15).is_none());
        assert!(pair_up(&[0.05, 0.15], window, 0.15).is_none());
        assert!(pair_up(&[0.05, 0.4, 0.7, 0.95], window, 0.15).is_none());
        assert_eq!(
            pair_up(&[0.05, 0.47, 0.53, 0.95], window, 0.15),
            Some(vec![(0.05, 0.47), (0.53, 0.95)])
        );
        // A pane's first side and the far side of the mullion, the rest unseen: one wide pane, leaving half the
        // window without glazing; the upper pane's rails alone, the lower pane missing.
        assert!(pair_up(&[0.05, 0.53], window, 0.15).is_none());
        assert!(pair_up(&[0.53, 0.95], window, 0.15).is_none());
    }
}
