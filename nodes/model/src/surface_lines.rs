//! Lines lying inside a wall's surface: mortar, tile and panel joints, painted lines. The line stages rightly
//! report them (they are lines of the images and lie on the building), but they are no edges of the building
//! model, and on a brick façade they outnumber its edges ten to one. The model keeps them aside, in
//! [`crate::Model::surface_lines`].
//!
//! A line is taken for one when both its ends lie in a wall's surface (within `surface_band_m` of the wall the
//! openings are found on), well inside the wall's extent (more than `surface_margin_m` from where its edges end:
//! the wall's outline stays), on no face but the wall's own (a window's or a roof's outline stays), neither of
//! its ends is a corner with an edge that leaves the surface (an opening's outline meets its reveals there, a
//! cornice's foot its returns; a mortar course meets nothing that leaves the wall), its middle lies in no window
//! or door (their frames and panes stay), and it lies in a field of parallel lines like it (courses, rows of
//! tiles; the outline of an opening on a plain wall, its reveals unseen, is alone). Measured in docs/model.md.
use lineflow_photogrammetry::Vec3;

use crate::openings::{Outline, Wall};
use crate::surface::{Face, SurfaceKind};
use crate::{Edge, Vertex};
use lineflow_linegeom::{azimuth_mod_quarter, signed_quarter};

/// The settings of the separation.
#[derive(Debug, Clone)]
pub(crate) struct SurfaceRule {
    /// How far off a wall's surface a line's ends may lie, metres.
    pub(crate) band_m: f64,
    /// How far inside the wall's extent they lie at least, metres.
    pub(crate) margin_m: f64,
    /// A field: this many parallel candidates…
    pub(crate) neighbours: usize,
    /// …within this distance across, metres.
    pub(crate) reach_m: f64,
    /// The building's plan directions (azimuths modulo 90°, radians): only walls along one of them are surfaces.
    pub(crate) plan_azimuths: Vec<f64>,
    /// How far a wall may be off plumb and off a plan direction, radians.
    pub(crate) angle_rad: f64,
}

impl SurfaceRule {
    /// A plumb wall along one of the building's plan directions; the plane hypotheses of the faces include
    /// planes a few degrees off through a wall's texture, which would take every line for a surface line.
    fn is_surface(&self, wall: &Wall) -> bool {
        let azimuth = azimuth_mod_quarter(&wall.across);
        wall.out.z.abs() < self.angle_rad.sin()
            && self
                .plan_azimuths
                .iter()
                .any(|&a| signed_quarter(azimuth - a).abs() < self.angle_rad)
    }
}

/// Takes the surface lines out of `edges` (completed edges are never surface lines) and returns them as vertex
/// pairs; the wall faces traced from them alone (a brick's outline between its joints) go too. Each vertex belongs
/// to the first wall (of `walls`, most edges first) whose surface it lies in. An edge of an input line the line
/// stage classed texture (`texture[edge.line]`) goes too unless it is a corner of a window, door or roof face or
/// lies in an opening: it need not lie in the wall's surface (on short baselines a course's depth is off by
/// centimetres to decimetres).
pub(crate) fn separate(
    vertices: &[Vertex],
    edges: &mut Vec<Edge>,
    faces: &mut Vec<Face>,
    walls: &[Wall],
    texture: &[bool],
    rule: &SurfaceRule,
) -> Vec<[usize; 2]> {
    let n = vertices.len();
    // Corners of a face that is no wall (a window, a door, a roof): what meets there is structure.
    let mut on_other_face = vec![false; n];
    for f in faces.iter().filter(|f| f.kind != SurfaceKind::Wall) {
        for &v in f.ring.iter().chain(f.holes.iter().flatten()) {
            on_other_face[v] = true;
        }
    }
    let walls: Vec<&Wall> = walls.iter().filter(|w| rule.is_surface(w)).collect();
    let mut wall_of: Vec<Option<usize>> = vec![None; n];
    for (k, wall) in walls.iter().enumerate() {
        for (v, vertex) in vertices.iter().enumerate() {
            if wall_of[v].is_none() && wall.depth(&vertex.point).abs() <= rule.band_m {
                wall_of[v] = Some(k);
            }
        }
    }
    let mut inside = vec![false; n];
    for (k, wall) in walls.iter().enumerate() {
        let own = |v: usize| wall_of[v] == Some(k);
        let Some([u0, u1, z0, z1]) = extent(vertices, edges, wall, own) else {
            continue;
        };
        let m = rule.margin_m;
        for v in (0..n).filter(|&v| own(v)) {
            let (u, z) = (vertices[v].point.dot(&wall.across), vertices[v].point.z);
            inside[v] = u > u0 + m && u < u1 - m && z > z0 + m && z < z1 - m;
        }
    }
    // An edge with one end in a wall's surface and the other well off it (a reveal, a sill's side, a return)
    // anchors that end.
    let mut anchored = vec![false; n];
    for e in edges.iter() {
        for (here, there) in [(e.a, e.b), (e.b, e.a)] {
            if let Some(k) = wall_of[here] {
                anchored[here] |= walls[k].depth(&vertices[there].point).abs() > 2.0 * rule.band_m;
            }
        }
    }
    let free = |v: usize| inside[v] && !anchored[v] && !on_other_face[v];
    let openings = OpeningBoxes::of(vertices, faces, walls.clone(), rule.band_m);
    let in_opening = |e: &Edge| openings.holds(&((vertices[e.a].point + vertices[e.b].point) / 2.0));
    let candidate = |e: &Edge| e.observed() && free(e.a) && free(e.b) && wall_of[e.a] == wall_of[e.b] && !in_opening(e);
    let candidates: Vec<usize> = (0..edges.len()).filter(|&k| candidate(&edges[k])).collect();
    let in_field = in_a_field(vertices, edges, &candidates, &walls, &wall_of, rule);
    let classed = |e: &Edge| {
        texture.get(e.line).copied().unwrap_or(false) && e.observed() && !on_other_face[e.a] && !on_other_face[e.b] && !in_opening(e)
    };
    let mut is_surface: Vec<bool> = edges.iter().map(classed).collect();
    for (&k, &f) in candidates.iter().zip(&in_field) {
        is_surface[k] |= f;
    }
    let surface_lines: Vec<[usize; 2]> = (0..edges.len())
        .filter(|&k| is_surface[k])
        .map(|k| [edges[k].a, edges[k].b])
        .collect();
    let mut k = 0;
    edges.retain(|_| {
        k += 1;
        !is_surface[k - 1]
    });
    faces.retain(|f| f.kind != SurfaceKind::Wall || !f.holes.is_empty() || !f.ring.iter().all(|&v| free(v)));
    surface_lines
}

/// How far behind or before a wall an opening's frames and panes may lie, metres.
const RECESS_REACH_M: f64 = 0.5;

/// The window and door faces as boxes `[u0, u1, z0, z1]` in their wall's coordinates, each with its wall.
pub(crate) struct OpeningBoxes<'a> {
    walls: Vec<&'a Wall>,
    boxes: Vec<(usize, [f64; 4])>,
}

impl<'a> OpeningBoxes<'a> {
    /// The boxes of the window and door faces of `walls`, grown by `grow`: a line along an opening's outline or
    /// inside it (its frame, its panes) is no course of the wall.
    pub(crate) fn of(vertices: &[Vertex], faces: &[Face], walls: Vec<&'a Wall>, grow: f64) -> OpeningBoxes<'a> {
        let parallel = |f: &Face, w: &Wall| f.normal.dot(&w.out).abs() > 0.99;
        let boxes = faces
            .iter()
            .filter(|f| matches!(f.kind, SurfaceKind::Window | SurfaceKind::Door))
            .filter_map(|f| {
                let w = (0..walls.len()).find(|&w| {
                    parallel(f, walls[w]) && f.ring.iter().all(|&v| walls[w].depth(&vertices[v].point).abs() < RECESS_REACH_M)
                })?;
                let ring: Vec<Vec3> = f.ring.iter().map(|&v| vertices[v].point).collect();
                let [u0, u1, z0, z1] = Outline::of(&ring, f.normal).bounds_in(walls[w]);
                Some((w, [u0 - grow, u1 + grow, z0 - grow, z1 + grow]))
            })
            .collect();
        OpeningBoxes { walls, boxes }
    }

    /// Whether `p` lies in a box, within the deepest recess of its wall.
    pub(crate) fn holds(&self, p: &Vec3) -> bool {
        self.boxes.iter().any(|&(w, [u0, u1, z0, z1])| {
            let u = p.dot(&self.walls[w].across);
            self.walls[w].depth(p).abs() < RECESS_REACH_M && u >= u0 && u <= u1 && p.z >= z0 && p.z <= z1
        })
    }
}

/// A level or plumb line in its wall's coordinates: its position across its direction and its extent along it.
#[derive(Debug, Clone, Copy)]
struct Span {
    wall: usize,
    upright: bool,
    across: f64,
    from: f64,
    to: f64,
}

impl Span {
    /// The span of an edge within a few degrees of level or plumb; slanted ones form no courses.
    fn of(p: &Vec3, q: &Vec3, wall: usize, surface: &Wall) -> Option<Span> {
        let ((pu, pz), (qu, qz)) = ((p.dot(&surface.across), p.z), (q.dot(&surface.across), q.z));
        let upright = (qz - pz).abs() > (qu - pu).abs();
        let (across, a, b) = if upright {
            ((pu + qu) / 2.0, pz, qz)
        } else {
            ((pz + qz) / 2.0, pu, qu)
        };
        let slant = if upright {
            (qu - pu).abs() / (qz - pz).abs()
        } else {
            (qz - pz).abs() / (qu - pu).abs().max(1e-9)
        };
        (slant < 0.1).then_some(Span {
            wall,
            upright,
            across,
            from: a.min(b),
            to: a.max(b),
        })
    }

    fn kind(&self) -> (usize, bool) {
        (self.wall, self.upright)
    }
}

/// Whether each candidate lies in a field of its kind: at least `neighbours` other candidates of its wall parallel
/// to it, overlapping it and within `reach_m` across. Courses of brick and rows of tiles are such fields; the
/// outline of an opening on a plain wall is not.
fn in_a_field(
    vertices: &[Vertex],
    edges: &[Edge],
    candidates: &[usize],
    walls: &[&Wall],
    wall_of: &[Option<usize>],
    rule: &SurfaceRule,
) -> Vec<bool> {
    let mut spans: Vec<(Span, usize)> = candidates
        .iter()
        .enumerate()
        .filter_map(|(i, &k)| {
            let e = &edges[k];
            let w = wall_of[e.a]?;
            Span::of(&vertices[e.a].point, &vertices[e.b].point, w, walls[w]).map(|s| (s, i))
        })
        .collect();
    spans.sort_by(|(a, _), (b, _)| a.kind().cmp(&b.kind()).then(a.across.total_cmp(&b.across)));
    let mut out = vec![false; candidates.len()];
    for (pos, (s, i)) in spans.iter().enumerate() {
        // Sorted by kind, then across: the neighbours within reach are a run on either side.
        let close = |(t, _): &&(Span, usize)| t.kind() == s.kind() && (t.across - s.across).abs() <= rule.reach_m;
        let overlapping = |(t, _): &&(Span, usize)| t.from.max(s.from) < t.to.min(s.to);
        let after = spans[pos + 1..].iter().take_while(close).filter(overlapping).count();
        let before = spans[..pos].iter().rev().take_while(close).filter(overlapping).count();
        out[*i] = after + before >= rule.neighbours;
    }
    out
}

/// The wall's extent `[u0, u1, z0, z1]` (along it and up): the bounds of the edges lying in its surface.
fn extent(vertices: &[Vertex], edges: &[Edge], wall: &Wall, own: impl Fn(usize) -> bool) -> Option<[f64; 4]> {
    let mut b = [f64::INFINITY, f64::NEG_INFINITY, f64::INFINITY, f64::NEG_INFINITY];
    for e in edges.iter().filter(|e| own(e.a) && own(e.b)) {
        for p in [vertices[e.a].point, vertices[e.b].point] {
            let (u, z) = (p.dot(&wall.across), p.z);
            b = [b[0].min(u), b[1].max(u), b[2].min(z), b[3].max(z)];
        }
    }
    (b[0] < b[1] && b[2] < b[3]).then_some(b)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::EdgeOrigin;

    fn vertex(x: f64, y: f64, z: f64) -> Vertex {
        Vertex {
            point: Vec3::new(x, y, z),
            sigma: None,
        }
    }

    fn edge(a: usize, b: usize) -> Edge {
        Edge {
            a,
            b,
            line: 0,
            origin: EdgeOrigin::Observed,
        }
    }

    /// A wall y = 0 (cameras at y < 0) 10 m wide and 6 m high: six brick courses 7.5 cm apart from z = 2, a
    /// window's head at z = 3 with a reveal going back from each end, a lone level line at z = 4.5 (an opening's
    /// outline on a plain wall, its reveals not seen), and the wall's outline.
    #[test]
    fn courses_go_aside_the_outline_a_head_with_its_reveals_and_a_lone_line_stay() {
        let mut vertices = vec![
            vertex(0.0, 0.0, 0.0),
            vertex(10.0, 0.0, 0.0),
            vertex(10.0, 0.0, 6.0),
            vertex(0.0, 0.0, 6.0),
        ];
        let mut edges = vec![edge(0, 1), edge(1, 2), edge(2, 3), edge(3, 0)];
        let mut add = |vertices: &mut Vec<Vertex>, a: Vertex, b: Vertex| {
            vertices.extend([a, b]);
            edges.push(edge(vertices.len() - 2, vertices.len() - 1));
        };
        for k in 0..6 {
            let z = 2.0 + 0.075 * k as f64;
            add(&mut vertices, vertex(1.0, 0.004 * (k % 2) as f64, z), vertex(9.0, -0.004, z));
        }
        add(&mut vertices, vertex(4.0, 0.0, 3.0), vertex(5.5, 0.0, 3.0));
        let head = vertices.len() - 2;
        add(&mut vertices, vertex(4.0, 0.0, 3.0), vertex(4.0, 0.2, 3.0));
        add(&mut vertices, vertex(5.5, 0.0, 3.0), vertex(5.5, 0.2, 3.0));
        add(&mut vertices, vertex(2.0, 0.01, 4.5), vertex(3.2, 0.01, 4.5));
        // The reveals start at the head's corners.
        let n = edges.len();
        edges[n - 3].a = head;
        edges[n - 2].a = head + 1;
        let mut faces = Vec::new();
        let plane = crate::surface::Plane {
            normal: Vec3::y(),
            offset: 0.0,
        };
        let wall = Wall::facing(plane, &Vec3::new(5.0, -20.0, 3.0)).expect("the cameras are in front");
        let rule = SurfaceRule {
            band_m: 0.03,
            margin_m: 0.1,
            neighbours: 4,
            reach_m: 0.3,
            plan_azimuths: vec![0.0],
            angle_rad: 2f64.to_radians(),
        };
        let aside = separate(&vertices, &mut edges, &mut faces, &[wall], &[], &rule);
        let courses: Vec<[usize; 2]> = (0..6).map(|k| [4 + 2 * k, 5 + 2 * k]).collect();
        assert_eq!(aside, courses);
        assert_eq!(
            edges.len(),
            8,
            "the outline, the head, its reveals and the lone line stay: {edges:?}"
        );
    }
}
