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
use crate::{Cameras, Edge, ModelParams, Vertex};

/// How far behind its wall a recessed face may lie to make an opening in it, metres: from a glazing bar's 4 cm (a
/// pane inside its frame, not an opening in the wall) up to half a metre.
const RECESS_M: (f64, f64) = (0.06, 0.5);
/// The smallest opening inferred from what is behind it, metres: smaller, the panes of a frame would pass for
/// openings wherever the frame itself was not found.
const MIN_OPENING_M: f64 = 0.8;
/// The largest, metres.
const MAX_OPENING_M: f64 = 4.0;
/// A frame's outer edges lie this far outside its glazing, metres…
const FRAME_M: (f64, f64) = (0.02, 0.15);
/// …and run along at least this share of the glazing's height.
const MIN_OUTER_COVER: f64 = 0.8;
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

/// What the inference does to the faces.
pub(crate) enum Inferred {
    /// A face in the wall plane is the opening.
    Mark(usize),
    /// A new opening face on these new corners, with this outward normal.
    New(Vec<Vertex>, Vec3),
}

/// A wall plane with coordinates along it (`x`), up (`z`) and behind it (`depth`, along −`out`).
struct Wall {
    plane: Plane,
    /// Outward unit normal (towards the cameras).
    out: Vec3,
    /// Horizontal unit vector in the wall.
    across: Vec3,
}

impl Wall {
    /// The plane as a wall seen from `viewpoint`; none when the viewpoint lies in it.
    fn facing(plane: Plane, viewpoint: &Vec3) -> Option<Wall> {
        let side = plane.normal.dot(viewpoint) - plane.offset;
        if side.abs() < 1e-9 {
            return None;
        }
        let out = plane.normal * side.signum();
        let across = Vec3::z().cross(&out).try_normalize(1e-9)?;
        Some(Wall { plane, out, across })
    }

    /// How far behind the wall `p` lies (negative in front).
    fn depth(&self, p: &Vec3) -> f64 {
        (self.plane.offset - self.plane.normal.dot(p)) / self.plane.normal.dot(&self.out)
    }

    /// The point of the wall plane at `x` along it and height `z`.
    fn point(&self, x: f64, z: f64, near: &Vec3) -> Vec3 {
        let base = near - self.across * near.dot(&self.across);
        let p = Vec3::new(base.x, base.y, z) + self.across * x;
        p + self.out * self.depth(&p)
    }
}

/// A wall with the observed edges behind it and on it gathered into sides.
struct WallView {
    wall: Wall,
    standing: Vec<Side>,
    lying: Vec<Side>,
    /// The standing and lying sides on the wall itself: an opening's own edges.
    standing_on_wall: Vec<Side>,
    lying_on_wall: Vec<Side>,
}

/// A ring flattened in its plane, for containment tests.
#[derive(Clone)]
struct Outline {
    normal: Vec3,
    centroid: Vec3,
    basis: (Vec3, Vec3),
    polygon: Vec<[f64; 2]>,
    area: f64,
}

impl Outline {
    fn of(points: &[Vec3], normal: Vec3) -> Outline {
        let basis = plane_basis(normal);
        let polygon: Vec<[f64; 2]> = points.iter().map(|p| [p.dot(&basis.0), p.dot(&basis.1)]).collect();
        Outline {
            normal,
            centroid: points.iter().sum::<Vec3>() / points.len().max(1) as f64,
            basis,
            area: signed_area(&polygon).abs(),
            polygon,
        }
    }

    /// Whether `p`, moved along the normal into the ring's plane, lies inside it.
    fn contains(&self, p: &Vec3) -> bool {
        point_in_polygon([p.dot(&self.basis.0), p.dot(&self.basis.1)], &self.polygon)
    }
}

/// A rectangle in a wall's coordinates: `bounds` [x0, x1, z0, z1], and which of those four sides lie on the wall
/// itself (the opening's own edge, seen where the frame's edge behind it is hidden) rather than behind it.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Rect {
    bounds: [f64; 4],
    on_wall: [bool; 4],
}

impl Rect {
    fn behind(bounds: [f64; 4]) -> Rect {
        Rect {
            bounds,
            on_wall: [false; 4],
        }
    }
}

/// A rectangle behind a wall proposed as an opening, its depth behind the wall and the σ of its corners.
struct Proposal {
    wall: usize,
    rect: Rect,
    depth: f64,
    sigma: Option<Vec3>,
}

/// Openings inferred from recessed faces and from rectangles of recessed edges, for a model seen from `cameras`.
/// `edges` are those the faces were traced on, `plane_edges` those lying in each plane.
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
) -> Vec<Inferred> {
    let Some(viewpoint) = cameras.mean() else {
        return Vec::new();
    };
    let centres = cameras.centres();
    let cos_par = params.plane_angle_deg.to_radians().cos();
    let ring = |r: &[usize]| r.iter().map(|&k| vertices[k].point).collect::<Vec<_>>();
    let outlines: Vec<Outline> = faces.iter().map(|f| Outline::of(&ring(&f.ring), f.normal)).collect();
    let walls = walls(vertices, edges, planes, plane_edges, cos_par, &viewpoint);
    // Recessed faces first, then rectangles; each only where no opening is on the wall there yet.
    let mut proposals = from_recesses(vertices, faces, &outlines, &walls, cos_par, centres);
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
    let mut out = Vec::new();
    for p in proposals {
        let wall = &walls[p.wall].wall;
        let [x0, x1, z0, z1] = p.rect.bounds;
        let centre = wall.point((x0 + x1) / 2.0, (z0 + z1) / 2.0, &viewpoint);
        let on_wall_here =
            |o: &Outline| o.normal.dot(&wall.out).abs() > cos_par && wall.depth(&o.centroid).abs() < RECESS_M.0 && o.contains(&centre);
        if found.iter().any(on_wall_here) {
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
                let corners = opening_corners(wall, p.rect, p.depth, centres, p.sigma, &centre);
                found.push(Outline::of(&corners.iter().map(|v| v.point).collect::<Vec<_>>(), wall.out));
                out.push(Inferred::New(corners, wall.out));
            }
        }
    }
    out
}

/// Adds the inferred openings to the model: marked faces become windows, new ones get their corners, their
/// outline as completed edges and a window face (`nest_openings` then cuts them into their walls and tells doors).
pub(crate) fn add(inferred: Vec<Inferred>, vertices: &mut Vec<Vertex>, edges: &mut Vec<Edge>, faces: &mut Vec<Face>) {
    for opening in inferred {
        match opening {
            Inferred::Mark(j) => faces[j].kind = SurfaceKind::Window,
            Inferred::New(corners, normal) => {
                let first = vertices.len();
                vertices.extend(corners);
                let ring: Vec<usize> = (first..vertices.len()).collect();
                edges.extend(ring.iter().enumerate().map(|(k, &a)| Edge {
                    a,
                    b: ring[(k + 1) % ring.len()],
                    line: usize::MAX,
                    completed: true,
                }));
                faces.push(Face {
                    ring,
                    holes: Vec::new(),
                    normal,
                    kind: SurfaceKind::Window,
                });
            }
        }
    }
}

/// The walls, most edges first: vertical planes whose edges (at least [`MIN_WALL_EDGES`]) spread
/// [`MIN_WALL_SPAN_M`] across and up and outnumber those of every parallel plane within [`RECESS_M`] of them (a row
/// of sill fronts, the reveals of a column of windows or a frame's own plane are no wall), each with the observed
/// edges behind it gathered into sides.
fn walls(
    vertices: &[Vertex],
    edges: &[Edge],
    planes: &[Plane],
    plane_edges: &[Vec<&Edge>],
    cos_par: f64,
    viewpoint: &Vec3,
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
    let parallel_near = |a: &Plane, b: &Plane| {
        let along = a.normal.dot(&b.normal);
        along.abs() > cos_par && (a.offset - b.offset * along.signum()).abs() <= RECESS_M.1
    };
    let mut chosen: Vec<(usize, usize)> = (0..planes.len())
        .filter(|&k| {
            let (p, n) = (&planes[k], plane_edges[k].len());
            n >= MIN_WALL_EDGES
                && p.normal.z.abs() < 0.2
                // Of two hypotheses that converged on one plane (as many edges), the first stands for both.
                && (0..planes.len()).all(|j| {
                    j == k || !parallel_near(p, &planes[j]) || plane_edges[j].len() < n || (plane_edges[j].len() == n && j > k)
                })
                && spread(p, &plane_edges[k])
        })
        .map(|k| (plane_edges[k].len(), k))
        .collect();
    chosen.sort_by(|a, b| b.0.cmp(&a.0).then(a.1.cmp(&b.1)));
    chosen
        .into_iter()
        .filter_map(|(_, k)| {
            let wall = Wall::facing(planes[k], viewpoint)?;
            let on_wall = (-DEPTH_TOLERANCE_M, DEPTH_TOLERANCE_M);
            Some(WallView {
                standing: sides(&wall, vertices, edges, true, RECESS_M),
                lying: sides(&wall, vertices, edges, false, RECESS_M),
                standing_on_wall: sides(&wall, vertices, edges, true, on_wall),
                lying_on_wall: sides(&wall, vertices, edges, false, on_wall),
                wall,
            })
        })
        .collect()
}

/// A vertical wall-kind face at least [`MIN_OPENING_M`] across, nearly a rectangle, parallel to a wall and
/// [`RECESS_M`] behind it, is what one sees through an opening: its bounding rectangle, widened to the frame
/// ([`widened_to_frame`]). Largest first, so that a frame comes before its panes.
fn from_recesses(
    vertices: &[Vertex],
    faces: &[Face],
    outlines: &[Outline],
    walls: &[WallView],
    cos_par: f64,
    centres: &[Vec3],
) -> Vec<Proposal> {
    let mut order: Vec<usize> = (0..faces.len()).collect();
    order.sort_by(|&a, &b| outlines[b].area.total_cmp(&outlines[a].area).then(a.cmp(&b)));
    order
        .into_iter()
        .filter(|&i| {
            let f = &faces[i];
            f.kind == SurfaceKind::Wall && f.normal.z.abs() < 0.2 && smaller_side(vertices, &f.ring, f.normal) >= MIN_OPENING_M
        })
        .filter_map(|i| {
            let (f, c) = (&faces[i], outlines[i].centroid);
            let k = walls
                .iter()
                .position(|w| w.wall.out.dot(&f.normal) > cos_par && (RECESS_M.0..=RECESS_M.1).contains(&w.wall.depth(&c)))?;
            let wall = &walls[k].wall;
            let (xs, zs): (Vec<f64>, Vec<f64>) = f
                .ring
                .iter()
                .map(|&w| (vertices[w].point.dot(&wall.across), vertices[w].point.z))
                .unzip();
            let rect = Rect::behind([min(&xs), max(&xs), min(&zs), max(&zs)]);
            let [x0, x1, z0, z1] = rect.bounds;
            // Only a rectangle is carried over as its box.
            if outlines[i].area < 0.8 * (x1 - x0) * (z1 - z0) {
                return None;
            }
            let depth = wall.depth(&c);
            Some(Proposal {
                wall: k,
                rect: widened_to_frame(rect, depth, &walls[k], centres).unwrap_or(rect),
                depth,
                sigma: f.ring.iter().find_map(|&w| vertices[w].sigma),
            })
        })
        .collect()
}

fn min(v: &[f64]) -> f64 {
    v.iter().copied().fold(f64::INFINITY, f64::min)
}

fn max(v: &[f64]) -> f64 {
    v.iter().copied().fold(f64::NEG_INFINITY, f64::max)
}

/// A side of a candidate rectangle: edges behind the wall along one direction, gathered at one position across
/// it and one depth.
#[derive(Debug, Clone)]
struct Side {
    /// Position across the direction (x of a standing side, z of a lying one), length-weighted.
    at: f64,
    depth: f64,
    /// Intervals covered along the direction.
    spans: Vec<(f64, f64)>,
    /// The σ of a vertex of one of its edges.
    sigma: Option<Vec3>,
}

impl Side {
    fn extent(&self) -> (f64, f64) {
        self.spans
            .iter()
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), s| (lo.min(s.0), hi.max(s.1)))
    }

    /// Share of [lo, hi] its spans cover.
    fn cover(&self, lo: f64, hi: f64) -> f64 {
        let mut spans: Vec<(f64, f64)> = self
            .spans
            .iter()
            .map(|&(a, b)| (a.max(lo), b.min(hi)))
            .filter(|(a, b)| b > a)
            .collect();
        spans.sort_by(|a, b| a.0.total_cmp(&b.0));
        let (mut covered, mut end) = (0.0, lo);
        for (a, b) in spans {
            let a = a.max(end);
            if b > a {
                covered += b - a;
                end = b;
            }
        }
        covered / (hi - lo).max(1e-9)
    }
}

/// The observed edges parallel to `wall` with both ends `depths` behind it, standing (`upright`) or lying,
/// gathered into sides. Completed edges are left out: they run along occluders, not along what was seen.
fn sides(wall: &Wall, vertices: &[Vertex], edges: &[Edge], upright: bool, depths: (f64, f64)) -> Vec<Side> {
    let mut pieces: Vec<(f64, f64, f64, f64, Option<Vec3>)> = edges
        .iter()
        .filter(|e| !e.completed)
        .filter_map(|e| {
            let (p, q) = (vertices[e.a].point, vertices[e.b].point);
            let d = q - p;
            let len = d.norm();
            let (dp, dq) = (wall.depth(&p), wall.depth(&q));
            let within = |x: f64| (depths.0..=depths.1).contains(&x);
            if len < 0.05 || !within(dp) || !within(dq) || (dp - dq).abs() > DEPTH_TOLERANCE_M {
                return None;
            }
            let along = if upright { d.z.abs() } else { d.dot(&wall.across).abs() };
            if along < len * 5f64.to_radians().cos() {
                return None;
            }
            let (cross, a, b) = if upright {
                ((p.dot(&wall.across) + q.dot(&wall.across)) / 2.0, p.z.min(q.z), p.z.max(q.z))
            } else {
                let (s, t) = (p.dot(&wall.across), q.dot(&wall.across));
                ((p.z + q.z) / 2.0, s.min(t), s.max(t))
            };
            Some((cross, (dp + dq) / 2.0, a, b, vertices[e.a].sigma.or(vertices[e.b].sigma)))
        })
        .collect();
    pieces.sort_by(|x, y| x.0.total_cmp(&y.0).then(x.1.total_cmp(&y.1)).then(x.2.total_cmp(&y.2)));
    // Greedy gathering in order across: a piece joins the first side within the tolerances.
    let mut out: Vec<(Side, f64)> = Vec::new();
    for (cross, depth, a, b, sigma) in pieces {
        let w = b - a;
        match out
            .iter_mut()
            .rev()
            .take_while(|(s, _)| cross - s.at <= 2.0 * SIDE_TOLERANCE_M)
            .find(|(s, _)| (cross - s.at).abs() <= SIDE_TOLERANCE_M && (depth - s.depth).abs() <= DEPTH_TOLERANCE_M)
        {
            Some((side, weight)) => {
                side.at = (side.at * *weight + cross * w) / (*weight + w);
                side.depth = (side.depth * *weight + depth * w) / (*weight + w);
                side.spans.push((a, b));
                *weight += w;
            }
            None => out.push((
                Side {
                    at: cross,
                    depth,
                    spans: vec![(a, b)],
                    sigma,
                },
                w,
            )),
        }
    }
    // A side ends at a gap: the frames of windows stacked one above the other share their sides' line.
    out.into_iter()
        .flat_map(|(mut side, _)| {
            side.spans.sort_by(|a, b| a.0.total_cmp(&b.0));
            let mut runs: Vec<Side> = Vec::new();
            for &(a, b) in &side.spans {
                match runs.last_mut() {
                    Some(run) if a <= run.extent().1 + MAX_SIDE_GAP_M => run.spans.push((a, b)),
                    _ => runs.push(Side {
                        spans: vec![(a, b)],
                        ..side.clone()
                    }),
                }
            }
            runs
        })
        .collect()
}

/// Rectangles of the edges behind a wall: two standing sides [`MIN_OPENING_M`] to [`MAX_OPENING_M`] apart and two
/// lying ones at their ends, at one depth, covered by their edges over [`MIN_STANDING_COVER`] and
/// [`MIN_LYING_COVER`] of their length. Where the frame's edge on one side is hidden (beyond a strip's end the
/// reveal hides the side away from the cameras, and a sill the foot of an opening above them), the opening's own
/// edge on the wall may stand in for it, if at least one standing and one lying side lie behind the wall: brick
/// courses on the wall alone would make openings anywhere. Largest first (of one size, those with fewer sides on the
/// wall); one inside another already taken (the panes of a frame) is left out. Each with its depth and a σ.
fn from_rectangles(view: &WallView, centres: &[Vec3]) -> Vec<(Rect, f64, Option<Vec3>)> {
    let on_wall = |s: &Side| s.depth < RECESS_M.0;
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
                _ => continue,
            };
            if !(MIN_OPENING_M..=MAX_OPENING_M).contains(&width) {
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
                let near =
                    |at: f64| move |s: &&&Side| (s.at - at).abs() <= 3.0 * SIDE_TOLERANCE_M && s.cover(l.at, r.at) >= MIN_LYING_COVER;
                let behind = |s: &&&Side| !on_wall(s) && (s.depth - depth).abs() <= DEPTH_TOLERANCE_M;
                let on = |s: &&&Side| on_wall(s);
                let nearest = |at: f64| move |a: &&&Side, b: &&&Side| (a.at - at).abs().total_cmp(&(b.at - at).abs());
                let (b, w) = (pick(behind_ends), pick(all_ends));
                (lying.iter().filter(near(b)).filter(behind).min_by(nearest(b)))
                    .or_else(|| lying.iter().filter(near(w)).filter(on).min_by(nearest(w)))
            };
            let (Some(top), Some(bottom)) = (end(true), end(false)) else {
                continue;
            };
            let (z0, z1) = (bottom.at, top.at);
            if (on_wall(top) && on_wall(bottom))
                || !(MIN_OPENING_M..=MAX_OPENING_M).contains(&(z1 - z0))
                || l.cover(z0, z1) < MIN_STANDING_COVER
                || r.cover(z0, z1) < MIN_STANDING_COVER
            {
                continue;
            }
            let rect = Rect {
                bounds: [l.at, r.at, z0, z1],
                on_wall: [on_wall(l), on_wall(r), on_wall(bottom), on_wall(top)],
            };
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
    let mut kept: Vec<(Rect, f64, Option<Vec3>)> = Vec::new();
    for (rect, depth, sigma) in found {
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

/// What a standing side of a rectangle is, told by the frame's other standing edge beside it.
enum FrameSide {
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
/// inward for its glazing: standing edges within [`FRAME_M`] of it, at its depth, along [`MIN_OUTER_COVER`] of the
/// rectangle's height `[z0, z1]`, the nearest first.
fn frame_side(at: f64, outward: f64, depth: f64, [z0, z1]: [f64; 2], standing: &[Side]) -> FrameSide {
    let nearest = |direction: f64| {
        standing
            .iter()
            .filter(|s| (s.depth - depth).abs() <= DEPTH_TOLERANCE_M && s.cover(z0, z1) >= MIN_OUTER_COVER)
            .map(|s| (s, (s.at - at) * direction))
            .filter(|(_, d)| (FRAME_M.0..=FRAME_M.1).contains(d))
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
fn widened_to_frame(rect: Rect, depth: f64, view: &WallView, centres: &[Vec3]) -> Option<Rect> {
    use FrameSide::{Glazing, OnWall, Outer, Unknown};
    let [x0, x1, z0, z1] = rect.bounds;
    let hidden = hidden_sides(&view.wall, rect.bounds, centres);
    let side = |k: usize, at: f64, outward: f64| {
        if rect.on_wall[k] {
            OnWall
        } else {
            frame_side(at, outward, depth, [z0, z1], &view.standing)
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
        if let Glazing { outer, .. } = frame_side(at, outward, depth, [l, r], &view.lying) {
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

/// Which sides of the rectangle `[x0, x1, z0, z1]` behind `wall` no camera saw the frame's outer edge of, as
/// [left, right, foot, top]: a camera sees a recessed frame's left outer edge only from the right of it (the
/// reveal hides it from the left), its foot only from above it, and so on.
fn hidden_sides(wall: &Wall, [x0, x1, z0, z1]: [f64; 4], centres: &[Vec3]) -> [bool; 4] {
    let all = |seen_from: &dyn Fn(f64, f64) -> bool| !centres.is_empty() && centres.iter().all(|c| seen_from(c.dot(&wall.across), c.z));
    [all(&|x, _| x < x0), all(&|x, _| x > x1), all(&|_, z| z < z0), all(&|_, z| z > z1)]
}

/// The corners on the wall plane of the opening through which the rectangle `rect`, `depth` behind the wall, is
/// seen from the cameras at `centres`. A foot behind the wall that every camera sees from below is where the line
/// of sight over the opening's foot meets the frame: it is moved back along the line of sight of the camera that
/// sees most of it, the highest; a top that every camera sees from above, likewise.
fn opening_corners(wall: &Wall, rect: Rect, depth: f64, centres: &[Vec3], sigma: Option<Vec3>, near: &Vec3) -> Vec<Vertex> {
    let [x0, x1, mut z0, mut z1] = rect.bounds;
    let hidden = hidden_sides(wall, rect.bounds, centres);
    // A height z on the wall is seen at the recessed depth at cz + (z − cz)·(D + depth)/D, D the wall's distance.
    let seen_on_wall = |z: f64, camera: &Vec3| {
        let distance = -wall.depth(camera);
        if distance > 0.0 {
            camera.z + (z - camera.z) * distance / (distance + depth)
        } else {
            z
        }
    };
    let highest = centres.iter().max_by(|a, b| a.z.total_cmp(&b.z));
    let lowest = centres.iter().min_by(|a, b| a.z.total_cmp(&b.z));
    if let (true, false, Some(camera)) = (hidden[2], rect.on_wall[2], highest) {
        z0 = seen_on_wall(z0, camera);
    }
    if let (true, false, Some(camera)) = (hidden[3], rect.on_wall[3], lowest) {
        z1 = seen_on_wall(z1, camera);
    }
    [(x0, z0), (x1, z0), (x1, z1), (x0, z1)]
        .iter()
        .map(|&(x, z)| Vertex {
            point: wall.point(x, z, near),
            sigma,
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::faces::find;

    /// Brick joints drawn on the wall (a wall carries more edges than anything behind it).
    const JOINTS: usize = 8;
    /// First point of the frame's sides.
    const FRAME: usize = 4 + 2 * JOINTS;

    fn vertex(p: [f64; 3]) -> Vertex {
        Vertex {
            point: Vec3::from(p),
            sigma: Some(Vec3::repeat(0.002)),
        }
    }

    fn edge(a: usize, b: usize) -> Edge {
        Edge {
            a,
            b,
            line: a,
            completed: false,
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
        // Closed, the frame is a recessed face; open at its corners, a rectangle of edges.
        for overshoot in [0.0, 0.03] {
            let (mut vertices, mut edges, viewpoint) = scene(overshoot, false);
            let n = vertices.len();
            let faces = find(&mut vertices, &mut edges, &ModelParams::default(), &viewpoint.into());
            assert_eq!(vertices.len(), n + 4, "overshoot {overshoot}: {faces:?}");
            assert_true_opening(&vertices, &faces, n, &format!("overshoot {overshoot}"));
            // Its outline is completed (not observed) and cut into the wall.
            assert_eq!(edges.iter().filter(|e| e.completed).count(), 4);
            let wall = faces.iter().find(|f| f.ring.contains(&0)).expect("wall");
            assert_eq!((wall.kind, wall.holes.len()), (SurfaceKind::Wall, 1));
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
    fn a_frame_behind_an_outline_that_closed_adds_nothing() {
        for overshoot in [0.0, 0.03] {
            let (mut vertices, mut edges, viewpoint) = scene(overshoot, true);
            let n = vertices.len();
            let faces = find(&mut vertices, &mut edges, &ModelParams::default(), &viewpoint.into());
            assert_eq!(vertices.len(), n, "overshoot {overshoot}");
            let outline = faces
                .iter()
                .find(|f| f.ring.iter().all(|&k| k >= FRAME + 8))
                .expect("the outline's face");
            assert_eq!(outline.kind, SurfaceKind::Window);
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
        let found = walls(&vertices, &edges, &[wall, wall], &[in_wall.clone(), in_wall], cos_par, &viewpoint);
        assert_eq!(found.len(), 1);
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
