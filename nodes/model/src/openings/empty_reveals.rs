//! The empty part of a reveal. Between an opening's outline on the wall and the frame behind it there are only the
//! reveal's sides, and they run along the wall's normal. An observed edge parallel to the wall in that space lies
//! where no surface is: a head, foot or sill that one strip sees along its epipolar lines, placed at a wrong depth,
//! or the edge of a shadow on the soffit. On buildings with deep reveals these are a tenth of the model's edges
//! (docs/model.md, "Empty reveals"). A stepped reveal (a rebate) does have edges there, but they close a ring at one
//! depth, so an edge with edges of the other direction at its depth in the same opening stays.
use super::*;

/// How far behind its frame's face the model may put a window's panes, metres. The lines along a pane's side are the
/// frame's inner edge and the glass's edge seen as one, and they lie between the two ([`super::panes`]). So lines up
/// to this far in front of the shallowest face behind an opening may still be its frame's.
const PANES_BEHIND_FRAME_M: f64 = 0.05;
/// An edge counts as parallel to its wall when the sine of its angle to the wall is at most this (about 17°). A
/// steeper edge is a reveal's own side.
const ALONG_WALL_SIN: f64 = 0.3;
/// An edge of a ring at one depth (a stepped reveal) has at least this many edges of the other direction, standing
/// or lying, within [`FLUSH_MIN_M`] of its depth in the same opening.
const RING_MATES: usize = 2;

/// The space of one opening's reveal in front of its frame: its wall, its bounds grown by the reach of the
/// opening's own lines, and how deep the empty space reaches.
struct Zone {
    wall: usize,
    bounds: [f64; 4],
    back: f64,
}

/// An edge in a zone: the zone, its depth behind the wall, and whether it lies (rather than stands).
struct InZone {
    edge: usize,
    zone: usize,
    depth: f64,
    lying: bool,
}

/// The zones of every window and door on `walls` that has a face behind it (its frame or panes).
fn zones(walls: &[Wall], outlines: &[Outline], faces: &[Face], params: &ModelParams, reach: f64) -> Vec<Zone> {
    let cos_par = params.plane_angle_deg.to_radians().cos();
    let sizes = params.opening_sizes();
    faces
        .iter()
        .zip(outlines)
        .filter(|(f, _)| matches!(f.kind, SurfaceKind::Window | SurfaceKind::Door))
        .filter_map(|(_, o)| {
            let wall = walls.iter().position(|w| o.on(w, cos_par, FLUSH_MIN_M))?;
            let [x0, x1, z0, z1] = o.bounds_in(&walls[wall]);
            let behind = face_behind(outlines, &walls[wall], [x0, x1, z0, z1], sizes, cos_par)?;
            let back = behind.depth - PANES_BEHIND_FRAME_M;
            (back > FLUSH_MIN_M).then_some(Zone {
                wall,
                bounds: [x0 - reach, x1 + reach, z0 - reach, z1 + reach],
                back,
            })
        })
        .collect()
}

/// Which of `edges` are observed, parallel to their wall and float in an opening's empty reveal: deeper than a
/// nearly flush frame ([`FLUSH_MIN_M`]) behind the wall, in front of what lies behind the opening, and on no ring
/// ([`RING_MATES`]). `reach` is how far around an opening's outline its lines lie, metres.
pub(crate) fn in_empty_reveals(
    walls: &[Wall],
    vertices: &[Vertex],
    edges: &[Edge],
    faces: &[Face],
    params: &ModelParams,
    reach: f64,
) -> Vec<bool> {
    let outlines = Outline::of_faces(faces, vertices);
    let zones = zones(walls, &outlines, faces, params, reach);
    let inside: Vec<InZone> = edges
        .iter()
        .enumerate()
        .filter(|(_, e)| e.observed())
        .filter_map(|(k, e)| {
            let (p, q) = (vertices[e.a].point, vertices[e.b].point);
            let (mid, along) = ((p + q) / 2.0, q - p);
            zones.iter().enumerate().find_map(|(z, zone)| {
                let wall = &walls[zone.wall];
                let [x0, x1, z0, z1] = zone.bounds;
                let x = mid.dot(&wall.across);
                let depth = wall.depth(&mid);
                let in_zone = (x0..=x1).contains(&x) && (z0..=z1).contains(&mid.z) && depth > FLUSH_MIN_M && depth < zone.back;
                let parallel = along.dot(&wall.out).abs() <= ALONG_WALL_SIN * along.norm();
                (in_zone && parallel).then_some(InZone {
                    edge: k,
                    zone: z,
                    depth,
                    lying: along.z.abs() < along.dot(&wall.across).abs(),
                })
            })
        })
        .collect();
    let mut floating = vec![false; edges.len()];
    for e in &inside {
        let mates = inside
            .iter()
            .filter(|o| o.zone == e.zone && o.lying != e.lying && (o.depth - e.depth).abs() <= FLUSH_MIN_M)
            .count();
        floating[e.edge] = mates < RING_MATES;
    }
    floating
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::surface::Plane;

    fn vertex(x: f64, y: f64, z: f64) -> Vertex {
        Vertex {
            point: Vec3::new(x, y, z),
            sigma: None,
        }
    }

    /// A rectangle at depth `y` (the wall is y = 0, seen from y < 0), x 1–2, z 1–2, as a face of `kind`.
    fn rectangle(y: f64, kind: SurfaceKind, vertices: &mut Vec<Vertex>) -> Face {
        let first = vertices.len();
        vertices.extend([vertex(1.0, y, 1.0), vertex(2.0, y, 1.0), vertex(2.0, y, 2.0), vertex(1.0, y, 2.0)]);
        Face {
            ring: (first..first + 4).collect(),
            holes: Vec::new(),
            normal: -Vec3::y(),
            kind,
        }
    }

    fn observed(a: usize, b: usize) -> Edge {
        Edge {
            a,
            b,
            line: 0,
            origin: EdgeOrigin::Observed,
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
            vertices.extend([vertex(1.1, y, 1.95), vertex(1.9, y, 1.95)]);
            edges.push(observed(vertices.len() - 2, vertices.len() - 1));
        }
        (vertices, edges, faces)
    }

    #[test]
    fn a_head_placed_between_the_wall_and_the_frame_floats_and_one_on_either_goes_on() {
        let (vertices, edges, faces) = window(0.3, &[0.0, 0.12, 0.3, 0.27, -0.05]);
        let floating = in_empty_reveals(&[wall()], &vertices, &edges, &faces, &ModelParams::default(), 0.15);
        // The wall's, the frame's, one just in front of the frame (its panes may lie behind it) and a sill's nose
        // in front of the wall stay.
        assert_eq!(floating, vec![false, true, false, false, false]);
    }

    #[test]
    fn a_ring_at_one_depth_is_a_stepped_reveal_and_stays() {
        let (mut vertices, mut edges, faces) = window(0.3, &[0.12]);
        vertices.extend([vertex(1.1, 0.12, 1.05), vertex(1.9, 0.12, 1.05)]);
        edges.push(observed(vertices.len() - 2, vertices.len() - 1));
        for x in [1.05, 1.95] {
            vertices.extend([vertex(x, 0.12, 1.1), vertex(x, 0.12, 1.9)]);
            edges.push(observed(vertices.len() - 2, vertices.len() - 1));
        }
        let floating = in_empty_reveals(&[wall()], &vertices, &edges, &faces, &ModelParams::default(), 0.15);
        assert_eq!(floating, vec![false; 4]);
        // The head alone is no ring.
        let floating = in_empty_reveals(&[wall()], &vertices, &edges[..1], &faces, &ModelParams::default(), 0.15);
        assert_eq!(floating, vec![true]);
    }

    #[test]
    fn without_a_face_behind_nothing_floats() {
        let (vertices, edges, mut faces) = window(0.3, &[0.12]);
        faces.pop();
        let floating = in_empty_reveals(&[wall()], &vertices, &edges, &faces, &ModelParams::default(), 0.15);
        assert_eq!(floating, vec![false]);
    }

    #[test]
    fn an_edge_along_the_reveal_is_its_side_and_inferred_edges_are_not_judged() {
        let (mut vertices, mut edges, faces) = window(0.3, &[]);
        vertices.extend([vertex(1.0, 0.0, 2.0), vertex(1.0, 0.3, 2.0)]);
        edges.push(observed(vertices.len() - 2, vertices.len() - 1));
        vertices.extend([vertex(1.1, 0.12, 1.95), vertex(1.9, 0.12, 1.95)]);
        edges.push(Edge {
            origin: EdgeOrigin::Inferred,
            ..observed(vertices.len() - 2, vertices.len() - 1)
        });
        let floating = in_empty_reveals(&[wall()], &vertices, &edges, &faces, &ModelParams::default(), 0.15);
        assert_eq!(floating, vec![false, false]);
    }
}
