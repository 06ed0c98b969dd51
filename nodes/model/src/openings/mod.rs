//! Openings inferred from what is seen through them. A street-level strip rarely closes an opening's outline on
//! the wall: the sill hides its foot, and its reveals run along the line of sight and are seldom matched. What it
//! does see are the frame, door leaf or loggia behind the opening, parallel to the wall. Two rules turn them into
//! the opening in the wall, each only where no opening is there yet:
//!
//! - a closed recessed face ([`from_recesses`]);
//! - a rectangle of edges behind the wall, two sides standing and two lying ([`from_rectangles`]), where the
//!   recessed face did not close (a corner junction missed, a side a centimetre off its plane).
//!
//! Reveals are taken as square to the wall, as they are on almost every façade. The side of the recessed outline
//! turned away from the cameras is hidden behind the opening's edge: a camera below sees a frame's top edge through
//! the soffit but not its foot, and the 3-D lines put that foot where the line of sight over the opening's foot
//! meets the frame plane (a window 11 m above a camera 19 m away, 20 cm deep: 11 cm too high). That side is moved
//! back along the line of sight ([`opening_corners`]); only the vertical is corrected, since a strip sees an
//! opening's sides from both left and right.
use lineflow_photogrammetry::Vec3;

use lineflow_photogrammetry::{point_in_polygon, signed_area};

use crate::surface::{plane_basis, smaller_side, Face, Plane, SurfaceKind};
use crate::{Cameras, Edge, EdgeOrigin, ModelParams, Vertex};

/// The sizes the opening rules assume, metres (the model's parameters `recess_*_m`, `opening_*_m`, `frame_*_m`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct OpeningSizes {
    /// How far behind its wall a recessed face may lie to make an opening in it (less, it is a pane inside its
    /// frame, and a frame that close is on the wall: a nearly flush opening).
    pub(crate) recess_m: (f64, f64),
    /// The width and height of an opening (smaller, the panes of a frame would pass for openings wherever the
    /// frame itself was not found).
    pub(crate) opening_m: (f64, f64),
    /// How far a frame's outer edges lie outside its glazing.
    pub(crate) frame_m: (f64, f64),
}

/// A frame's outer edges run along at least this share of the glazing's height.
const MIN_OUTER_COVER: f64 = 0.8;
/// How far the foot and top of a nearly flush opening may lie from where its standing sides end, metres: no frame
/// behind the wall tells them.
const FLUSH_END_REACH_M: f64 = 0.1;
/// The most distinct heights of lying edges inside a nearly flush opening ([`WallView::courses_within`]): a
/// frame's rails and its panes' edges.
const MAX_FLUSH_LEVELS: usize = 6;
/// Openings of one column have their sides within this of each other, and those of one row their foot and top,
/// metres ([`grid`]).
const GRID_TOLERANCE_M: f64 = 0.06;
/// The narrowest wall between two openings side by side or one above the other, metres
/// ([`rectangles::holds_another_beside`]): a frame's mullion or transom is narrower.
const MIN_PIER_M: f64 = 0.3;
/// Pieces of one side leave gaps of at most this, metres.
const MAX_SIDE_GAP_M: f64 = 0.3;
/// Edges a plane must carry to count as the wall an opening is cut into…
const MIN_WALL_EDGES: usize = 8;
/// …spread over at least this much across and up, metres (the reveals of a column of windows share a plane too).
const MIN_WALL_SPAN_M: f64 = 2.0;
/// Sides of one rectangle: positions across within this, metres…
const SIDE_TOLERANCE_M: f64 = 0.015;
/// …depths within this, metres…
const DEPTH_TOLERANCE_M: f64 = 0.03;
/// …the standing sides covered by their edges over at least this share (a frame's sides are often seen only in
/// part)…
const MIN_STANDING_COVER: f64 = 0.5;
/// …and the lying ones over this much: they run the whole width, and a lower share lets the tops of two
/// neighbouring windows at one height pass for one wide opening.
const MIN_LYING_COVER: f64 = 0.8;
/// Planes whose normals lie within this cosine (about 10°) are one wall's, for what a proposed or predicted opening
/// overlaps.
const NEAR_PLANE_COS: f64 = 0.985;

/// What the inference does to the faces.
pub(crate) enum Inferred {
    /// A face in the wall plane is the opening.
    Mark(usize),
    /// A new opening face on these new corners, with this outward normal.
    New {
        corners: Vec<Vertex>,
        normal: Vec3,
        /// Where the model has no face for the frame behind, the depth its proposal found: the opening gets its
        /// frame face and reveals (the other openings get theirs from [`add_frames`]).
        reveal_m: Option<f64>,
    },
}

mod evidence;
mod floating;
#[cfg(test)]
mod flush_tests;
mod frames;
mod glass;
mod grid;
mod panes;
mod recesses;
mod rectangles;
mod rows;
mod settle;
mod sides;
mod sills;
mod wall;
pub(crate) use evidence::Evidence;
pub(crate) use floating::floating_at_openings;
pub(crate) use frames::add_frames;
pub(crate) use glass::add_glass;
pub(crate) use panes::add_panes;
pub(crate) use sills::{add_sills, SillRule};
pub(crate) use wall::{Outline, Wall};
mod wall_from_edges;

use frames::*;
use grid::*;
use recesses::*;
use rectangles::*;
use rows::agreed_by_rows;
use settle::settle;
use sides::*;
use wall::*;
use wall_from_edges::*;

/// A rectangle behind a wall proposed as an opening, its depth behind the wall and the σ of its corners.
struct Proposal {
    wall: usize,
    rect: Rect,
    depth: f64,
    sigma: Option<Vec3>,
}

/// Openings inferred from recessed faces and from rectangles of recessed edges, for a model seen from `cameras`,
/// and the walls they were looked for on.
/// `edges` are the observed edges, before nearby vertices were merged for tracing the faces (noisy vertices
/// merged in chains take whole frames with them); `plane_edges` are the traced edges lying in each plane.
#[allow(clippy::too_many_arguments)]
pub(crate) fn infer(
    vertices: &[Vertex],
    edges: &[Edge],
    planes: &[Plane],
    plane_edges: &[Vec<&Edge>],
    faces: &[Face],
    tol: f64,
    params: &ModelParams,
    cameras: &Cameras,
    surface: &[[Vec3; 2]],
    evidence: Option<&Evidence>,
) -> (Vec<Inferred>, Vec<WallView>) {
    let Some(viewpoint) = cameras.mean() else {
        return (Vec::new(), Vec::new());
    };
    let centres = cameras.centres();
    let cos_par = params.plane_angle_deg.to_radians().cos();
    let outlines = Outline::of_faces(faces, vertices);
    let sizes = params.opening_sizes();
    let walls = walls(vertices, edges, planes, plane_edges, surface, cos_par, &viewpoint, sizes);
    // Recessed faces first, then rectangles; each only where no opening is on the wall there yet.
    let mut proposals = from_recesses(vertices, faces, &outlines, &walls, cos_par, centres, sizes);
    for (k, w) in walls.iter().enumerate() {
        proposals.extend(from_rectangles(w, centres).into_iter().map(|(rect, depth, sigma)| Proposal {
            wall: k,
            rect,
            depth,
            sigma,
        }));
    }
    let mut found: Vec<Outline> = faces
        .iter()
        .zip(&outlines)
        .filter(|(f, _)| matches!(f.kind, SurfaceKind::Window | SurfaceKind::Door))
        .map(|(_, o)| o.clone())
        .collect();
    // Each new opening's sides settled in the images, where they are given.
    let settled_in_images = |wall: &Wall, rect: Rect| match evidence.filter(|_| params.settle_openings) {
        Some(e) => settle(wall, rect, &viewpoint, e),
        None => rect,
    };
    let mut out = Vec::new();
    // The new openings: their place in `out`, their wall, their outline in `found`, whether their row and column
    // predicted them.
    let mut news: Vec<(usize, usize, usize, bool)> = Vec::new();
    for p in proposals {
        let wall = &walls[p.wall].wall;
        let [x0, x1, z0, z1] = p.rect.bounds;
        let centre = wall.point((x0 + x1) / 2.0, (z0 + z1) / 2.0, &viewpoint);
        let on_wall_here = |o: &Outline| o.on(wall, cos_par, sizes.recess_m.0) && o.contains(&centre);
        if found_near(&found, &wall.out, &centre, sizes.recess_m.0) {
            continue;
        }
        // An outline of about its size on the wall that closed without being taken for an opening (nothing nests
        // it yet) is the opening.
        let area = (x1 - x0) * (z1 - z0);
        let outline = (0..faces.len()).find(|&j| {
            let o = &outlines[j];
            on_wall_here(o)
                && faces[j].ring.iter().all(|&w| wall.depth(&vertices[w].point).abs() < tol)
                && o.area < 2.0 * area
                && o.area > 0.5 * area
        });
        match outline {
            Some(j) if faces[j].kind == SurfaceKind::Wall => {
                out.push(Inferred::Mark(j));
                found.push(outlines[j].clone());
            }
            Some(_) => {}
            None => {
                let rect = settled_in_images(wall, p.rect);
                let corners = opening_corners(wall, rect, p.depth, centres, p.sigma, &centre);
                news.push((out.len(), p.wall, found.len(), false));
                found.push(Outline::of(&corners.iter().map(|v| v.point).collect::<Vec<_>>(), wall.out));
                out.push(Inferred::New {
                    corners,
                    normal: wall.out,
                    // None where the model has a face behind already, or the frame is nearly flush (on the wall).
                    reveal_m: Some(p.depth)
                        .filter(|&d| d >= sizes.recess_m.0 && face_behind(&outlines, wall, rect.bounds, sizes, cos_par).is_none()),
                });
            }
        }
    }
    // The rows and columns of what was found on each wall predict what was missed.
    for (w, view) in walls.iter().enumerate() {
        let wall = &view.wall;
        let taken: Vec<[f64; 4]> = found
            .iter()
            .filter(|o| o.on(wall, cos_par, sizes.recess_m.0))
            .map(|o| o.bounds_in(wall))
            .collect();
        for rect in from_grid(view, &taken, &viewpoint, evidence.filter(|_| params.verify_openings)) {
            let [x0, x1, z0, z1] = rect.bounds;
            let centre = wall.point((x0 + x1) / 2.0, (z0 + z1) / 2.0, &viewpoint);
            if found_near(&found, &wall.out, &centre, sizes.recess_m.0) {
                continue;
            }
            let rect = settled_in_images(wall, rect);
            let corners = opening_corners(wall, rect, 0.0, centres, None, &centre);
            news.push((out.len(), w, found.len(), true));
            found.push(Outline::of(&corners.iter().map(|v| v.point).collect::<Vec<_>>(), wall.out));
            out.push(Inferred::New {
                corners,
                normal: wall.out,
                reveal_m: None,
            });
        }
    }
    // Each new opening with the sides its row and column agree on. Those found count; a predicted one copies its
    // row's and column's sides, and a row's wrong foot copied along it would outvote the openings that show it.
    let mut predicted = vec![false; found.len()];
    for n in news.iter().filter(|n| n.3) {
        predicted[n.2] = true;
    }
    for &(k, w, own, _) in &news {
        let wall = &walls[w].wall;
        let others: Vec<[f64; 4]> = (found.iter().enumerate())
            .filter(|&(j, o)| j != own && !predicted[j] && o.on(wall, cos_par, sizes.recess_m.0))
            .map(|(_, o)| o.bounds_in(wall))
            .collect();
        if let Inferred::New { corners, .. } = &mut out[k] {
            let at = |v: &Vertex| (v.point.dot(&wall.across), v.point.z);
            let ([x0, z0], [x1, z1]) = ([at(&corners[0]).0, at(&corners[0]).1], [at(&corners[2]).0, at(&corners[2]).1]);
            let [ax0, ax1, az0, az1] = agreed_by_rows([x0, x1, z0, z1], &others);
            for (v, (x, z)) in corners.iter_mut().zip([(ax0, az0), (ax1, az0), (ax1, az1), (ax0, az1)]) {
                v.point = wall.point(x, z, &v.point);
            }
        }
    }
    (out, walls)
}

/// Whether an opening already found on a wall whose normal lies within [`NEAR_PLANE_COS`] of `out` (the wall
/// proposing one, or a second plane fitted to a column of frames a few degrees off it), within `reach_m` of
/// `centre` across its plane, holds `centre`: it is the one proposed there.
fn found_near(found: &[Outline], out: &Vec3, centre: &Vec3, reach_m: f64) -> bool {
    found
        .iter()
        .any(|o| o.normal.dot(out).abs() > NEAR_PLANE_COS && (centre - o.centroid).dot(&o.normal).abs() < reach_m && o.contains(centre))
}

/// Adds the inferred openings to the model: marked faces become windows, new ones get their corners, their
/// outline as completed edges and a window face (`nest_openings` then cuts them into their walls and tells doors).
/// An opening whose proposal found its frame's depth also gets the frame face there and its reveals
/// ([`add_frame`]).
pub(crate) fn add(inferred: Vec<Inferred>, vertices: &mut Vec<Vertex>, edges: &mut Vec<Edge>, faces: &mut Vec<Face>) {
    for opening in inferred {
        match opening {
            Inferred::Mark(j) => faces[j].kind = SurfaceKind::Window,
            Inferred::New { corners, normal, reveal_m } => {
                let outline = add_face(corners, normal, SurfaceKind::Window, vertices, edges, faces);
                if let Some(depth) = reveal_m {
                    add_frame(&outline, normal, depth, SurfaceKind::Window, vertices, edges, faces);
                }
            }
        }
    }
}

/// A new face of `kind` on new `corners`, its outline as completed edges; the corners' indices.
pub(super) fn add_face(
    corners: Vec<Vertex>,
    normal: Vec3,
    kind: SurfaceKind,
    vertices: &mut Vec<Vertex>,
    edges: &mut Vec<Edge>,
    faces: &mut Vec<Face>,
) -> Vec<usize> {
    let first = vertices.len();
    vertices.extend(corners);
    let ring: Vec<usize> = (first..vertices.len()).collect();
    edges.extend(ring.iter().enumerate().map(|(k, &a)| Edge {
        a,
        b: ring[(k + 1) % ring.len()],
        line: usize::MAX,
        origin: EdgeOrigin::Inferred,
    }));
    faces.push(Face {
        ring: ring.clone(),
        holes: Vec::new(),
        normal,
        kind,
    });
    ring
}

/// The walls, most edges first: vertical planes whose edges (at least [`MIN_WALL_EDGES`]) spread
/// [`MIN_WALL_SPAN_M`] across and up and outnumber those of every parallel plane within the deepest recess of them (a row
/// of sill fronts, the reveals of a column of windows or a frame's own plane are no wall), each with the observed
/// edges behind it gathered into sides. Where no face makes a wall, the edges alone may, with the `surface` lines
/// ([`wall_from_edges`]).
#[allow(clippy::too_many_arguments)]
fn walls(
    vertices: &[Vertex],
    edges: &[Edge],
    planes: &[Plane],
    plane_edges: &[Vec<&Edge>],
    surface: &[[Vec3; 2]],
    cos_par: f64,
    viewpoint: &Vec3,
    sizes: OpeningSizes,
) -> Vec<WallView> {
    let spread = |p: &Plane, on: &[&Edge]| {
        let across = Vec3::z().cross(&p.normal).try_normalize(1e-9).unwrap_or(Vec3::x());
        let ends: Vec<Vec3> = on.iter().flat_map(|e| [vertices[e.a].point, vertices[e.b].point]).collect();
        let span = |f: &dyn Fn(&Vec3) -> f64| {
            let v: Vec<f64> = ends.iter().map(f).collect();
            max(&v) - min(&v)
        };
        span(&|q| q.dot(&across)) >= MIN_WALL_SPAN_M && span(&|q| q.z) >= MIN_WALL_SPAN_M
    };
    // Where a plane's edges lie: a plane a few degrees off another (fitted to a column of frames) crosses it
    // somewhere along the façade, so offsets alone do not tell how far apart the two are where it matters.
    let centroids: Vec<Vec3> = plane_edges
        .iter()
        .map(|on| on.iter().map(|e| vertices[e.a].point + vertices[e.b].point).sum::<Vec3>() / (2 * on.len()).max(1) as f64)
        .collect();
    // A plane within 10° of another with its edges within the deepest recess of it: a frame's plane, a column of
    // frames, a row of sill fronts in front of that wall, or the same wall twice.
    let within = |p: &Plane, centroid: &Vec3, wall: &Plane| {
        p.normal.dot(&wall.normal).abs() > NEAR_PLANE_COS && (wall.normal.dot(centroid) - wall.offset).abs() <= sizes.recess_m.1
    };
    let parallel_near = |k: usize, j: usize| within(&planes[j], &centroids[j], &planes[k]) || within(&planes[k], &centroids[k], &planes[j]);
    let mut chosen: Vec<(usize, usize)> = (0..planes.len())
        .filter(|&k| {
            let (p, n) = (&planes[k], plane_edges[k].len());
            n >= MIN_WALL_EDGES
                && p.normal.z.abs() < (1.0 - cos_par * cos_par).sqrt()
                // Of two hypotheses that converged on one plane (as many edges), the first stands for both.
                && (0..planes.len()).all(|j| {
                    j == k || !parallel_near(k, j) || plane_edges[j].len() < n || (plane_edges[j].len() == n && j > k)
                })
                && spread(p, &plane_edges[k])
        })
        .map(|k| (plane_edges[k].len(), k))
        .collect();
    chosen.sort_by(|a, b| b.0.cmp(&a.0).then(a.1.cmp(&b.1)));
    let mut chosen: Vec<usize> = chosen.into_iter().map(|(_, k)| k).collect();
    // The faces' planes count closed faces, and deep frames close more of them than the wall in front: the wall of
    // the edges comes first, in place of the planes within a recess of it.
    let from_edges = wall_from_edges(vertices, edges, surface, viewpoint);
    if let Some(wall) = &from_edges {
        chosen.retain(|&k| !within(&planes[k], &centroids[k], wall));
    }
    let chosen: Vec<Plane> = from_edges.into_iter().chain(chosen.into_iter().map(|k| planes[k])).collect();
    // The surface lines as edges of their own: the courses they are run across the wall too.
    let surface_vertices: Vec<Vertex> = surface.iter().flatten().map(|&point| Vertex { point, sigma: None }).collect();
    let surface_edges: Vec<Edge> = (0..surface.len())
        .map(|k| Edge {
            a: 2 * k,
            b: 2 * k + 1,
            line: usize::MAX,
            origin: EdgeOrigin::Observed,
        })
        .collect();
    chosen
        .into_iter()
        .filter_map(|plane| {
            let observed = [(vertices, edges), (&surface_vertices[..], &surface_edges[..])];
            let wall = Wall::facing(plane, viewpoint)?.settled(observed, sizes.recess_m.0);
            // Up to where a recess starts, so that a nearly flush frame (3 to 6 cm back) is on the wall, not lost
            // between the two.
            let on_wall = (-DEPTH_TOLERANCE_M, sizes.recess_m.0);
            // The courses on the wall, among its edges and among the surface lines left out of the model (on brick
            // the line stage classes most courses texture, and a pier between two windows would look bare).
            let mut courses = pieces(&wall, vertices, edges, false, on_wall);
            courses.extend(pieces(&wall, &surface_vertices, &surface_edges, false, on_wall));
            courses.sort_by(|x, y| x.0.total_cmp(&y.0).then(x.1.total_cmp(&y.1)).then(x.2.total_cmp(&y.2)));
            Some(WallView {
                lying_pieces_on_wall: courses,
                standing_pieces_on_wall: pieces(&wall, vertices, edges, true, on_wall),
                standing: sides(&wall, vertices, edges, true, sizes.recess_m),
                lying: sides(&wall, vertices, edges, false, sizes.recess_m),
                standing_on_wall: sides(&wall, vertices, edges, true, on_wall),
                lying_on_wall: sides(&wall, vertices, edges, false, on_wall),
                wall,
                sizes,
            })
        })
        .collect()
}

#[cfg(test)]
pub(super) mod tests {
    use super::*;
    use crate::faces::find;

    /// Brick joints drawn on the wall (a wall carries more edges than anything behind it).
    const JOINTS: usize = 8;
    /// First point of the frame's sides.
    const FRAME: usize = 4 + 2 * JOINTS;

    pub(super) fn vertex(p: [f64; 3]) -> Vertex {
        Vertex {
            point: Vec3::from(p),
            sigma: Some(Vec3::repeat(0.002)),
        }
    }

    pub(super) fn edge(a: usize, b: usize) -> Edge {
        Edge {
            a,
            b,
            line: a,
            origin: EdgeOrigin::Observed,
        }
    }

    /// The face on the vertices from `first` on: the opening of the true outline, x 1–2.4 m, z 2–3.7 m.
    fn assert_true_opening(vertices: &[Vertex], faces: &[Face], first: usize, case: &str) {
        assert_opening(vertices, faces, first, 2.4, case);
    }

    /// The face on the vertices from `first` on: the opening x 1–`x1` m, z 2–3.7 m.
    fn assert_opening(vertices: &[Vertex], faces: &[Face], first: usize, x1: f64, case: &str) {
        let opening = faces.iter().find(|f| f.ring.iter().all(|&k| k >= first)).expect("an opening");
        assert_eq!(opening.kind, SurfaceKind::Window, "{case}");
        let mut corners: Vec<[f64; 3]> = opening.ring.iter().map(|&k| vertices[k].point.into()).collect();
        corners.sort_by(|a, b| a[2].total_cmp(&b[2]).then(a[0].total_cmp(&b[0])));
        let expected = [[1.0, 0.0, 2.0], [x1, 0.0, 2.0], [1.0, 0.0, 3.7], [x1, 0.0, 3.7]];
        for (c, e) in corners.iter().zip(expected) {
            assert!((Vec3::from(*c) - Vec3::from(e)).norm() < 1e-9, "{case}: {corners:?}");
        }
    }

    /// A wall y = 0 facing −y (its outline and [`JOINTS`] brick joints) and, 20 cm behind it, a window frame 1.4 × 1.7 m
    /// whose foot the 3-D lines put where the line of sight over the opening's foot meets the frame: cameras below
    /// see the frame's top edge through the soffit, but not its foot. With `overshoot` > 0 each side of the frame is
    /// its own line running that far past the corners (no junction found, no face); with `outline`, the opening's
    /// own outline on the wall is there too.
    fn scene(overshoot: f64, outline: bool) -> (Vec<Vertex>, Vec<Edge>, Vec3) {
        let viewpoint = Vec3::new(1.7, -19.0, 1.6);
        let foot = viewpoint.z + (2.0 - viewpoint.z) * 19.2 / 19.0;
        let o = overshoot;
        let mut points = vec![[-1.0, 0.0, 0.0], [5.0, 0.0, 0.0], [5.0, 0.0, 6.0], [-1.0, 0.0, 6.0]];
        for k in 0..JOINTS {
            let z = 4.2 + 0.2 * k as f64;
            points.extend([[0.0, 0.0, z], [4.0, 0.0, z]]);
        }
        points.extend([
            [1.0 - o, 0.2, foot],
            [2.4 + o, 0.2, foot],
            [2.4, 0.2, foot - o],
            [2.4, 0.2, 3.7 + o],
        ]);
        points.extend([[2.4 + o, 0.2, 3.7], [1.0 - o, 0.2, 3.7], [1.0, 0.2, 3.7 + o], [1.0, 0.2, foot - o]]);
        if outline {
            points.extend([[1.0, 0.0, 2.0], [2.4, 0.0, 2.0], [2.4, 0.0, 3.7], [1.0, 0.0, 3.7]]);
        }
        let vertices = points.into_iter().map(vertex).collect();
        let ring = |first: usize| (0..4).map(move |k| edge(first + k, first + (k + 1) % 4));
        let mut edges: Vec<Edge> = ring(0).collect();
        edges.extend((0..JOINTS).map(|k| edge(4 + 2 * k, 5 + 2 * k)));
        let f = FRAME;
        if overshoot > 0.0 {
            edges.extend((0..4).map(|k| edge(f + 2 * k, f + 1 + 2 * k)));
        } else {
            // Without overshoot the sides meet: one closed frame.
            edges.extend([edge(f, f + 1), edge(f + 1, f + 4), edge(f + 4, f + 5), edge(f + 5, f)]);
        }
        if outline {
            edges.extend(ring(FRAME + 8));
        }
        (vertices, edges, viewpoint)
    }

    #[test]
    fn a_frame_behind_a_wall_whose_outline_did_not_close_makes_the_opening_in_it() {
        // Closed, the frame is a recessed face; open at its corners, a rectangle of edges, and then the model has
        // no face for the frame: the opening gets one, 20 cm behind its outline, and its four reveals.
        for (overshoot, frame) in [(0.0, false), (0.03, true)] {
            let (mut vertices, mut edges, viewpoint) = scene(overshoot, false);
            let n = vertices.len();
            let faces = find(&mut vertices, &mut edges, &ModelParams::default(), &viewpoint.into());
            let new_corners = if frame { 8 } else { 4 };
            assert_eq!(vertices.len(), n + new_corners, "overshoot {overshoot}: {faces:?}");
            assert_true_opening(&vertices, &faces, n, &format!("overshoot {overshoot}"));
            // Its outline (and the frame's, and the reveals) are completed, not observed; the outline is cut into
            // the wall.
            assert_eq!(
                edges.iter().filter(|e| e.origin == EdgeOrigin::Inferred).count(),
                if frame { 12 } else { 4 }
            );
            let wall = faces.iter().find(|f| f.ring.contains(&0)).expect("wall");
            assert_eq!((wall.kind, wall.holes.len()), (SurfaceKind::Wall, 1));
            if frame {
                let back = faces.iter().find(|f| f.ring.iter().all(|&k| k >= n + 4)).expect("the frame's face");
                assert_eq!(back.kind, SurfaceKind::Window);
                for (k, &v) in back.ring.iter().enumerate() {
                    let front = vertices[n + k].point;
                    assert!((vertices[v].point - front - Vec3::new(0.0, 0.2, 0.0)).norm() < 1e-9, "{back:?}");
                    assert!(edges.iter().any(|e| e.origin == EdgeOrigin::Inferred && (e.a, e.b) == (n + k, v)));
                }
            }
        }
    }

    #[test]
    fn the_openings_own_edge_on_the_wall_stands_in_for_a_hidden_side_of_its_frame() {
        // The frame's right side hidden behind the reveal (a window beyond the strip's end): alone, the other three
        // make no opening; with the opening's right edge seen on the wall, they do.
        for seen_on_wall in [false, true] {
            let (mut vertices, mut edges, viewpoint) = scene(0.03, false);
            edges.retain(|e| e.a != FRAME + 2);
            if seen_on_wall {
                vertices.extend([[2.4, 0.0, 2.0], [2.4, 0.0, 3.7]].map(vertex));
                edges.push(edge(vertices.len() - 2, vertices.len() - 1));
            }
            let n = vertices.len();
            let faces = find(&mut vertices, &mut edges, &ModelParams::default(), &viewpoint.into());
            if seen_on_wall {
                assert_true_opening(&vertices, &faces, n, "right side on the wall");
            } else {
                assert_eq!(vertices.len(), n, "three sides: {faces:?}");
            }
        }
    }

    /// The bounds [x0, x1, z0, z1] of the opening on the vertices from `first` on, on the wall plane y = 0.
    fn opening_bounds(vertices: &[Vertex], faces: &[Face], first: usize) -> [f64; 4] {
        let opening = faces.iter().find(|f| f.ring.iter().all(|&k| k >= first)).expect("an opening");
        let p: Vec<Vec3> = opening.ring.iter().map(|&k| vertices[k].point).collect();
        assert!(p.iter().all(|q| q.y.abs() < 1e-9), "{p:?}");
        let (xs, zs): (Vec<f64>, Vec<f64>) = p.iter().map(|q| (q.x, q.z)).unzip();
        [min(&xs), max(&xs), min(&zs), max(&zs)]
    }

    fn assert_bounds(found: [f64; 4], expected: [f64; 4], case: &str) {
        assert!(
            found.iter().zip(expected).all(|(a, b)| (a - b).abs() < 1e-9),
            "{case}: {found:?}, expected {expected:?}"
        );
    }

    /// The wall and its joints of [`scene`], a frame 20 cm behind it whose edges are `frame` (pairs of ends), and
    /// `on_wall` edges on the wall.
    fn frame_behind_wall(frame: &[([f64; 2], [f64; 2])], upright: &[bool], on_wall: &[([f64; 3], [f64; 3])]) -> (Vec<Vertex>, Vec<Edge>) {
        let (mut vertices, mut edges, _) = scene(0.0, false);
        edges.retain(|e| e.a < FRAME);
        vertices.truncate(FRAME);
        for (&(a, b), &up) in frame.iter().zip(upright) {
            // (x, z from, z to) standing or (z, x from, x to) lying.
            let (p, q) = if up {
                ([a[0], 0.2, a[1]], [b[0], 0.2, b[1]])
            } else {
                ([a[1], 0.2, a[0]], [b[1], 0.2, b[0]])
            };
            vertices.extend([p, q].map(vertex));
            edges.push(edge(vertices.len() - 2, vertices.len() - 1));
        }
        for &(p, q) in on_wall {
            vertices.extend([p, q].map(vertex));
            edges.push(edge(vertices.len() - 2, vertices.len() - 1));
        }
        (vertices, edges)
    }

    #[test]
    fn a_side_no_camera_saw_the_outer_edge_of_is_widened_by_the_frame_found_on_the_other() {
        // The glazing's left edge at 1.06, the frame's outer right edge at 2.4 with the glazing's 6 cm inside it,
        // top and foot at 3.7 and 2.0 (cameras between them see both). Cameras all left of 1.06 cannot see the
        // frame's outer left edge (the reveal hides it): it is a frame's width out. With a camera right of it,
        // which would have seen it, nothing says so.
        let frame = [
            ([1.06, 2.0], [1.06, 3.7]),
            ([2.4, 2.0], [2.4, 3.7]),
            ([2.34, 2.06], [2.34, 3.64]),
            ([3.7, 1.06], [3.7, 2.4]),
            ([2.0, 1.06], [2.0, 2.4]),
        ];
        let upright = [true, true, true, false, false];
        for (xs, x0) in [([-1.5, -1.0], 1.0), ([-1.0, 1.5], 1.06)] {
            let (mut vertices, mut edges) = frame_behind_wall(&frame, &upright, &[]);
            let cameras = Cameras::new(xs.iter().map(|&x| Vec3::new(x, -19.0, 3.0)).collect());
            let n = vertices.len();
            let faces = find(&mut vertices, &mut edges, &ModelParams::default(), &cameras);
            assert_bounds(
                opening_bounds(&vertices, &faces, n),
                [x0, 2.4, 2.0, 3.7],
                &format!("cameras at x {xs:?}"),
            );
        }
    }

    #[test]
    fn a_foot_above_every_camera_is_the_openings_own_edge_on_the_wall_a_frames_width_below_the_glazing() {
        // Cameras below the foot see the glazing's foot (2.06) over the sill, not the frame's (2.0); the frame's
        // outer sides at 1.0 and 2.4 (the glazing 6 cm inside the right one) tell its width. The opening's foot on
        // the wall, seen, is the foot; without it the glazing's foot is moved back along the line of sight only.
        let frame = [
            ([1.0, 2.06], [1.0, 3.7]),
            ([2.4, 2.06], [2.4, 3.7]),
            ([2.34, 2.06], [2.34, 3.64]),
            ([3.7, 1.0], [3.7, 2.4]),
            ([2.06, 1.06], [2.06, 2.34]),
        ];
        let upright = [true, true, true, false, false];
        let camera = Cameras::from(Vec3::new(1.7, -19.0, 1.6));
        for with_wall_foot in [true, false] {
            let foot = [([1.0, 0.0, 2.0], [2.4, 0.0, 2.0])];
            let (mut vertices, mut edges) = frame_behind_wall(&frame, &upright, if with_wall_foot { &foot } else { &[] });
            let n = vertices.len();
            let faces = find(&mut vertices, &mut edges, &ModelParams::default(), &camera);
            let expected_foot = if with_wall_foot { 2.0 } else { 1.6 + (2.06 - 1.6) * 19.0 / 19.2 };
            assert_bounds(
                opening_bounds(&vertices, &faces, n),
                [1.0, 2.4, expected_foot, 3.7],
                &format!("foot on the wall {with_wall_foot}"),
            );
        }
    }

    #[test]
    fn a_frame_behind_an_outline_that_closed_adds_no_opening_and_its_sides_give_the_reveals() {
        // Closed, the frame is a face of the model already; as four lines, it gives the frame's depth: a face 20 cm
        // behind the outline, on its corners, with the four reveals.
        for (overshoot, frame) in [(0.0, false), (0.03, true)] {
            let (mut vertices, mut edges, viewpoint) = scene(overshoot, true);
            let n = vertices.len();
            let faces = find(&mut vertices, &mut edges, &ModelParams::default(), &viewpoint.into());
            assert_eq!(vertices.len(), if frame { n + 4 } else { n }, "overshoot {overshoot}");
            let outline = faces
                .iter()
                .find(|f| f.ring.iter().all(|&k| (FRAME + 8..n).contains(&k)))
                .expect("the outline's face");
            assert_eq!(outline.kind, SurfaceKind::Window);
            if frame {
                let back = faces.iter().find(|f| f.ring.iter().all(|&k| k >= n)).expect("the frame's face");
                assert_eq!(back.kind, SurfaceKind::Window);
                for (&a, &b) in outline.ring.iter().zip(&back.ring) {
                    assert!((vertices[b].point - vertices[a].point - Vec3::new(0.0, 0.2, 0.0)).norm() < 1e-9);
                    assert!(edges.iter().any(|e| e.origin == EdgeOrigin::Inferred && (e.a, e.b) == (a, b)));
                }
            }
        }
    }

    #[test]
    fn one_side_of_a_frame_gives_the_reveals_and_two_that_disagree_give_none() {
        // The frame's right side (its points FRAME + 2 and + 3) hidden from the cameras, as a deep reveal hides
        // one side from most of a strip; or 10 cm deeper than the left one.
        for (case, expected) in [("hidden", Some(0.2)), ("deeper", None)] {
            let (mut vertices, mut edges, viewpoint) = scene(0.03, true);
            if case == "hidden" {
                edges.retain(|e| (e.a, e.b) != (FRAME + 2, FRAME + 3));
            } else {
                vertices[FRAME + 2].point.y = 0.3;
                vertices[FRAME + 3].point.y = 0.3;
            }
            let n = vertices.len();
            let faces = find(&mut vertices, &mut edges, &ModelParams::default(), &viewpoint.into());
            let back = faces.iter().find(|f| f.ring.iter().all(|&k| k >= n));
            let depth = back.map(|f| vertices[f.ring[0]].point.y);
            assert_eq!(depth.map(|d| (d * 1e6).round() / 1e6), expected, "{case}");
        }
    }

    #[test]
    fn a_nearly_flush_frame_gives_the_reveals_from_the_corners_behind_the_wall_at_its_sides() {
        // The frame 4 cm behind the wall, among the wall's own edges: its standing sides are the reveals' inner
        // corners, beside the outline's own sides on the face. 1 cm back, it is the wall.
        for (back, expected) in [(0.04, Some(0.04)), (0.01, None)] {
            let (mut vertices, mut edges, viewpoint) = scene(0.03, true);
            for v in &mut vertices[FRAME..FRAME + 8] {
                v.point.y = back;
            }
            let n = vertices.len();
            let faces = find(&mut vertices, &mut edges, &ModelParams::default(), &viewpoint.into());
            let frame = faces.iter().find(|f| f.ring.iter().all(|&k| k >= n));
            let depth = frame.map(|f| (vertices[f.ring[0]].point.y * 1e6).round() / 1e6);
            assert_eq!(depth, expected, "{back}");
        }
    }

    #[test]
    fn a_glazing_outline_inside_its_frame_is_widened_to_the_frame() {
        // Only the frame's outer sides (no top, no foot; or only its left one) and, 6 cm inside, the glazing's
        // outline: closed (a recessed face) or its sides apart at the corners (a rectangle).
        for (overshoot, both) in [(0.0, true), (0.03, true), (0.0, false), (0.03, false)] {
            let (mut vertices, mut edges, viewpoint) = scene(0.0, false);
            edges.retain(|e| e.a < FRAME);
            let n = vertices.len();
            let foot = vertices[FRAME].point.z;
            let o = overshoot;
            let (x0, x1, z0, z1) = (1.06, 2.34, foot + 0.06, 3.64);
            let mut points = vec![[1.0, 0.2, foot], [1.0, 0.2, 3.7], [2.4, 0.2, foot], [2.4, 0.2, 3.7]];
            points.extend([[x0 - o, 0.2, z0], [x1 + o, 0.2, z0], [x1, 0.2, z0 - o], [x1, 0.2, z1 + o]]);
            points.extend([[x1 + o, 0.2, z1], [x0 - o, 0.2, z1], [x0, 0.2, z1 + o], [x0, 0.2, z0 - o]]);
            vertices.extend(points.into_iter().map(vertex));
            edges.push(edge(n, n + 1));
            if both {
                edges.push(edge(n + 2, n + 3));
            }
            let g = n + 4;
            if overshoot > 0.0 {
                edges.extend((0..4).map(|k| edge(g + 2 * k, g + 1 + 2 * k)));
            } else {
                edges.extend([edge(g, g + 1), edge(g + 1, g + 4), edge(g + 4, g + 5), edge(g + 5, g)]);
            }
            let before = vertices.len();
            let faces = find(&mut vertices, &mut edges, &ModelParams::default(), &viewpoint.into());
            // With one outer side, the other moves out by the frame's width found on it.
            assert_true_opening(
                &vertices,
                &faces,
                before,
                &format!("glazing, overshoot {overshoot}, both sides {both}"),
            );
        }
    }

    #[test]
    fn a_rectangle_already_on_the_frame_on_one_side_is_widened_on_the_other_only() {
        // The rectangle runs from the frame's outer left edge (the glazing's left edge 6 cm inside it) to the
        // glazing's right edge (the frame's outer right edge 6 cm outside it).
        let (mut vertices, mut edges, viewpoint) = scene(0.0, false);
        edges.retain(|e| e.a < FRAME);
        let n = vertices.len();
        let foot = vertices[FRAME].point.z;
        let (z0, z1) = (foot + 0.06, 3.64);
        vertices.extend(
            [
                [1.0, 0.2, z0],
                [2.34, 0.2, z0],
                [2.34, 0.2, z1],
                [1.0, 0.2, z1],
                [1.06, 0.2, z0],
                [1.06, 0.2, z1],
                [2.4, 0.2, foot],
                [2.4, 0.2, 3.7],
            ]
            .map(vertex),
        );
        edges.extend((0..4).map(|k| edge(n + k, n + (k + 1) % 4)));
        edges.extend([edge(n + 4, n + 5), edge(n + 6, n + 7)]);
        let before = vertices.len();
        let faces = find(&mut vertices, &mut edges, &ModelParams::default(), &viewpoint.into());
        let opening = faces.iter().find(|f| f.ring.iter().all(|&k| k >= before)).expect("an opening");
        let xs: Vec<f64> = opening.ring.iter().map(|&k| vertices[k].point.x).collect();
        assert!(xs.iter().all(|x| (x - 1.0).abs() < 1e-9 || (x - 2.4).abs() < 1e-9), "{xs:?}");
    }

    #[test]
    fn two_hypotheses_of_one_wall_plane_make_one_wall() {
        // Plane hypotheses from different corners can converge on the same plane, with the same edges: each must
        // not disqualify the other as "a parallel plane with as many edges".
        let (vertices, edges, viewpoint) = scene(0.0, false);
        let wall = Plane {
            normal: Vec3::new(0.0, 1.0, 0.0),
            offset: 0.0,
        };
        let in_wall: Vec<&Edge> = edges.iter().filter(|e| e.a < FRAME).collect();
        let cos_par = ModelParams::default().plane_angle_deg.to_radians().cos();
        let found = walls(
            &vertices,
            &edges,
            &[wall, wall],
            &[in_wall.clone(), in_wall],
            &[],
            cos_par,
            &viewpoint,
            ModelParams::default().opening_sizes(),
        );
        assert_eq!(found.len(), 1);
    }

    #[test]
    fn an_opening_found_on_a_wall_a_few_degrees_off_is_the_one_proposed_there() {
        // A window 1 to 2 m across and up on the wall y = 0 facing −y.
        let found = [Outline::of(
            &[[1.0, 0.0, 1.0], [2.0, 0.0, 1.0], [2.0, 0.0, 2.0], [1.0, 0.0, 2.0]].map(|p| Vec3::new(p[0], p[1], p[2])),
            Vec3::new(0.0, -1.0, 0.0),
        )];
        let turned = |deg: f64| Vec3::new(deg.to_radians().sin(), -deg.to_radians().cos(), 0.0);
        let centre = Vec3::new(1.5, 0.03, 1.53);
        assert!(found_near(&found, &turned(3.0), &centre, 0.1));
        // A wall at right angles, a point beside the window or far behind the wall: another opening.
        assert!(!found_near(&found, &turned(90.0), &centre, 0.1));
        assert!(!found_near(&found, &turned(3.0), &Vec3::new(2.5, 0.0, 1.5), 0.1));
        assert!(!found_near(&found, &turned(3.0), &Vec3::new(1.5, 0.5, 1.5), 0.1));
    }

    #[test]
    fn a_pane_on_its_own_makes_no_opening() {
        // A 0.6 m pane behind the wall, its frame not found: smaller than any opening inferred this way.
        let (mut vertices, mut edges, viewpoint) = scene(0.0, false);
        let base = vertices.len();
        vertices.extend([[3.0, 0.2, 4.0], [3.6, 0.2, 4.0], [3.6, 0.2, 5.0], [3.0, 0.2, 5.0]].map(vertex));
        edges.extend((0..4).map(|k| edge(base + k, base + (k + 1) % 4)));
        find(&mut vertices, &mut edges, &ModelParams::default(), &viewpoint.into());
        // Only the frame's opening is new.
        assert_eq!(vertices.len(), base + 4 + 4);
    }
}
