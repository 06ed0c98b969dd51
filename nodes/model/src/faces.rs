//! Faces of the wire-frame: planes hypothesised at corners from pairs of their edges, the edges lying in each
//! plane traced as a planar graph (each bounded cycle a face), a face lying inside another face of its plane made
//! that face's opening (the seed's "roof inside a roof"), and a semantic kind for each face.
use std::collections::BTreeMap;

use lineflow_photogrammetry::{point_in_polygon, signed_area, Vec3};

use crate::disjoint::Disjoint;
use crate::openings::{Evidence, Wall};
use crate::surface::{plane_basis, smaller_side, Face, Plane, SurfaceKind};
use crate::{Cameras, Edge, ModelParams, Vertex};

/// The faces of a wire-frame. The `cameras`' mean centre decides which side is outside; without cameras the
/// centroid of the vertices is taken as inside.
///
/// Openings inferred from what is seen through them ([`crate::openings`]) add their corners to `vertices` and
/// their outlines, as completed edges, to `edges`.
pub fn find(vertices: &mut Vec<Vertex>, edges: &mut Vec<Edge>, params: &ModelParams, cameras: &Cameras) -> Vec<Face> {
    find_with_walls(vertices, edges, params, cameras, &[], None).0
}

/// [`find`], and the walls the openings were looked for on. `surface` holds lines known to lie inside a surface
/// (the texture lines left out of the model): they show where the walls are. `evidence`, the images' 2-D lines,
/// confirms the openings a façade's rows and columns predict.
pub(crate) fn find_with_walls(
    vertices: &mut Vec<Vertex>,
    edges: &mut Vec<Edge>,
    params: &ModelParams,
    cameras: &Cameras,
    surface: &[[Vec3; 2]],
    evidence: Option<&Evidence>,
) -> (Vec<Face>, Vec<Wall>) {
    let viewpoint = cameras.mean();
    if vertices.is_empty() {
        return (Vec::new(), Vec::new());
    }
    let tol = plane_tolerance(vertices, params);
    let merged = merge_close(vertices, edges, tol);
    let edges_out = edges;
    let edges = &merged[..];
    let incident = incident_edges(vertices.len(), edges);
    let planes = plane_hypotheses(vertices, edges, &incident, params, tol);
    let inside_ref = viewpoint.unwrap_or_else(|| vertices.iter().map(|v| v.point).sum::<Vec3>() / vertices.len() as f64);
    let outward_from_centroid = viewpoint.is_none();
    let mut faces = Vec::new();
    let mut seen_rings = std::collections::HashSet::new();
    let plane_edges: Vec<Vec<&Edge>> = planes
        .iter()
        .map(|plane| {
            let on_plane = |v: usize| (plane.normal.dot(&vertices[v].point) - plane.offset).abs() < tol;
            edges.iter().filter(|e| on_plane(e.a) && on_plane(e.b)).collect()
        })
        .collect();
    for (plane, in_plane) in planes.iter().zip(&plane_edges) {
        for ring in cycles(vertices, in_plane, plane.normal) {
            let mut key = ring.clone();
            key.sort_unstable();
            if !seen_rings.insert(key) {
                continue;
            }
            let centroid = ring.iter().map(|&v| vertices[v].point).sum::<Vec3>() / ring.len() as f64;
            let towards = if outward_from_centroid {
                centroid - inside_ref
            } else {
                inside_ref - centroid
            };
            // A face through the reference point (a flat model without viewpoint) keeps the canonical normal, so
            // that all faces of one plane agree.
            let (normal, ring) = if plane.normal.dot(&towards) >= -1e-9 {
                (plane.normal, ring)
            } else {
                (-plane.normal, ring.into_iter().rev().collect())
            };
            faces.push(Face {
                ring,
                holes: Vec::new(),
                normal,
                kind: kind_of_plane(normal),
            });
        }
    }
    let mut walls = Vec::new();
    if viewpoint.is_some() {
        recessed_openings(vertices, &incident, edges, &mut faces);
        let inferred;
        (inferred, walls) = crate::openings::infer(
            vertices,
            edges_out,
            &planes,
            &plane_edges,
            &faces,
            tol,
            params,
            cameras,
            surface,
            evidence,
        );
        crate::openings::add(inferred, vertices, edges_out, &mut faces);
    }
    nest_openings(vertices, &mut faces, params);
    crate::openings::add_frames(&walls, params, vertices, edges_out, &mut faces);
    if params.panes {
        crate::openings::add_panes(&walls, params, vertices, edges_out, &mut faces);
    }
    if params.glass {
        crate::openings::add_glass(&walls, params, vertices, edges_out, &mut faces);
    }
    if params.sills {
        let cos_par = params.plane_angle_deg.to_radians().cos();
        crate::openings::add_sills(&walls, params.sill_rule(), cos_par, vertices, edges_out, &faces);
    }
    (faces, walls.into_iter().map(|v| v.wall).collect())
}

/// The edges with every vertex replaced by the first of the vertices within twice the plane tolerance `tol` of it
/// (single linkage), and the edges that then join a vertex to itself left out. Noise can leave two ends of one corner apart: a line
/// end left free a few millimetres from the corner its line runs into, or a reveal's corner beside the outline's.
/// Within twice the plane tolerance they cannot be told apart, and kept apart they break the face's cycle. The
/// wire-frame keeps both vertices; only the faces see one.
pub(crate) fn merge_close(vertices: &[Vertex], edges: &[Edge], tol: f64) -> Vec<Edge> {
    let reach = 2.0 * tol;
    let grid = crate::grid::SegmentGrid::of_points(vertices.iter().map(|v| v.point), reach);
    let mut sets = Disjoint::new(vertices.len());
    for (v, vertex) in vertices.iter().enumerate() {
        for w in grid.near_point(&vertex.point, reach) {
            if w > v && (vertices[w].point - vertex.point).norm() <= reach {
                sets.join(v, w);
            }
        }
    }
    edges
        .iter()
        .filter_map(|e| {
            let (a, b) = (sets.root(e.a), sets.root(e.b));
            (a != b).then_some(Edge { a, b, ..*e })
        })
        .collect()
}

/// The edges at each vertex.
pub(crate) fn incident_edges(n_vertices: usize, edges: &[Edge]) -> Vec<Vec<usize>> {
    let mut incident: Vec<Vec<usize>> = vec![Vec::new(); n_vertices];
    for (k, e) in edges.iter().enumerate() {
        incident[e.a].push(k);
        incident[e.b].push(k);
    }
    incident
}

/// Plane hypotheses at every corner from every pair of its non-parallel edges, merged greedily in a fixed order:
/// normals within `plane_angle_deg`, offsets within `tol`.
pub(crate) fn plane_hypotheses(vertices: &[Vertex], edges: &[Edge], incident: &[Vec<usize>], params: &ModelParams, tol: f64) -> Vec<Plane> {
    let dir = |e: &Edge, from: usize| {
        let (p, q) = if e.a == from { (e.a, e.b) } else { (e.b, e.a) };
        (vertices[q].point - vertices[p].point).normalize()
    };
    let min_sin = 10f64.to_radians().sin();
    let cos_merge = params.plane_angle_deg.to_radians().cos();
    let mut planes: Vec<Plane> = Vec::new();
    for (v, list) in incident.iter().enumerate() {
        for (x, &e1) in list.iter().enumerate() {
            for &e2 in &list[x + 1..] {
                let n = dir(&edges[e1], v).cross(&dir(&edges[e2], v));
                if n.norm() < min_sin {
                    continue;
                }
                let n = canonical(n.normalize());
                let p = vertices[v].point;
                let known = planes
                    .iter()
                    .any(|pl| pl.normal.dot(&n) > cos_merge && (pl.normal.dot(&p) - pl.offset).abs() < tol);
                if !known {
                    planes.push(refit(
                        vertices,
                        Plane {
                            normal: n,
                            offset: n.dot(&p),
                        },
                        cos_merge,
                        tol,
                    ));
                }
            }
        }
    }
    planes
}

/// A hypothesis from two edges at one corner, refitted to the vertices near it (least squares, smallest
/// eigenvector), three times with a shrinking band (3, 2, 1 × `tol`): two noisy edges give the normal a few
/// tenths of a degree off, which tilts a 30 m façade out of the tolerance at its far end, so the wall's outline
/// would never close. The normal may turn by less than the merge angle.
fn refit(vertices: &[Vertex], plane: Plane, cos_merge: f64, tol: f64) -> Plane {
    let mut p = plane;
    for band in [3.0 * tol, 2.0 * tol, tol] {
        let near: Vec<Vec3> = vertices
            .iter()
            .map(|v| v.point)
            .filter(|x| (p.normal.dot(x) - p.offset).abs() < band)
            .collect();
        if near.len() < 3 {
            break;
        }
        let c = near.iter().sum::<Vec3>() / near.len() as f64;
        let cov = near
            .iter()
            .fold(nalgebra::Matrix3::zeros(), |m, x| m + (x - c) * (x - c).transpose());
        let eig = nalgebra::SymmetricEigen::new(cov);
        let n = eig.eigenvectors.column(eig.eigenvalues.imin()).into_owned();
        let n = if n.dot(&p.normal) < 0.0 { -n } else { n };
        if n.dot(&p.normal) < cos_merge {
            break;
        }
        p = Plane {
            normal: n,
            offset: n.dot(&c),
        };
    }
    p
}

/// Three times the median corner σ, at least 5 mm: vertices of one plane scatter by their own precision.
pub(crate) fn plane_tolerance(vertices: &[Vertex], params: &ModelParams) -> f64 {
    let mut s: Vec<f64> = vertices.iter().filter_map(|v| v.sigma).map(|s| s.norm() / 3f64.sqrt()).collect();
    s.sort_by(f64::total_cmp);
    let typical = s.get(s.len() / 2).copied().unwrap_or(params.sigma_m);
    (3.0 * typical).max(0.005)
}

/// A normal's sign fixed by its largest component, so that both sides of a plane give one hypothesis.
fn canonical(n: Vec3) -> Vec3 {
    if n[n.iamax()] < 0.0 {
        -n
    } else {
        n
    }
}

fn kind_of_plane(normal: Vec3) -> SurfaceKind {
    if normal.z.abs() < 0.2 {
        SurfaceKind::Wall
    } else if normal.z > 0.98 {
        SurfaceKind::Floor
    } else if normal.z < -0.98 {
        SurfaceKind::Ground
    } else {
        SurfaceKind::Roof
    }
}

/// The bounded faces of the planar graph of `edges` (vertices projected into the plane), each as a simple cycle
/// traced counter-clockwise about `normal`. Dangling edges are pruned first.
fn cycles(vertices: &[Vertex], edges: &[&Edge], normal: Vec3) -> Vec<Vec<usize>> {
    let (u, v) = plane_basis(normal);
    let uv = |k: usize| [vertices[k].point.dot(&u), vertices[k].point.dot(&v)];
    let mut adj: BTreeMap<usize, Vec<usize>> = BTreeMap::new();
    for e in edges {
        adj.entry(e.a).or_default().push(e.b);
        adj.entry(e.b).or_default().push(e.a);
    }
    for list in adj.values_mut() {
        list.sort_unstable();
        list.dedup();
    }
    // Prune vertices of degree one until none is left.
    loop {
        let leaves: Vec<usize> = adj.iter().filter(|(_, l)| l.len() < 2).map(|(&k, _)| k).collect();
        if leaves.is_empty() {
            break;
        }
        for leaf in leaves {
            if let Some(list) = adj.remove(&leaf) {
                for n in list {
                    if let Some(l) = adj.get_mut(&n) {
                        l.retain(|&x| x != leaf);
                    }
                }
            }
        }
    }
    // Neighbours in counter-clockwise order of direction.
    for (&k, list) in adj.iter_mut() {
        let o = uv(k);
        list.sort_by(|&a, &b| {
            let (pa, pb) = (uv(a), uv(b));
            let aa = (pa[1] - o[1]).atan2(pa[0] - o[0]);
            let ab = (pb[1] - o[1]).atan2(pb[0] - o[0]);
            aa.total_cmp(&ab).then(a.cmp(&b))
        });
    }
    let mut used = std::collections::HashSet::new();
    let mut out = Vec::new();
    for (&start, list) in &adj {
        for &next in list {
            if used.contains(&(start, next)) {
                continue;
            }
            // Walk keeping the face on the left: at each vertex turn to the neighbour just clockwise of the one
            // we came from.
            let mut ring = vec![start];
            let (mut a, mut b) = (start, next);
            let mut simple = true;
            loop {
                used.insert((a, b));
                let around = &adj[&b];
                let i = around.iter().position(|&x| x == a).unwrap_or(0);
                let c = around[(i + around.len() - 1) % around.len()];
                if b == start {
                    break;
                }
                if ring.contains(&b) {
                    simple = false;
                }
                ring.push(b);
                (a, b) = (b, c);
                if ring.len() > edges.len() + 1 {
                    simple = false;
                    break;
                }
            }
            let pts: Vec<[f64; 2]> = ring.iter().map(|&k| uv(k)).collect();
            if simple && ring.len() >= 3 && signed_area(&pts) > 1e-4 {
                out.push(ring);
            }
        }
    }
    out
}

/// A vertical face at least [`MIN_OPENING_M`] across whose corners (two or more) have edges running straight back
/// from it, and none running forward, is an opening in its own right: a hole with reveals, even where the wall's
/// outline is not closed (a façade's foot or top edge is often hidden). Two corners, because a street-level
/// camera sees only the reveals at an opening's top corners (from above, its bottom ones); the size keeps out the
/// front of a sill, whose edges also run back to the wall.
/// Needs outward normals, i.e. a viewpoint. The edges are those of the merged graph ([`merge_close`]), so a reveal
/// whose junction noise kept a few millimetres from the corner counts at the corner.
fn recessed_openings(vertices: &[Vertex], incident: &[Vec<usize>], edges: &[Edge], faces: &mut [Face]) {
    let cos = 20f64.to_radians().cos();
    for f in faces.iter_mut() {
        if f.kind != SurfaceKind::Wall || smaller_side(vertices, &f.ring, f.normal) < MIN_OPENING_M {
            continue;
        }
        let (mut back, mut forward) = (0, 0);
        for &v in &f.ring {
            let goes = |sign: f64| {
                incident[v].iter().any(|&e| {
                    let other = if edges[e].a == v { edges[e].b } else { edges[e].a };
                    let d = (vertices[other].point - vertices[v].point).normalize();
                    sign * d.dot(&f.normal) > cos
                })
            };
            back += usize::from(goes(-1.0));
            forward += usize::from(goes(1.0));
        }
        if back >= 2 && forward == 0 {
            f.kind = SurfaceKind::Window;
        }
    }
}

/// The smallest opening found by its reveals alone, metres (a cellar window; a sill's front is 6 cm tall).
const MIN_OPENING_M: f64 = 0.25;

/// A face lying inside a larger wall or roof face of the same plane, sharing no vertex with it, is that face's
/// opening (the innermost container wins): a window, or a door when it reaches within 0.3 m of the container's
/// foot (of the model's lowest point, for an opening no wall face holds). Faces
/// behind an opening (reveals excepted: frames and glass parallel to it, within 0.5 m) take the opening's kind.
fn nest_openings(vertices: &[Vertex], faces: &mut [Face], params: &ModelParams) {
    let cos_par = params.plane_angle_deg.to_radians().cos();
    let flat = |f: &Face, ring: &[usize]| -> Vec<[f64; 2]> {
        let (u, v) = plane_basis(f.normal);
        ring.iter()
            .map(|&k| [vertices[k].point.dot(&u), vertices[k].point.dot(&v)])
            .collect()
    };
    // Each face's polygon in its own plane, area and offset, once.
    let polys: Vec<Vec<[f64; 2]>> = faces.iter().map(|f| flat(f, &f.ring)).collect();
    let areas: Vec<f64> = polys.iter().map(|p| signed_area(p).abs()).collect();
    let centroids: Vec<Vec3> = faces
        .iter()
        .map(|f| f.ring.iter().map(|&k| vertices[k].point).sum::<Vec3>() / f.ring.len() as f64)
        .collect();
    let mut parent: Vec<Option<usize>> = vec![None; faces.len()];
    let container = |k: SurfaceKind| matches!(k, SurfaceKind::Wall | SurfaceKind::Roof);
    for (i, f) in faces.iter().enumerate() {
        if !container(f.kind) && f.kind != SurfaceKind::Window {
            continue;
        }
        let mut best: Option<(f64, usize)> = None;
        for (j, g) in faces.iter().enumerate() {
            let coplanar = g.normal.dot(&f.normal) > cos_par && f.normal.dot(&(centroids[j] - centroids[i])).abs() < 0.01;
            if i == j || !container(g.kind) || !coplanar || areas[j] <= areas[i] || g.ring.iter().any(|v| f.ring.contains(v)) {
                continue;
            }
            if polys[i].iter().all(|&q| point_in_polygon(q, &polys[j])) && best.is_none_or(|(a, _)| areas[j] < a) {
                best = Some((areas[j], j));
            }
        }
        parent[i] = best.map(|(_, j)| j);
    }
    let foot = |f: &Face| f.ring.iter().map(|&k| vertices[k].point.z).fold(f64::INFINITY, f64::min);
    // The ground: the lowest point of the model (a wall's lines reach further down than its closed faces).
    let ground = vertices.iter().map(|v| v.point.z).fold(f64::INFINITY, f64::min);
    for i in 0..faces.len() {
        let door_level = match parent[i] {
            Some(p) if faces[p].kind == SurfaceKind::Wall => foot(&faces[p]),
            Some(_) => f64::NEG_INFINITY,
            // An opening by its reveals alone: a door when it reaches down to the lowest face.
            None if faces[i].kind == SurfaceKind::Window => ground,
            None => continue,
        };
        faces[i].kind = if foot(&faces[i]) - door_level < 0.3 {
            SurfaceKind::Door
        } else {
            SurfaceKind::Window
        };
        if let Some(p) = parent[i] {
            let ring = faces[i].ring.iter().rev().copied().collect();
            faces[p].holes.push(ring);
        }
    }
    // Frames and glass behind an opening.
    let openings: Vec<usize> = (0..faces.len())
        .filter(|&i| matches!(faces[i].kind, SurfaceKind::Window | SurfaceKind::Door))
        .collect();
    for i in 0..faces.len() {
        if parent[i].is_some() || faces[i].kind != SurfaceKind::Wall {
            continue;
        }
        let c = faces[i].ring.iter().map(|&k| vertices[k].point).sum::<Vec3>() / faces[i].ring.len() as f64;
        for &o in &openings {
            let of = &faces[o];
            let depth = of.normal.dot(&(vertices[of.ring[0]].point - c));
            if of.normal.dot(&faces[i].normal) > cos_par && depth > 0.0 && depth < 0.5 {
                let (u, v) = plane_basis(of.normal);
                if point_in_polygon([c.dot(&u), c.dot(&v)], &polys[o]) {
                    faces[i].kind = of.kind;
                    break;
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use lineflow_messages::FaceVertex;

    #[test]
    fn kind_codes_follow_the_message_contract() {
        assert_eq!(SurfaceKind::Window.code(), FaceVertex::KIND_WINDOW);
        assert_eq!(SurfaceKind::Door.code(), FaceVertex::KIND_DOOR);
        for k in SurfaceKind::ALL {
            assert_eq!(SurfaceKind::from_code(k.code()), Some(k));
        }
        assert_eq!(SurfaceKind::from_code(6), None);
    }
}
