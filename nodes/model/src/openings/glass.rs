//! The glazing behind a window's panes. A pane is an opening in the frame; the glass sits a little behind the
//! frame's face (on its glazing bead), so each pane has a ring of glass and four short reveals, the frame's inner
//! sides, from its corners back to the glass. From the street the glass's edge lies just behind the frame's inner
//! edge and the images show the two as one line: the 3-D lines seldom place it. On the full-size presets these
//! rings and reveals are a fifth to a quarter of a façade's edges (@1006: 825 of 3,450 reveals 8 mm deep).
//!
//! Every pane of a window whose frame the model knows gets its glass ring `glass_inset_m` behind it, with the four
//! reveals, as inferred edges, unless the lines closed its glass already (a face or a hole of its outline just
//! behind or before it). The glass's depth comes from the lines where they show it (the densest cluster of the
//! edges along the wall's panes' sides, behind them by more than the lines' noise and at most a frame's depth:
//! 43 and 51 mm where the truth is 40 and 47.5), else the parameter's default (15 mm: within the edge tolerance of
//! glass 0 to 35 mm deep at full size).
use super::*;
use lineflow_photogrammetry::median;

/// Lines inside a pane behind it by less than this are the pane's own (the lines' depth noise), metres.
const MIN_GLASS_INSET_M: f64 = 0.01;
/// The fewest such lines, within [`GLASS_CLUSTER_M`] of each other, that give a wall's glass depth (deeper lines
/// along a pane's side are other things: a second frame, the room behind).
const MIN_GLASS_LINES: usize = 8;
/// How far apart in depth the lines of one glass may lie, metres (their depth noise at full size, twice).
const GLASS_CLUSTER_M: f64 = 0.02;

/// The panes on `wall`: window faces parallel to it, behind it by at least [`FLUSH_MIN_M`] and at most the deepest
/// recess, inside an opening's outline on the wall and spanning none (that face is the frame). Their indices.
fn panes_of(wall: &Wall, outlines: &[Outline], faces: &[Face], sizes: OpeningSizes, cos_par: f64) -> Vec<usize> {
    let openings: Vec<[f64; 4]> = faces
        .iter()
        .zip(outlines)
        .filter(|(f, o)| f.kind == SurfaceKind::Window && o.on(wall, cos_par, FLUSH_MIN_M))
        .map(|(_, o)| o.bounds_in(wall))
        .collect();
    let reach = sizes.frame_m.1;
    (0..faces.len())
        .filter(|&k| {
            let o = &outlines[k];
            let depth = wall.depth(&o.centroid);
            if faces[k].kind != SurfaceKind::Window
                || !o.on(wall, cos_par, f64::INFINITY)
                || !(FLUSH_MIN_M..=sizes.recess_m.1).contains(&depth)
            {
                return false;
            }
            let [a0, a1, b0, b1] = o.bounds_in(wall);
            let inside = |&[x0, x1, z0, z1]: &[f64; 4]| a0 >= x0 - reach && a1 <= x1 + reach && b0 >= z0 - reach && b1 <= z1 + reach;
            let spans = |&[x0, x1, z0, z1]: &[f64; 4]| [a0 - x0, x1 - a1, b0 - z0, z1 - b1].iter().all(|gap| gap.abs() <= reach);
            // Inside an opening and spanning none (the frame of its own opening spans it; a large face on the wall
            // may hold the whole opening).
            openings.iter().any(inside) && !openings.iter().any(spans)
        })
        .collect()
}

/// How far behind its panes a wall's glass lies: the median depth behind its pane of the observed edges parallel
/// to the wall along a pane's side (within `tolerance` of it across, their middle within its extent) and behind it
/// by [`MIN_GLASS_INSET_M`] to `max_m`, of their densest cluster ([`GLASS_CLUSTER_M`]); none where it holds fewer
/// than [`MIN_GLASS_LINES`]. The glass's edge lies along the pane's, just behind it.
fn measured_inset(wall: &Wall, panes: &[([f64; 4], f64)], vertices: &[Vertex], edges: &[Edge], tolerance: f64, max_m: f64) -> Option<f64> {
    let insets: Vec<f64> = edges
        .iter()
        .filter(|e| e.observed())
        .filter_map(|e| {
            let (p, q) = (vertices[e.a].point, vertices[e.b].point);
            let d = q - p;
            if d.dot(&wall.out).abs() > 0.2 * d.norm() {
                return None;
            }
            let standing = d.z.abs() > d.dot(&wall.across).abs();
            let m = (p + q) / 2.0;
            let (x, z, depth) = (m.dot(&wall.across), m.z, wall.depth(&m));
            panes.iter().find_map(|&([x0, x1, z0, z1], pane)| {
                let along_side = if standing {
                    ((x - x0).abs() <= tolerance || (x - x1).abs() <= tolerance) && z > z0 && z < z1
                } else {
                    ((z - z0).abs() <= tolerance || (z - z1).abs() <= tolerance) && x > x0 && x < x1
                };
                let inset = depth - pane;
                (along_side && (MIN_GLASS_INSET_M..=max_m).contains(&inset)).then_some(inset)
            })
        })
        .collect();
    densest(insets, GLASS_CLUSTER_M)
        .filter(|c| c.len() >= MIN_GLASS_LINES)
        .and_then(median)
}

/// Whether an observed edge lies on the ring (the lines closed it, at least in part).
fn ring_observed(ring: &[usize], observed: &std::collections::HashSet<[usize; 2]>) -> bool {
    (0..ring.len()).any(|i| observed.contains(&crate::sorted_pair(ring[i], ring[(i + 1) % ring.len()])))
}

/// The values of the densest run of `values` no wider than `width` (the first of the fullest).
pub(super) fn densest(mut values: Vec<f64>, width: f64) -> Option<Vec<f64>> {
    values.sort_by(f64::total_cmp);
    let runs: Vec<usize> = (0..values.len())
        .map(|i| values[i..].iter().take_while(|&&v| v - values[i] <= width).count())
        .collect();
    let best = (0..runs.len()).max_by(|&a, &b| runs[a].cmp(&runs[b]).then(b.cmp(&a)))?;
    Some(values[best..best + runs[best]].to_vec())
}

/// Gives every pane of the model's windows on `walls` its glass ring behind it and the four reveals from its
/// corners to the glass's, as inferred edges and a window face. Runs after [`super::add_panes`].
pub(crate) fn add_glass(
    walls: &[WallView],
    params: &ModelParams,
    vertices: &mut Vec<Vertex>,
    edges: &mut Vec<Edge>,
    faces: &mut Vec<Face>,
) {
    glaze(walls.iter().map(|v| &v.wall), params, vertices, edges, faces);
}

/// [`add_glass`] on the walls themselves.
fn glaze<'w>(
    walls: impl Iterator<Item = &'w Wall>,
    params: &ModelParams,
    vertices: &mut Vec<Vertex>,
    edges: &mut Vec<Edge>,
    faces: &mut Vec<Face>,
) {
    let cos_par = params.plane_angle_deg.to_radians().cos();
    let sizes = params.opening_sizes();
    let outlines = Outline::of_faces(faces, vertices);
    let mut taken = vec![false; faces.len()];
    let mut glass = Vec::new();
    let observed: std::collections::HashSet<[usize; 2]> = edges
        .iter()
        .filter(|e| e.observed())
        .map(|e| crate::sorted_pair(e.a, e.b))
        .collect();
    for wall in walls {
        let panes: Vec<usize> = panes_of(wall, &outlines, faces, sizes, cos_par)
            .into_iter()
            .filter(|&k| !taken[k])
            .collect();
        let bounds: Vec<([f64; 4], f64)> = panes
            .iter()
            .map(|&k| (outlines[k].bounds_in(wall), wall.depth(&outlines[k].centroid)))
            .collect();
        // Every window ring and hole parallel to the wall: a pane's glass that closed, or the hole a pane makes in
        // its frame's face where the glass closed as a face of its own.
        let rings: Vec<([f64; 4], f64)> = faces
            .iter()
            .zip(&outlines)
            .filter(|(f, o)| f.kind == SurfaceKind::Window && o.on(wall, cos_par, f64::INFINITY))
            .flat_map(|(f, _)| std::iter::once(&f.ring).chain(&f.holes))
            .map(|ring| {
                let points: Vec<Vec3> = ring.iter().map(|&v| vertices[v].point).collect();
                let depth = points.iter().map(|p| wall.depth(p)).sum::<f64>() / points.len().max(1) as f64;
                (Outline::of(&points, wall.out).bounds_in(wall), depth)
            })
            .collect();
        // Measured at the panes the lines closed where they show it: an added pane's sides are its layout's, and
        // the lines there are as often the frame's rail and the glass seen as one, between the two, as the glass.
        let seen: Vec<([f64; 4], f64)> = panes
            .iter()
            .zip(&bounds)
            .filter(|(&k, _)| ring_observed(&faces[k].ring, &observed))
            .map(|(_, b)| *b)
            .collect();
        let measured = measured_inset(wall, &seen, vertices, edges, SIDE_TOLERANCE_M, sizes.frame_m.1)
            .or_else(|| measured_inset(wall, &bounds, vertices, edges, SIDE_TOLERANCE_M, sizes.frame_m.1));
        let inset = measured.unwrap_or(params.glass_inset_m);
        for (k, (b, depth)) in panes.iter().zip(&bounds) {
            taken[*k] = true;
            // A pane with another of its outline close behind or before it has its glass: the lines closed both.
            let glazed = rings.iter().any(|(c, d)| {
                (d - depth).abs() > MIN_GLASS_INSET_M / 2.0
                    && (d - depth).abs() <= sizes.frame_m.1
                    && b.iter().zip(c).all(|(p, q)| (p - q).abs() <= SIDE_TOLERANCE_M)
            });
            if !glazed {
                glass.push((*k, wall.out * -inset));
            }
        }
    }
    for (k, back) in glass {
        let ring = faces[k].ring.clone();
        let corners: Vec<Vertex> = ring
            .iter()
            .map(|&v| Vertex {
                point: vertices[v].point + back,
                sigma: None,
            })
            .collect();
        let normal = faces[k].normal;
        let glass_ring = add_face(corners, normal, SurfaceKind::Window, vertices, edges, faces);
        edges.extend(ring.iter().zip(&glass_ring).map(|(&a, &b)| Edge {
            a,
            b,
            line: usize::MAX,
            origin: EdgeOrigin::Inferred,
        }));
    }
}

#[cfg(test)]
mod tests {
    use super::super::tests::{edge, vertex};
    use super::*;

    fn wall() -> Wall {
        let plane = Plane {
            normal: Vec3::y(),
            offset: 0.0,
        };
        Wall::facing(plane, &Vec3::new(1.0, -10.0, 1.0)).unwrap()
    }

    #[test]
    fn the_glass_lies_where_the_lines_along_the_panes_sides_show_it() {
        // Two panes 12 cm behind the wall; along their sides, lines 4.5 cm behind them (the glass), lines on the
        // panes' plane (their own sides), a few 10 to 14 cm behind (beyond the glass: something else) and one in
        // the middle of a pane (no side of it).
        let panes = [([0.05, 0.45, 1.05, 1.95], 0.12), ([0.55, 0.95, 1.05, 1.95], 0.12)];
        let mut vertices = Vec::new();
        let mut edges = Vec::new();
        let mut line = |x: f64, y: f64| {
            vertices.push(vertex([x, y, 1.2]));
            vertices.push(vertex([x, y, 1.8]));
            edges.push(edge(vertices.len() - 2, vertices.len() - 1));
        };
        for k in 0..10 {
            let x = [0.05, 0.45, 0.55, 0.95][k % 4] + 0.001 * k as f64;
            line(x, 0.165 + 0.001 * k as f64);
            line(x, 0.121);
        }
        for y in [0.22, 0.23, 0.25, 0.26] {
            line(0.05, y);
        }
        line(0.3, 0.17);
        let inset = measured_inset(&wall(), &panes, &vertices, &edges, 0.015, 0.15);
        assert!(inset.is_some_and(|i| (i - 0.0495).abs() < 1e-9), "{inset:?}");
        assert_eq!(
            measured_inset(&wall(), &panes, &vertices[..8], &edges[..4], 0.015, 0.15),
            None,
            "too few lines"
        );
    }

    #[test]
    fn each_pane_gets_its_glass_and_reveals_unless_its_glass_closed() {
        // A window 1–2 m across and up in the wall y = 0, its two panes 12 cm behind; the left pane's glass closed
        // as a face of its own 4 cm behind it.
        let out = Vec3::new(0.0, -1.0, 0.0);
        let (mut vertices, mut edges, mut faces) = (Vec::new(), Vec::new(), Vec::new());
        let mut face = |[x0, x1, z0, z1]: [f64; 4], y: f64| {
            let corners = [[x0, y, z0], [x1, y, z0], [x1, y, z1], [x0, y, z1]].map(vertex).to_vec();
            add_face(corners, out, SurfaceKind::Window, &mut vertices, &mut edges, &mut faces);
        };
        face([1.0, 2.0, 1.0, 2.0], 0.0);
        face([1.05, 1.47, 1.05, 1.95], 0.12);
        face([1.53, 1.95, 1.05, 1.95], 0.12);
        face([1.05, 1.47, 1.05, 1.95], 0.16);
        let (n_faces, n_edges) = (faces.len(), edges.len());
        let params = ModelParams::default();
        glaze(std::iter::once(&wall()), &params, &mut vertices, &mut edges, &mut faces);
        assert_eq!(faces.len(), n_faces + 1, "only the right pane gets glass");
        let glass: Vec<Vec3> = faces[n_faces].ring.iter().map(|&v| vertices[v].point).collect();
        assert!(
            glass.iter().all(|p| (p.y - 0.12 - params.glass_inset_m).abs() < 1e-9 && p.x > 1.5),
            "{glass:?}"
        );
        assert_eq!(edges.len(), n_edges + 8, "the glass's ring and its four reveals");
        assert!(edges[n_edges..].iter().all(|e| e.origin == EdgeOrigin::Inferred));
    }

    #[test]
    fn the_glass_is_measured_at_the_panes_the_lines_closed() {
        // Two panes 12 cm behind the wall y = 0. The lines closed the left one, and along its sides 8 lines show
        // the glass 4.5 cm behind it. The right one was added by its window's layout, and along its sides 10 lines
        // lie 2 cm behind it: its rail and its glass seen as one. Both panes get their glass 4.5 cm behind.
        let out = Vec3::new(0.0, -1.0, 0.0);
        let (mut vertices, mut edges, mut faces) = (Vec::new(), Vec::new(), Vec::new());
        let mut face = |[x0, x1, z0, z1]: [f64; 4], y: f64, vertices: &mut Vec<Vertex>, edges: &mut Vec<Edge>| {
            let corners = [[x0, y, z0], [x1, y, z0], [x1, y, z1], [x0, y, z1]].map(vertex).to_vec();
            add_face(corners, out, SurfaceKind::Window, vertices, edges, &mut faces);
        };
        face([1.0, 2.0, 1.0, 2.0], 0.0, &mut vertices, &mut edges);
        let before = edges.len();
        face([1.05, 1.47, 1.05, 1.95], 0.12, &mut vertices, &mut edges);
        for e in &mut edges[before..] {
            e.origin = EdgeOrigin::Observed;
        }
        face([1.53, 1.95, 1.05, 1.95], 0.12, &mut vertices, &mut edges);
        let mut line = |x: f64, y: f64, k: usize| {
            let z = 1.2 + 0.05 * k as f64;
            vertices.extend([vertex([x, y, z]), vertex([x, y, z + 0.3])]);
            edges.push(edge(vertices.len() - 2, vertices.len() - 1));
        };
        for k in 0..8 {
            line(if k % 2 == 0 { 1.05 } else { 1.47 }, 0.165, k);
        }
        for k in 0..10 {
            line(if k % 2 == 0 { 1.53 } else { 1.95 }, 0.14, k);
        }
        let n_faces = faces.len();
        glaze(
            std::iter::once(&wall()),
            &ModelParams::default(),
            &mut vertices,
            &mut edges,
            &mut faces,
        );
        assert_eq!(faces.len(), n_faces + 2, "both panes get glass");
        for f in &faces[n_faces..] {
            assert!(f.ring.iter().all(|&v| (vertices[v].point.y - 0.165).abs() < 1e-9));
        }
    }

    #[test]
    fn the_densest_run_of_values_is_the_fullest_within_its_width() {
        let run = densest(vec![0.013, 0.094, 0.013, 0.118, 0.128, 0.013, 0.144], 0.02);
        assert_eq!(run, Some(vec![0.013, 0.013, 0.013]));
        assert_eq!(densest(Vec::new(), 0.02), None);
    }
}
