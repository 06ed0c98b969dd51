//! A wall's own coordinates (along, up, behind), outlines for containment, rectangles in those coordinates,
//! and the corners of an opening placed back along the line of sight.
use super::*;
use lineflow_photogrammetry::weighted_quantile;

/// Half the window over which the wall's face gathers its edges, metres: under half the shallowest reveal told
/// apart from the face (1.4 cm), wide enough for the edges' depth noise at full size (1 GSD is 7 mm).
const FACE_BANDWIDTH_M: f64 = 0.007;
/// Steps up the density at most (each moves to the median within [`FACE_BANDWIDTH_M`]; a few suffice).
const MAX_FACE_STEPS: usize = 20;

/// A wall plane with coordinates along it (`x`), up (`z`) and behind it (`depth`, along −`out`).
#[derive(Debug, Clone, Copy)]
pub(crate) struct Wall {
    pub(crate) plane: Plane,
    /// Outward unit normal (towards the cameras).
    pub(crate) out: Vec3,
    /// Horizontal unit vector in the wall.
    pub(crate) across: Vec3,
}

impl Wall {
    /// The plane as a wall seen from `viewpoint`; none when the viewpoint lies in it.
    pub(crate) fn facing(plane: Plane, viewpoint: &Vec3) -> Option<Wall> {
        let side = plane.normal.dot(viewpoint) - plane.offset;
        if side.abs() < 1e-9 {
            return None;
        }
        let out = plane.normal * side.signum();
        let across = Vec3::z().cross(&out).try_normalize(1e-9)?;
        Some(Wall { plane, out, across })
    }

    /// The wall moved along its normal onto its face: the densest depth of the observed edges parallel to it within
    /// `reach` of it, climbed to from the front quarter of their length. The plane of the faces is fitted to
    /// corners, which noise and the frames a few centimetres behind pull off the wall by up to a few centimetres.
    /// The median of the edges is no better where the wall itself shows few lines (plaster): the frames and panes
    /// of nearly flush windows, 1 to 4 cm behind, then outweigh it, the median lands among them and every opening
    /// comes out on its frame with no reveal. The face is the front of the edges' depths, and a peak of them.
    pub(super) fn settled(mut self, observed: [(&[Vertex], &[Edge]); 2], reach: f64) -> Wall {
        let mut depths: Vec<(f64, f64)> = [true, false]
            .into_iter()
            .flat_map(|upright| observed.map(|(vertices, edges)| pieces(&self, vertices, edges, upright, (-reach, reach))))
            .flatten()
            .map(|(_, depth, a, b, _)| (depth, b - a))
            .collect();
        depths.sort_by(|a, b| a.0.total_cmp(&b.0));
        // From the front quarter up the density to its peak: the wall's face, not the frames behind it.
        let Some(mut face) = weighted_quantile(&depths, 0.25) else {
            return self;
        };
        for _ in 0..MAX_FACE_STEPS {
            let near: Vec<(f64, f64)> = depths.iter().copied().filter(|d| (d.0 - face).abs() <= FACE_BANDWIDTH_M).collect();
            match weighted_quantile(&near, 0.5) {
                Some(next) if (next - face).abs() > 1e-6 => face = next,
                _ => break,
            }
        }
        self.plane.offset -= face * self.plane.normal.dot(&self.out);
        self
    }

    /// How far behind the wall `p` lies (negative in front).
    pub(crate) fn depth(&self, p: &Vec3) -> f64 {
        (self.plane.offset - self.plane.normal.dot(p)) / self.plane.normal.dot(&self.out)
    }

    /// The point of the wall plane at `x` along it and height `z`.
    pub(super) fn point(&self, x: f64, z: f64, near: &Vec3) -> Vec3 {
        let base = near - self.across * near.dot(&self.across);
        let p = Vec3::new(base.x, base.y, z) + self.across * x;
        p + self.out * self.depth(&p)
    }
}

/// A wall with the observed edges behind it and on it gathered into sides.
pub(crate) struct WallView {
    pub(crate) wall: Wall,
    pub(super) standing: Vec<Side>,
    pub(super) lying: Vec<Side>,
    /// The standing and lying sides on the wall itself: an opening's own edges.
    pub(super) standing_on_wall: Vec<Side>,
    pub(super) lying_on_wall: Vec<Side>,
    /// The lying edges on the wall one by one: courses of brick or tiles run across the wall and stop at its
    /// openings ([`WallView::courses_within`]).
    pub(super) lying_pieces_on_wall: Vec<Piece>,
    /// The standing edges on the wall one by one: at a nearly flush opening's side, the reveal's two corners, on
    /// the wall's face and on the frame ([`super::frames::flush_frame_depth`]).
    pub(super) standing_pieces_on_wall: Vec<Piece>,
    pub(super) sizes: OpeningSizes,
}

impl WallView {
    /// How many distinct heights (`margin` apart) the lying edges on the wall inside the rectangle
    /// `[x0, x1, z0, z1]` take, more than `margin` from its sides: a frame's rails and panes take a few, the courses
    /// of the wall between two openings many.
    pub(super) fn courses_within(&self, [x0, x1, z0, z1]: [f64; 4], margin: f64) -> usize {
        let mut heights: Vec<f64> = self
            .lying_pieces_on_wall
            .iter()
            .filter(|&&(z, _, a, b, _)| z > z0 + margin && z < z1 - margin && a >= x0 - margin && b <= x1 + margin)
            .map(|p| p.0)
            .collect();
        heights.sort_by(f64::total_cmp);
        heights.windows(2).filter(|w| w[1] - w[0] > margin).count() + usize::from(!heights.is_empty())
    }
}

/// A ring flattened in its plane, for containment tests.
#[derive(Clone)]
pub(crate) struct Outline {
    pub(super) points: Vec<Vec3>,
    pub(super) normal: Vec3,
    pub(super) centroid: Vec3,
    pub(super) basis: (Vec3, Vec3),
    pub(super) polygon: Vec<[f64; 2]>,
    pub(super) area: f64,
}

impl Outline {
    pub(crate) fn of(points: &[Vec3], normal: Vec3) -> Outline {
        let basis = plane_basis(normal);
        let polygon: Vec<[f64; 2]> = points.iter().map(|p| [p.dot(&basis.0), p.dot(&basis.1)]).collect();
        Outline {
            points: points.to_vec(),
            normal,
            centroid: points.iter().sum::<Vec3>() / points.len().max(1) as f64,
            basis,
            area: signed_area(&polygon).abs(),
            polygon,
        }
    }

    /// The outline of every face, in order.
    pub(crate) fn of_faces(faces: &[Face], vertices: &[Vertex]) -> Vec<Outline> {
        faces
            .iter()
            .map(|f| Outline::of(&f.ring.iter().map(|&k| vertices[k].point).collect::<Vec<_>>(), f.normal))
            .collect()
    }

    /// Whether the ring lies on `wall`: its normal within `cos_par` of the wall's, its centroid within `within_m`
    /// of the wall's plane.
    pub(super) fn on(&self, wall: &Wall, cos_par: f64, within_m: f64) -> bool {
        self.normal.dot(&wall.out).abs() > cos_par && wall.depth(&self.centroid).abs() < within_m
    }

    /// The ring's bounds `[x0, x1, z0, z1]` in `wall`'s coordinates.
    pub(crate) fn bounds_in(&self, wall: &Wall) -> [f64; 4] {
        let xs: Vec<f64> = self.points.iter().map(|p| p.dot(&wall.across)).collect();
        let zs: Vec<f64> = self.points.iter().map(|p| p.z).collect();
        [min(&xs), max(&xs), min(&zs), max(&zs)]
    }

    /// Whether `p`, moved along the normal into the ring's plane, lies inside it.
    pub(super) fn contains(&self, p: &Vec3) -> bool {
        point_in_polygon([p.dot(&self.basis.0), p.dot(&self.basis.1)], &self.polygon)
    }
}

/// A rectangle in a wall's coordinates: `bounds` [x0, x1, z0, z1], and which of those four sides lie on the wall
/// itself (the opening's own edge, seen where the frame's edge behind it is hidden) rather than behind it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) struct Rect {
    pub(super) bounds: [f64; 4],
    pub(super) on_wall: [bool; 4],
}

impl Rect {
    pub(super) fn behind(bounds: [f64; 4]) -> Rect {
        Rect {
            bounds,
            on_wall: [false; 4],
        }
    }
}

/// Which sides of the rectangle `[x0, x1, z0, z1]` behind `wall` no camera saw the frame's outer edge of, as
/// [left, right, foot, top]: a camera sees a recessed frame's left outer edge only from the right of it (the
/// reveal hides it from the left), its foot only from above it, and so on.
pub(super) fn hidden_sides(wall: &Wall, [x0, x1, z0, z1]: [f64; 4], centres: &[Vec3]) -> [bool; 4] {
    let all = |seen_from: &dyn Fn(f64, f64) -> bool| !centres.is_empty() && centres.iter().all(|c| seen_from(c.dot(&wall.across), c.z));
    [all(&|x, _| x < x0), all(&|x, _| x > x1), all(&|_, z| z < z0), all(&|_, z| z > z1)]
}

/// The corners on the wall plane of the opening through which the rectangle `rect`, `depth` behind the wall, is
/// seen from the cameras at `centres`. A foot behind the wall that every camera sees from below is where the line
/// of sight over the opening's foot meets the frame: it is moved back along the line of sight of the camera that
/// sees most of it, the highest; a top that every camera sees from above, likewise.
pub(super) fn opening_corners(wall: &Wall, rect: Rect, depth: f64, centres: &[Vec3], sigma: Option<Vec3>, near: &Vec3) -> Vec<Vertex> {
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
    use super::super::tests::{edge, vertex};
    use super::*;

    /// Vertices and edges of level lines from x 0 to `length` at the heights `zs`, `y` metres behind the wall y = 0.
    fn level_lines(y: f64, zs: &[f64], length: f64) -> (Vec<Vertex>, Vec<Edge>) {
        let vertices = zs.iter().flat_map(|&z| [vertex([0.0, y, z]), vertex([length, y, z])]).collect();
        (vertices, (0..zs.len()).map(|k| edge(2 * k, 2 * k + 1)).collect())
    }

    /// Two sets of vertices and edges as one.
    fn joined((mut vertices, mut edges): (Vec<Vertex>, Vec<Edge>), (more_v, more_e): (Vec<Vertex>, Vec<Edge>)) -> (Vec<Vertex>, Vec<Edge>) {
        let n = vertices.len();
        vertices.extend(more_v);
        edges.extend(more_e.iter().map(|e| edge(e.a + n, e.b + n)));
        (vertices, edges)
    }

    /// On a plastered wall, or a brick one whose courses the line stage classed texture, the model's own edges
    /// near the wall are mostly nearly flush frames 2 cm behind it; a median of them settled the wall on the frames
    /// and every reveal came out 2 cm short. The face is in front of them, and the courses, where given, agree.
    #[test]
    fn the_wall_settles_on_its_face_not_on_its_frames() {
        let plane = Plane {
            normal: Vec3::y(),
            offset: 0.01,
        };
        let wall = Wall::facing(plane, &Vec3::new(3.0, -19.0, 1.6)).unwrap();
        let (outline_v, outline_e) = level_lines(0.0, &[0.0, 6.0], 8.0);
        let (frames_v, frames_e) = level_lines(0.02, &[1.0, 1.5, 2.5, 3.0, 4.0, 4.5], 8.0);
        let (vertices, edges) = joined((outline_v, outline_e), (frames_v, frames_e));
        let none: (&[Vertex], &[Edge]) = (&[], &[]);
        let on_frames = wall.settled([(&vertices, &edges), none], 0.06);
        assert!(
            on_frames.depth(&Vec3::zeros()).abs() < 1e-9,
            "the frames outweigh the face: {}",
            on_frames.plane.offset
        );
        let (with_sills, sills) = joined((vertices.clone(), edges.clone()), level_lines(-0.05, &[0.9, 2.4], 1.0));
        let past_sills = wall.settled([(&with_sills, &sills), none], 0.06);
        assert!(
            past_sills.depth(&Vec3::zeros()).abs() < 1e-9,
            "sill noses in front: {}",
            past_sills.plane.offset
        );
        let zs: Vec<f64> = (0..60).map(|k| 0.05 + 0.1 * k as f64).collect();
        let (courses_v, courses_e) = level_lines(0.0, &zs, 8.0);
        let on_face = wall.settled([(&vertices, &edges), (&courses_v, &courses_e)], 0.06);
        assert!(
            on_face.depth(&Vec3::zeros()).abs() < 1e-9,
            "with the courses: {}",
            on_face.plane.offset
        );
    }
}
