//! Edges that float at an opening, where the model has no surface.
//!
//! - **In the empty part of a reveal.** Between an opening's outline on the wall and the frame behind it there are
//!   only the reveal's sides, and they run along the wall's normal. An observed edge parallel to the wall in that
//!   space lies where no surface is: a head, foot or sill that one strip sees along its epipolar lines, placed at a
//!   wrong depth, or the edge of a shadow on the soffit.
//! - **In front of the wall.** The one thing that stands proud of the wall at an opening is its sill, which the
//!   model builds as a box from its nose ([`super::add_sills`]). An observed edge in front of the wall, at no face's
//!   depth, is one of those misplaced heads and feet. Lying edges just below the opening's foot are left alone:
//!   there the sill's nose lies, and the lines show it at windows where no sill was built.
//!
//! On the rule-informed buildings these are 3–10 % of the model's edges (docs/model.md, "Floating edges"). A stepped
//! reveal (a rebate) or a window's surround stands there too, but its edges close a ring at one depth. So an edge
//! with edges of the other direction at its depth in the same opening stays.
use super::*;

/// How far behind its frame's face the model may put a window's panes, metres. The lines along a pane's side are the
/// frame's inner edge and the glass's edge seen as one, and they lie between the two ([`super::panes`]). So lines up
/// to this far in front of the shallowest face behind an opening may still be its frame's.
const PANES_BEHIND_FRAME_M: f64 = 0.05;
/// An edge counts as parallel to its wall when the sine of its angle to the wall is at most this (about 17°). A
/// steeper edge is a reveal's own side.
const ALONG_WALL_SIN: f64 = 0.3;
/// An edge of a ring at one depth (a stepped reveal, a surround) has at least this many edges of the other
/// direction, standing or lying, within [`FLUSH_MIN_M`] of its depth in the same opening.
const RING_MATES: usize = 2;

/// The space around one opening: its wall, its bounds grown by the reach of the opening's own lines, its foot, how
/// deep the empty part of its reveal reaches (none without a face behind), and the depths of the faces in front of
/// the wall there (its sill's).
struct Zone {
    wall: usize,
    bounds: [f64; 4],
    foot: f64,
    back: Option<f64>,
    in_front: Vec<f64>,
}

impl Zone {
    /// Whether an edge parallel to the wall, its middle at `depth` and height `z`, floats here: in the empty reveal,
    /// or in front of the wall (no further than a sill's nose may stand) at no face's depth and not where a sill's
    /// nose lies (lying, at most the sill's reach below the foot).
    fn floats(&self, depth: f64, z: f64, lying: bool, sills: &SillRule) -> bool {
        let in_reveal = self.back.is_some_and(|back| depth > FLUSH_MIN_M && depth < back);
        let nose = lying && z < self.foot && z >= self.foot - sills.reach_m;
        let in_front =
            (-sills.proud_m.1..-FLUSH_MIN_M).contains(&depth) && !nose && self.in_front.iter().all(|f| (f - depth).abs() > FLUSH_MIN_M);
        in_reveal || in_front
    }
}

/// An edge that may float: the zone, its depth behind the wall, and whether it lies (rather than stands).
struct Floating {
    edge: usize,
    zone: usize,
    depth: f64,
    lying: bool,
}

/// The zones of every window and door on `walls`.
fn zones(walls: &[Wall], outlines: &[Outline], faces: &[Face], params: &ModelParams, reach: f64) -> Vec<Zone> {
    let cos_par = params.plane_angle_deg.to_radians().cos();
    let sizes = params.opening_sizes();
    faces
        .iter()
        .zip(outlines)
        .filter(|(f, _)| matches!(f.kind, SurfaceKind::Window | SurfaceKind::Door))
        .filter_map(|(_, o)| {
            let wall = walls.iter().position(|w| o.on(w, cos_par, FLUSH_MIN_M))?;
            let on = &walls[wall];
            let [x0, x1, z0, z1] = o.bounds_in(on);
            let back = face_behind(outlines, on, [x0, x1, z0, z1], sizes, cos_par)
                .map(|behind| behind.depth - PANES_BEHIND_FRAME_M)
                .filter(|&back| back > FLUSH_MIN_M);
            let bounds = [x0 - reach, x1 + reach, z0 - reach, z1 + reach];
            let in_front = outlines
                .iter()
                .filter(|f| f.normal.dot(&on.out).abs() > cos_par && contains(&bounds, on, &f.centroid))
                .map(|f| on.depth(&f.centroid))
                .filter(|&depth| depth < -FLUSH_MIN_M)
                .collect();
            Some(Zone {
                wall,
                bounds,
                foot: z0,
                back,
                in_front,
            })
        })
        .collect()
}

/// Whether `p` lies within `[x0, x1, z0, z1]` of `wall`, across and up.
fn contains(&[x0, x1, z0, z1]: &[f64; 4], wall: &Wall, p: &Vec3) -> bool {
    (x0..=x1).contains(&p.dot(&wall.across)) && (z0..=z1).contains(&p.z)
}

/// Which of `edges` are observed, parallel to their wall and float at an opening ([`Zone::floats`]) on no ring
/// ([`RING_MATES`]). `reach` is how far around an opening's outline its lines lie, metres.
pub(crate) fn floating_at_openings(
    walls: &[Wall],
    vertices: &[Vertex],
    edges: &[Edge],
    faces: &[Face],
    params: &ModelParams,
    reach: f64,
) -> Vec<bool> {
    let outlines = Outline::of_faces(faces, vertices);
    let zones = zones(walls, &outlines, faces, params, reach);
    let sills = params.sill_rule();
    let candidates: Vec<Floating> = edges
        .iter()
        .enumerate()
        .filter(|(_, e)| e.observed())
        .filter_map(|(k, e)| {
            let (p, q) = (vertices[e.a].point, vertices[e.b].point);
            let (mid, along) = ((p + q) / 2.0, q - p);
            zones.iter().enumerate().find_map(|(z, zone)| {
                let wall = &walls[zone.wall];
                let depth = wall.depth(&mid);
                let parallel = along.dot(&wall.out).abs() <= ALONG_WALL_SIN * along.norm();
                let lying = along.z.abs() < along.dot(&wall.across).abs();
                (parallel && contains(&zone.bounds, wall, &mid) && zone.floats(depth, mid.z, lying, &sills)).then_some(Floating {
                    edge: k,
                    zone: z,
                    depth,
                    lying,
                })
            })
        })
        .collect();
    let mut floating = vec![false; edges.len()];
    for e in &candidates {
        let mates = candidates
            .iter()
            .filter(|o| o.zone == e.zone && o.lying != e.lying && (o.depth - e.depth).abs() <= FLUSH_MIN_M)
            .count();
        floating[e.edge] = mates < RING_MATES;
    }
    floating
}

#[cfg(test)]
mod tests {
    use super::super::tests::{edge, vertex};
    use super::*;
    use crate::surface::Plane;

    /// A rectangle at depth `y` (the wall is y = 0, seen from y < 0), x 1–2, z 1–2, as a face of `kind`.
    fn rectangle(y: f64, kind: SurfaceKind, vertices: &mut Vec<Vertex>) -> Face {
        let first = vertices.len();
        vertices.extend([
            vertex([1.0, y, 1.0]),
            vertex([2.0, y, 1.0]),
            vertex([2.0, y, 2.0]),
            vertex([1.0, y, 2.0]),
        ]);
        Face {
            ring: (first..first + 4).collect(),
            holes: Vec::new(),
            normal: -Vec3::y(),
            kind,
        }
    }

    fn wall() -> Wall {
        Wall::facing(
            Plane {
                normal: Vec3::y(),
                offset: 0.0,
            },
            &Vec3::new(0.0, -10.0, 1.5),
        )
        .unwrap()
    }

    /// A window in the wall with its frame `frame_m` behind, and lying edges across it at `depths`.
    fn window(frame_m: f64, depths: &[f64]) -> (Vec<Vertex>, Vec<Edge>, Vec<Face>) {
        let mut vertices = Vec::new();
        let faces = vec![
            rectangle(0.0, SurfaceKind::Window, &mut vertices),
            rectangle(frame_m, SurfaceKind::Window, &mut vertices),
        ];
        let mut edges = Vec::new();
        for &y in depths {
            vertices.extend([vertex([1.1, y, 1.95]), vertex([1.9, y, 1.95])]);
            edges.push(edge(vertices.len() - 2, vertices.len() - 1));
        }
        (vertices, edges, faces)
    }

    #[test]
    fn a_head_placed_between_the_wall_and_the_frame_floats_and_one_on_either_goes_on() {
        let (vertices, edges, faces) = window(0.3, &[0.0, 0.12, 0.3, 0.27, -0.05]);
        let floating = floating_at_openings(&[wall()], &vertices, &edges, &faces, &ModelParams::default(), 0.15);
        // The wall's, the frame's and one just in front of the frame (its panes may lie behind it) stay; one 5 cm in
        // front of the wall, where the model has no sill, floats.
        assert_eq!(floating, vec![false, true, false, false, true]);
    }

    #[test]
    fn a_ring_at_one_depth_is_a_stepped_reveal_and_stays() {
        let (mut vertices, mut edges, faces) = window(0.3, &[0.12]);
        vertices.extend([vertex([1.1, 0.12, 1.05]), vertex([1.9, 0.12, 1.05])]);
        edges.push(edge(vertices.len() - 2, vertices.len() - 1));
        for x in [1.05, 1.95] {
            vertices.extend([vertex([x, 0.12, 1.1]), vertex([x, 0.12, 1.9])]);
            edges.push(edge(vertices.len() - 2, vertices.len() - 1));
        }
        let floating = floating_at_openings(&[wall()], &vertices, &edges, &faces, &ModelParams::default(), 0.15);
        assert_eq!(floating, vec![false; 4]);
        // The head alone is no ring.
        let floating = floating_at_openings(&[wall()], &vertices, &edges[..1], &faces, &ModelParams::default(), 0.15);
        assert_eq!(floating, vec![true]);
    }

    #[test]
    fn without_a_face_behind_nothing_floats_in_the_reveal() {
        let (vertices, edges, mut faces) = window(0.3, &[0.12]);
        faces.pop();
        let floating = floating_at_openings(&[wall()], &vertices, &edges, &faces, &ModelParams::default(), 0.15);
        assert_eq!(floating, vec![false]);
    }

    #[test]
    fn in_front_of_the_wall_only_a_face_s_depth_holds_an_edge() {
        // A sill's nose face 5 cm proud under the window; edges on it, 10 cm proud, and 1 m proud (no sill's).
        let (mut vertices, mut edges, mut faces) = window(0.3, &[-0.05, -0.1, -1.0]);
        let first = vertices.len();
        vertices.extend([
            vertex([0.9, -0.05, 0.9]),
            vertex([2.1, -0.05, 0.9]),
            vertex([2.1, -0.05, 0.95]),
            vertex([0.9, -0.05, 0.95]),
        ]);
        faces.push(Face {
            ring: (first..first + 4).collect(),
            holes: Vec::new(),
            normal: -Vec3::y(),
            kind: SurfaceKind::Wall,
        });
        let floating = floating_at_openings(&[wall()], &vertices, &edges, &faces, &ModelParams::default(), 0.15);
        assert_eq!(floating, vec![false, true, false]);
        // Without the sill an edge at its depth at the head floats too; one just below the foot is a nose the lines
        // show where no sill was built, and stays.
        faces.pop();
        edges.truncate(1);
        vertices.extend([vertex([1.1, -0.05, 0.95]), vertex([1.9, -0.05, 0.95])]);
        edges.push(edge(vertices.len() - 2, vertices.len() - 1));
        let floating = floating_at_openings(&[wall()], &vertices, &edges, &faces, &ModelParams::default(), 0.15);
        assert_eq!(floating, vec![true, false]);
    }

    #[test]
    fn an_edge_along_the_reveal_is_its_side_and_inferred_edges_are_not_judged() {
        let (mut vertices, mut edges, faces) = window(0.3, &[]);
        vertices.extend([vertex([1.0, 0.0, 2.0]), vertex([1.0, 0.3, 2.0])]);
        edges.push(edge(vertices.len() - 2, vertices.len() - 1));
        vertices.extend([vertex([1.1, 0.12, 1.95]), vertex([1.9, 0.12, 1.95])]);
        edges.push(Edge {
            origin: EdgeOrigin::Inferred,
            ..edge(vertices.len() - 2, vertices.len() - 1)
        });
        let floating = floating_at_openings(&[wall()], &vertices, &edges, &faces, &ModelParams::default(), 0.15);
        assert_eq!(floating, vec![false, false]);
    }
}
