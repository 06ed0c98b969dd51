//! Occluded-edge completion (seed 003 §3.4.2): a face whose boundary is an open chain, because a structure in
//! front of it hides one of its edges, is closed along the shortest path through that structure's outline.
//!
//! The seed works in the XY projection of roofs: a lower roof next to a higher building loses the edge where it
//! meets that building; both ends of its open boundary meet the higher building's outline in plan, and the hidden
//! edge is the shortest path between those junctions through the higher building's corners (Floyd–Warshall over
//! the plan graph), with the heights of the lower roof. The same reasoning holds for a wall that a structure in
//! front of it (a protruding neighbour, a wing, a balcony slab) hides, in the wall's own projection. Here:
//!
//! - the projection runs along Z for roofs and horizontal planes, as in the seed, and along the horizontal normal
//!   towards the cameras for walls (it needs the viewpoint: which side is the front);
//! - "higher" is "in front by more than `occlusion_min_depth_m`" (the seed: higher by more than k √2 σ_Z, with
//!   the σ of building-level lines), and the occluder is another structure, not connected to the chain through
//!   corners. Both keep a façade's own relief out: a sill, a cornice, a frame or a reveal hides parts of its
//!   opening or of the wall that are no edges of the model, and closing those would add faces that do not exist;
//! - an open chain is a connected set of edges in one plane with exactly two free ends (the seed: two unresolved
//!   boundary ends), not all parallel, and of a building's scale (at least twice `occlusion_min_depth_m` across
//!   in both directions of its plane);
//! - each free end is extended, up to `occlusion_reach_m` either way, to the nearest crossing with an occluder
//!   edge's projection (the seed's junction of lines 1 and 5);
//! - the shortest path between the two junctions runs over the occluders' projected edges (Dijkstra from the one
//!   junction gives the same path as the seed's all-pairs Floyd–Warshall, in O(E log V)); the face's own vertices
//!   are never on it because they are not in front;
//! - the path's nodes are put into the face's plane along the projection direction: for a plane face this is
//!   exact, where the seed's eq. 5 (heights shared out by path length) leaves a bent path off a tilted plane;
//! - a path longer than three times the distance between its ends is refused as a detour, not an outline.
//!
//! The façade's own relief hides edges at a smaller scale, where a path along the occluder would put the edge on
//! the occluder: a sill hides the bottom edge of a window above the cameras while its sides are seen to their
//! ends. Such a chain, a U, is closed by the chord between its seen ends (`relief_hides_chord`).
use std::cmp::Reverse;
use std::collections::{BTreeMap, BinaryHeap};

use lineflow_photogrammetry::Vec3;

use crate::disjoint::Disjoint;
use crate::faces::{incident_edges, merge_close, plane_hypotheses, plane_tolerance};
use crate::surface::{plane_basis, smaller_side, Plane};
use crate::{Edge, EdgeOrigin, ModelParams, Vertex};

/// Closes the open chains that an occluder in front of them explains; appends the new vertices (no σ) and edges
/// (`completed`) and returns the number of chains closed. `viewpoint` (e.g. the mean camera centre) tells walls
/// their front; without it only roofs and horizontal faces are completed.
pub fn complete(vertices: &mut Vec<Vertex>, edges: &mut Vec<Edge>, params: &ModelParams, viewpoint: Option<Vec3>) -> usize {
    if params.occlusion_reach_m <= 0.0 || vertices.is_empty() {
        return 0;
    }
    let tol = plane_tolerance(vertices, params);
    // The wire-frame as the faces will see it (corners split by noise made one), so that a chain is open here
    // exactly when its face would be.
    let mut graph = merge_close(vertices, edges, tol);
    let incident = incident_edges(vertices.len(), &graph);
    let planes = plane_hypotheses(vertices, &graph, &incident, params, tol);
    let mut closed = 0;
    // The structures change only where a completion joins two; recomputed then, not for every plane.
    let mut component = components(vertices.len(), &graph);
    for plane in planes {
        let Some(up) = projection_direction(&plane, vertices, viewpoint) else {
            continue;
        };
        let view = PlaneView {
            plane,
            up,
            tol,
            min_depth: params.occlusion_min_depth_m.max(std::f64::consts::SQRT_2 * tol),
        };
        let chains = open_chains(vertices, &graph, &view);
        if chains.is_empty() {
            continue;
        }
        // Only a chain of a building's scale looks for occluders: found once per plane, when one needs them.
        let mut occluders: Option<Occluders> = None;
        // The wire-frame as it was when the plane's turn came (a chord completed meanwhile is no occluder).
        let (n_vertices, n_graph, closed_before) = (vertices.len(), graph.len(), closed);
        for chain in chains {
            let own = component[chain.ends[0].0];
            // The seed's case needs a face of a building's scale: a façade's relief (reveals, frames, sills) is
            // smaller than the depth that makes an occluder, and its planes are not 2.5-D along their normals.
            let building = chain.extent >= 2.0 * view.min_depth && faces_the_viewpoint(vertices, &chain, &view, viewpoint);
            let reach = params.occlusion_reach_m;
            let seed_path = building
                .then(|| {
                    let occluders =
                        occluders.get_or_insert_with(|| Occluders::of(&vertices[..n_vertices], &graph[..n_graph], &component, &view));
                    hidden_path(vertices, &graph, occluders, own, &view, &chain, reach)
                })
                .flatten();
            let path = seed_path.or_else(|| {
                let [(a, _), (b, _)] = chain.ends;
                relief_hides_chord(vertices, &graph, &component, &view, &chain, reach, viewpoint)
                    .then(|| vec![vertices[a].point, vertices[b].point])
            });
            if let Some(path) = path {
                let before = edges.len();
                add_path(vertices, edges, &chain, &path, tol);
                graph.extend_from_slice(&edges[before..]);
                closed += 1;
            }
        }
        // Later chains of a plane keep the structures as they were before any completion of it, as they always
        // have; later planes see the joined ones.
        if closed > closed_before {
            component = components(vertices.len(), &graph);
        }
    }
    closed
}

/// The façade's own relief hides an opening's edge where the opening's other edges are seen whole: a sill hides the
/// bottom edge of a window above the cameras, 3 cm above it. The chain is a U (its two end edges run the same
/// way, the chord between its free ends across them), and an observed edge of another structure, in front by
/// less than `occlusion_min_depth_m`, runs along the chord (parallel within 10°, over half its length) on its
/// outer side within `reach`, and the cameras look at the chord over it (the viewpoint on that side). Then the
/// free ends are the corners and the chord is the hidden edge. An occluder on the inner side (a frame behind the
/// opening's outline) does not qualify: the edge it hides is no outline of the face.
fn relief_hides_chord(
    vertices: &[Vertex],
    edges: &[Edge],
    component: &[usize],
    view: &PlaneView,
    chain: &Chain,
    reach: f64,
    viewpoint: Option<Vec3>,
) -> bool {
    let [(v0, p0), (v1, p1)] = chain.ends;
    let (a, b) = (vertices[v0].point, vertices[v1].point);
    let (Some(d0), Some(d1)) = (
        (a - vertices[p0].point).try_normalize(1e-12),
        (b - vertices[p1].point).try_normalize(1e-12),
    ) else {
        return false;
    };
    let (cos10, sin10) = (10f64.to_radians().cos(), 10f64.to_radians().sin());
    let len = (b - a).norm();
    let c = (b - a) / len.max(1e-12);
    if d0.dot(&d1) < cos10 || len < 2.0 * view.tol || c.dot(&d0).abs() > sin10 {
        return false;
    }
    let Some(out) = ((d0 + d1) - c * c.dot(&(d0 + d1))).try_normalize(1e-12) else {
        return false;
    };
    let mid = (a + b) / 2.0;
    if viewpoint.is_none_or(|eye| (eye - mid).dot(&out) <= 0.0) {
        return false;
    }
    let own = component[v0];
    let relief = |x: &Vec3| {
        let h = view.height(x);
        h > std::f64::consts::SQRT_2 * view.tol && h < view.min_depth
    };
    edges.iter().any(|e| {
        if !e.observed() || component.get(e.a).is_none_or(|&k| k == own) {
            return false;
        }
        let (pa, pb) = (vertices[e.a].point, vertices[e.b].point);
        if !(relief(&pa) && relief(&pb)) {
            return false;
        }
        let (qa, qb) = (view.project(&pa), view.project(&pb));
        let parallel = (qb - qa).try_normalize(1e-12).is_some_and(|d| d.dot(&c).abs() > cos10);
        let outside = [qa, qb].iter().all(|q| (-view.tol..=reach).contains(&(q - a).dot(&out)));
        let (ta, tb) = ((qa - a).dot(&c), (qb - a).dot(&c));
        let overlap = ta.max(tb).min(len) - ta.min(tb).max(0.0);
        parallel && outside && overlap >= 0.5 * len
    })
}

/// The observed edges standing in front of a plane, with their structures (connected components).
struct Occluders {
    edges: Vec<(usize, usize)>,
}

impl Occluders {
    /// Edges in front by `min_depth` or more. For a wall, only structures that reach back to it (a wing, a
    /// balcony, a neighbour built against it): a façade is 2.5-D along its normal only where the structure in
    /// front stands on it. Roofs keep the seed's plan reasoning, where every roof is a block standing on the
    /// ground.
    fn of(vertices: &[Vertex], edges: &[Edge], component: &[usize], view: &PlaneView) -> Occluders {
        let wall = view.up.z.abs() < 0.5;
        // Components are named by their smallest vertex, so a flag per vertex index marks them.
        let mut standing = vec![false; vertices.len()];
        if wall {
            for v in (0..vertices.len()).filter(|&v| view.height(&vertices[v].point).abs() < 0.5 * view.min_depth) {
                standing[component[v]] = true;
            }
        }
        let edges = (0..edges.len())
            .filter(|&k| edges[k].observed())
            .filter(|&k| view.in_front(&vertices[edges[k].a].point) && view.in_front(&vertices[edges[k].b].point))
            .map(|k| (k, component[edges[k].a]))
            .filter(|&(_, c)| !wall || standing[c])
            .collect();
        Occluders { edges }
    }

    /// The edges of structures other than `own`.
    fn except(&self, own: usize) -> Vec<usize> {
        self.edges.iter().filter(|e| e.1 != own).map(|e| e.0).collect()
    }
}

/// Whether the chain is seen roughly along the projection direction (within 45°): the cameras look at the face
/// the way the plan or the façade's elevation reasons. A reveal or a side wall seen at a grazing angle, or a sill
/// top seen from the street, is not. Without a viewpoint only roofs are completed (the seed's plan view).
fn faces_the_viewpoint(vertices: &[Vertex], chain: &Chain, view: &PlaneView, viewpoint: Option<Vec3>) -> bool {
    let Some(eye) = viewpoint else {
        return view.up.z.abs() > 0.5;
    };
    let mid = (vertices[chain.ends[0].0].point + vertices[chain.ends[1].0].point) / 2.0;
    (eye - mid)
        .try_normalize(1e-9)
        .is_some_and(|d| d.dot(&view.up) > std::f64::consts::FRAC_1_SQRT_2)
}

/// The connected component of every vertex (the smallest vertex index in it).
fn components(n: usize, edges: &[Edge]) -> Vec<usize> {
    let mut sets = Disjoint::new(n);
    for e in edges {
        sets.join(e.a, e.b);
    }
    (0..n).map(|v| sets.root(v)).collect()
}

/// A plane with the direction occluders are sought in and points are projected along.
struct PlaneView {
    plane: Plane,
    /// Unit direction towards the front (the cameras); not parallel to the plane.
    up: Vec3,
    tol: f64,
    /// How far in front an occluder stands at least.
    min_depth: f64,
}

impl PlaneView {
    /// How far `x` lies in front of the plane, measured along `up`.
    fn height(&self, x: &Vec3) -> f64 {
        (self.plane.normal.dot(x) - self.plane.offset) / self.plane.normal.dot(&self.up)
    }
    /// `x` moved along `up` into the plane.
    fn project(&self, x: &Vec3) -> Vec3 {
        x - self.up * self.height(x)
    }
    fn on_plane(&self, x: &Vec3) -> bool {
        (self.plane.normal.dot(x) - self.plane.offset).abs() < self.tol
    }
    fn in_front(&self, x: &Vec3) -> bool {
        self.height(x) > self.min_depth
    }
}

/// +Z for roofs and horizontal planes (the seed's plan view); the horizontal normal towards `viewpoint` for walls.
fn projection_direction(plane: &Plane, vertices: &[Vertex], viewpoint: Option<Vec3>) -> Option<Vec3> {
    let n = plane.normal;
    if n.z.abs() > 0.5 {
        return Some(Vec3::z());
    }
    let h = Vec3::new(n.x, n.y, 0.0).try_normalize(1e-9)?;
    let on = vertices
        .iter()
        .map(|v| v.point)
        .find(|p| (n.dot(p) - plane.offset).abs() < 1e-3)
        .unwrap_or(n * plane.offset);
    let towards = viewpoint? - on;
    Some(if h.dot(&towards) >= 0.0 { h } else { -h })
}

/// An open chain: its two free ends, each with the vertex before it, in a fixed order, and its size.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Chain {
    ends: [(usize, usize); 2],
    /// The smaller side of its bounding rectangle in the plane, metres.
    extent: f64,
}

/// The connected sets of in-plane edges with exactly two vertices of degree one, not all parallel.
fn open_chains(vertices: &[Vertex], edges: &[Edge], view: &PlaneView) -> Vec<Chain> {
    let in_plane: Vec<&Edge> = edges
        .iter()
        .filter(|e| view.on_plane(&vertices[e.a].point) && view.on_plane(&vertices[e.b].point))
        .collect();
    let mut adj: BTreeMap<usize, Vec<usize>> = BTreeMap::new();
    for e in &in_plane {
        adj.entry(e.a).or_default().push(e.b);
        adj.entry(e.b).or_default().push(e.a);
    }
    for list in adj.values_mut() {
        list.sort_unstable();
        list.dedup();
    }
    let mut seen = std::collections::BTreeSet::new();
    let mut out = Vec::new();
    for &start in adj.keys() {
        if !seen.insert(start) {
            continue;
        }
        let mut component = vec![start];
        let mut k = 0;
        while k < component.len() {
            for &n in &adj[&component[k]] {
                if seen.insert(n) {
                    component.push(n);
                }
            }
            k += 1;
        }
        let leaves: Vec<usize> = component.iter().copied().filter(|v| adj[v].len() == 1).collect();
        if leaves.len() != 2 || component.len() < 3 {
            continue;
        }
        let directions: Vec<Vec3> = component
            .iter()
            .flat_map(|&a| adj[&a].iter().map(move |&b| (a, b)))
            .filter_map(|(a, b)| (vertices[b].point - vertices[a].point).try_normalize(1e-12))
            .collect();
        let bent = directions.iter().any(|d| d.cross(&directions[0]).norm() > 10f64.to_radians().sin());
        if bent {
            out.push(Chain {
                ends: [(leaves[0], adj[&leaves[0]][0]), (leaves[1], adj[&leaves[1]][0])],
                extent: smaller_side(vertices, &component, view.plane.normal),
            });
        }
    }
    out
}

/// Where a free end's line, extended up to `reach` either way, first crosses an occluder edge's projection: the
/// point (in the plane) and the edge.
fn junction(
    vertices: &[Vertex],
    occluders: &[usize],
    edges: &[Edge],
    view: &PlaneView,
    end: (usize, usize),
    reach: f64,
) -> Option<(Vec3, usize)> {
    let (u, v) = plane_basis(view.plane.normal);
    let flat = |x: &Vec3| [x.dot(&u), x.dot(&v)];
    let (p, before) = (vertices[end.0].point, vertices[end.1].point);
    let d = (p - before).try_normalize(1e-12)?;
    let (p2, d2) = (flat(&p), [d.dot(&u), d.dot(&v)]);
    let mut best: Option<(f64, Vec3, usize)> = None;
    for &k in occluders {
        let (a, b) = (view.project(&vertices[edges[k].a].point), view.project(&vertices[edges[k].b].point));
        let (a2, b2) = (flat(&a), flat(&b));
        let s = [b2[0] - a2[0], b2[1] - a2[1]];
        let denom = d2[0] * s[1] - d2[1] * s[0];
        let len = s[0].hypot(s[1]);
        // Parallel to the chain's line: it continues the line, it does not stop it.
        if len < 1e-9 || denom.abs() < 0.1 * len {
            continue;
        }
        let w = [a2[0] - p2[0], a2[1] - p2[1]];
        let lambda = (w[0] * s[1] - w[1] * s[0]) / denom;
        let mu = (w[0] * d2[1] - w[1] * d2[0]) / denom;
        let slack = view.tol / len;
        if lambda.abs() > reach || !(-slack..=1.0 + slack).contains(&mu) {
            continue;
        }
        if best.is_none_or(|(l, _, _)| lambda.abs() < l) {
            best = Some((lambda.abs(), a + (b - a) * mu.clamp(0.0, 1.0), k));
        }
    }
    best.map(|(_, x, k)| (view.project(&x), k))
}

/// The hidden part of a chain's boundary: the junctions and the occluder's corners between them, in the plane, from
/// the chain's first end to its second.
fn hidden_path(
    vertices: &[Vertex],
    edges: &[Edge],
    occluders: &Occluders,
    own: usize,
    view: &PlaneView,
    chain: &Chain,
    reach: f64,
) -> Option<Vec<Vec3>> {
    let occluders = occluders.except(own);
    if occluders.is_empty() {
        return None;
    }
    let (j0, k0) = junction(vertices, &occluders, edges, view, chain.ends[0], reach)?;
    let (j1, k1) = junction(vertices, &occluders, edges, view, chain.ends[1], reach)?;
    let chord = (j1 - j0).norm();
    if chord < view.tol {
        return None;
    }
    let corners = if k0 == k1 {
        Vec::new()
    } else {
        shortest_path(vertices, edges, &occluders, view, (j0, k0), (j1, k1))?
    };
    let path: Vec<Vec3> = std::iter::once(j0)
        .chain(corners.iter().map(|&c| view.project(&vertices[c].point)))
        .chain(std::iter::once(j1))
        .collect();
    let length: f64 = path.windows(2).map(|w| (w[1] - w[0]).norm()).sum();
    (length <= 3.0 * chord).then_some(path)
}

/// The occluder vertices on the shortest path (lengths in the plane's projection) from a junction on edge `from.1`
/// to one on edge `to.1`, in order.
fn shortest_path(
    vertices: &[Vertex],
    edges: &[Edge],
    occluders: &[usize],
    view: &PlaneView,
    from: (Vec3, usize),
    to: (Vec3, usize),
) -> Option<Vec<usize>> {
    let at = |v: usize| view.project(&vertices[v].point);
    let mut adj: BTreeMap<usize, Vec<(usize, f64)>> = BTreeMap::new();
    for &k in occluders {
        let (a, b) = (edges[k].a, edges[k].b);
        let w = (at(a) - at(b)).norm();
        adj.entry(a).or_default().push((b, w));
        adj.entry(b).or_default().push((a, w));
    }
    // Costs in integer micrometres keep the heap's order total and the result deterministic.
    let cost = |x: f64| (x * 1e6).round() as u64;
    let mut dist: BTreeMap<usize, (u64, Option<usize>)> = BTreeMap::new();
    let mut heap = BinaryHeap::new();
    let start = &edges[from.1];
    for v in [start.a, start.b] {
        let c = cost((at(v) - from.0).norm());
        if dist.get(&v).is_none_or(|&(d, _)| c < d) {
            dist.insert(v, (c, None));
            heap.push(Reverse((c, v)));
        }
    }
    while let Some(Reverse((d, v))) = heap.pop() {
        if dist.get(&v).is_some_and(|&(best, _)| d > best) {
            continue;
        }
        for &(n, w) in adj.get(&v).map_or(&[][..], |l| l.as_slice()) {
            let c = d + cost(w);
            if dist.get(&n).is_none_or(|&(best, _)| c < best) {
                dist.insert(n, (c, Some(v)));
                heap.push(Reverse((c, n)));
            }
        }
    }
    let end = &edges[to.1];
    let last = [end.a, end.b]
        .into_iter()
        .filter_map(|v| dist.get(&v).map(|&(d, _)| (d + cost((at(v) - to.0).norm()), v)))
        .min()?
        .1;
    let mut path = vec![last];
    while let Some(&(_, Some(prev))) = dist.get(path.last()?) {
        path.push(prev);
    }
    path.reverse();
    Some(path)
}

/// Appends the path's vertices and the edges from the chain's first free end through the path to its second; a
/// junction within `tol` of its free end (the line ended right at the occluder) is that end.
fn add_path(vertices: &mut Vec<Vertex>, edges: &mut Vec<Edge>, chain: &Chain, path: &[Vec3], tol: f64) {
    let (first, last) = (chain.ends[0].0, chain.ends[1].0);
    let mut ids = vec![first];
    for (k, p) in path.iter().enumerate() {
        let end = match k {
            0 => Some(first),
            _ if k + 1 == path.len() => Some(last),
            _ => None,
        };
        match end {
            Some(e) if (vertices[e].point - p).norm() < tol => ids.push(e),
            _ => {
                vertices.push(Vertex { point: *p, sigma: None });
                ids.push(vertices.len() - 1);
            }
        }
    }
    ids.push(last);
    ids.dedup();
    for w in ids.windows(2) {
        edges.push(Edge {
            a: w[0],
            b: w[1],
            line: usize::MAX,
            origin: EdgeOrigin::Hidden,
        });
    }
}

#[cfg(test)]
mod tests {
    use crate::{build, Cameras, EdgeOrigin, Model, ModelLine, ModelParams, SurfaceKind};
    use lineflow_photogrammetry::Vec3;

    fn lines(segments: &[([f64; 3], [f64; 3])]) -> Vec<ModelLine> {
        segments
            .iter()
            .map(|&(a, b)| ModelLine::new(Vec3::from(a), Vec3::from(b), 0.005))
            .collect()
    }

    fn has_vertex(model: &Model, ring: &[usize], p: [f64; 3]) -> bool {
        ring.iter().any(|&v| (model.vertices[v].point - Vec3::from(p)).norm() < 1e-3)
    }

    /// The seed's Fig. 14: a lower roof (tilted, z = 5 + 0.3 y) whose corner is hidden under a higher flat roof
    /// (z = 9) reaching over it. The lower roof's boundary stops where it meets the higher roof in plan; the hidden
    /// boundary runs along the higher roof's outline, through its corner (2, 2), at the lower roof's heights.
    #[test]
    fn a_roof_under_a_higher_one_is_closed_along_its_outline() {
        let z = |y: f64| 5.0 + 0.3 * y;
        let mut segs = vec![
            ([0.0, 2.0, z(2.0)], [0.0, 0.0, z(0.0)]),
            ([0.0, 0.0, z(0.0)], [10.0, 0.0, z(0.0)]),
            ([10.0, 0.0, z(0.0)], [10.0, 6.0, z(6.0)]),
            ([10.0, 6.0, z(6.0)], [2.0, 6.0, z(6.0)]),
        ];
        let high = [[-4.0, 2.0], [2.0, 2.0], [2.0, 8.0], [-4.0, 8.0]];
        for k in 0..4 {
            let (a, b) = (high[k], high[(k + 1) % 4]);
            segs.push(([a[0], a[1], 9.0], [b[0], b[1], 9.0]));
        }
        let params = ModelParams::default();
        let model = build(&lines(&segs), &params, &Vec3::new(4.0, 3.0, 300.0).into());
        assert_eq!(model.diagnostics.chains_completed, 1, "{}", model.summary());
        let completed: Vec<_> = model.edges.iter().filter(|e| e.origin == EdgeOrigin::Hidden).collect();
        assert_eq!(completed.len(), 2, "(0, 2) → (2, 2) → (2, 6)");
        let roof = model
            .faces
            .iter()
            .find(|f| f.kind == SurfaceKind::Roof)
            .expect("the lower roof is a face");
        assert_eq!(roof.ring.len(), 6);
        for p in [[0.0, 2.0, z(2.0)], [2.0, 2.0, z(2.0)], [2.0, 6.0, z(6.0)], [10.0, 0.0, z(0.0)]] {
            assert!(has_vertex(&model, &roof.ring, p), "{p:?} in {:?}", roof.ring);
        }
        // Without completion the roof stays open.
        let off = ModelParams {
            occlusion_reach_m: 0.0,
            ..params
        };
        let open = build(&lines(&segs), &off, &Vec3::new(4.0, 3.0, 300.0).into());
        assert!(open.faces.iter().all(|f| f.kind != SurfaceKind::Roof));
        assert_eq!(open.diagnostics.chains_completed, 0);
    }

    /// A wall (y = 0, cameras at y < 0) whose right part is hidden by a block standing 3 m in front of it: its top
    /// and bottom edges end at the block's left edge in the wall's projection, which closes it.
    fn facade(block_y: f64) -> Vec<ModelLine> {
        let mut segs = vec![
            ([0.0, 0.0, 0.0], [0.0, 0.0, 6.0]),
            ([0.0, 0.0, 6.0], [8.0, 0.0, 6.0]),
            ([0.0, 0.0, 0.0], [8.0, 0.0, 0.0]),
        ];
        let front = [[8.0, 0.0], [14.0, 0.0], [14.0, 8.0], [8.0, 8.0]];
        for k in 0..4 {
            let (a, b) = (front[k], front[(k + 1) % 4]);
            segs.push(([a[0], block_y, a[1]], [b[0], block_y, b[1]]));
        }
        segs.push(([8.0, block_y, 8.0], [8.0, 0.0, 8.0]));
        segs.push(([14.0, block_y, 8.0], [14.0, 0.0, 8.0]));
        lines(&segs)
    }

    #[test]
    fn a_wall_hidden_by_a_block_in_front_is_closed_along_the_block() {
        let camera = &Cameras::from(Vec3::new(5.0, -20.0, 1.5));
        let model = build(&facade(-3.0), &ModelParams::default(), camera);
        assert_eq!(model.diagnostics.chains_completed, 1, "{}", model.summary());
        let wall = model
            .faces
            .iter()
            .find(|f| f.kind == SurfaceKind::Wall && f.ring.iter().all(|&v| model.vertices[v].point.y.abs() < 1e-3))
            .expect("the wall is a face");
        assert_eq!(wall.ring.len(), 4);
        assert!(has_vertex(&model, &wall.ring, [8.0, 0.0, 6.0]) && has_vertex(&model, &wall.ring, [8.0, 0.0, 0.0]));
        assert!(wall.normal.y < -0.99, "outward, towards the cameras");
    }

    #[test]
    fn nothing_is_completed_without_an_occluder_in_front() {
        let camera = &Cameras::from(Vec3::new(5.0, -20.0, 1.5));
        // The block behind the wall hides nothing.
        let behind = build(&facade(3.0), &ModelParams::default(), camera);
        assert_eq!(behind.diagnostics.chains_completed, 0);
        assert!(behind.edges.iter().all(|e| e.observed()));
        // No viewpoint: a wall has no known front.
        let blind = build(&facade(-3.0), &ModelParams::default(), &Cameras::default());
        assert_eq!(blind.diagnostics.chains_completed, 0);
        // The wall alone.
        let alone = build(&facade(-3.0)[..3], &ModelParams::default(), camera);
        assert_eq!(alone.diagnostics.chains_completed, 0);
    }
}

#[cfg(test)]
mod relief_tests {
    use crate::{build, EdgeOrigin, ModelLine, ModelParams, SurfaceKind};
    use lineflow_photogrammetry::Vec3;

    /// A window (x 1…2.4, z 10…11.7 in the wall y = 0) whose bottom edge is not seen, with reveals running back
    /// from its top corners and a sill 6 cm in front, 3 cm below it.
    fn window_over_a_sill(sill_y: f64, sill_z: f64) -> Vec<ModelLine> {
        let segs: [([f64; 3], [f64; 3]); 7] = [
            ([1.0, 0.0, 10.0], [1.0, 0.0, 11.7]),
            ([1.0, 0.0, 11.7], [2.4, 0.0, 11.7]),
            ([2.4, 0.0, 11.7], [2.4, 0.0, 10.0]),
            ([1.0, 0.0, 11.7], [1.0, 0.2, 11.7]),
            ([2.4, 0.0, 11.7], [2.4, 0.2, 11.7]),
            ([0.95, sill_y, sill_z], [2.45, sill_y, sill_z]),
            ([0.95, sill_y, sill_z - 0.06], [2.45, sill_y, sill_z - 0.06]),
        ];
        segs.iter()
            .map(|&(a, b)| ModelLine::new(Vec3::from(a), Vec3::from(b), 0.002))
            .collect()
    }

    fn window_faces(lines: &[ModelLine], camera: Vec3) -> (usize, usize) {
        let model = build(lines, &ModelParams::default(), &camera.into());
        // The only face reaches the lowest foot, so it is called a door.
        let windows = model.count(&[SurfaceKind::Window, SurfaceKind::Door]);
        (model.diagnostics.chains_completed, windows)
    }

    #[test]
    fn a_sill_hides_the_bottom_edge_of_a_window_seen_from_below() {
        let below = Vec3::new(1.7, -12.0, 1.5);
        let (closed, windows) = window_faces(&window_over_a_sill(-0.06, 9.97), below);
        assert_eq!((closed, windows), (1, 1), "closed along the chord, an opening by its reveals");
        let model = build(&window_over_a_sill(-0.06, 9.97), &ModelParams::default(), &below.into());
        let hidden: Vec<_> = model.edges.iter().filter(|e| e.origin == EdgeOrigin::Hidden).collect();
        assert_eq!(hidden.len(), 1);
        let (a, b) = (model.vertices[hidden[0].a].point, model.vertices[hidden[0].b].point);
        assert!(
            (a.z - 10.0).abs() < 1e-9 && (b.z - 10.0).abs() < 1e-9,
            "the chord between the seen ends: {a} {b}"
        );
        assert_eq!(model.visible_edges().len(), model.edges.len() - 1);
    }

    #[test]
    fn no_chord_without_a_sill_on_the_outer_side_seen_from_that_side() {
        // Seen from above, the sill hides nothing of the window.
        let above = Vec3::new(1.7, -12.0, 25.0);
        assert_eq!(window_faces(&window_over_a_sill(-0.06, 9.97), above).0, 0);
        // An occluder across the window's inside (a transom bar in front) is no sill.
        assert_eq!(window_faces(&window_over_a_sill(-0.06, 10.9), Vec3::new(1.7, -12.0, 1.5)).0, 0);
        // A sill more than `occlusion_reach_m` below.
        assert_eq!(window_faces(&window_over_a_sill(-0.06, 9.2), Vec3::new(1.7, -12.0, 1.5)).0, 0);
    }
}
