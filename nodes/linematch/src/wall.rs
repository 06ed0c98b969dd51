//! Wall planes: the approximate building model the matching searches around (`site.toml`), or a plane fitted to
//! tie points when there is none.
use lineflow_photogrammetry::ransac::{best_of_samples, Sampling};
use lineflow_photogrammetry::{point_in_polygon, polygon_normal, Vec3};

/// A planar wall polygon with its outward normal and an in-plane frame (u horizontal, w up).
#[derive(Debug, Clone, PartialEq)]
pub struct WallPlane {
    /// Name from `site.toml` (or `fitted`).
    pub name: String,
    /// Outward unit normal n̂.
    pub normal: Vec3,
    /// n̂·X of the plane.
    pub offset: f64,
    /// A point of the plane (the polygon's first corner).
    pub origin: Vec3,
    /// In-plane horizontal unit axis.
    pub u: Vec3,
    /// In-plane unit axis pointing up (w·ẑ ≥ 0).
    pub w: Vec3,
    /// The polygon in (u, w) coordinates relative to `origin`; empty means unbounded.
    pub polygon: Vec<[f64; 2]>,
}

impl WallPlane {
    /// The wall of a polygon listed counter-clockwise as seen from outside (`conventions.md`): the right-hand rule
    /// gives the outward normal. `None` for fewer than three corners or a degenerate polygon.
    pub fn from_corners(name: &str, corners: &[Vec3]) -> Option<Self> {
        if corners.len() < 3 {
            return None;
        }
        let normal = polygon_normal(corners)?;
        let mut wall = Self::from_plane(name, normal, corners[0]);
        wall.polygon = corners.iter().map(|c| wall.in_plane(c)).collect();
        Some(wall)
    }

    /// An unbounded wall through `point` with outward normal `normal` (unit).
    pub fn from_plane(name: &str, normal: Vec3, point: Vec3) -> Self {
        let z = Vec3::z();
        let u = z.cross(&normal).try_normalize(1e-9).unwrap_or_else(Vec3::x);
        let mut w = normal.cross(&u);
        if w.z < 0.0 {
            w = -w;
        }
        WallPlane {
            name: name.to_owned(),
            normal,
            offset: normal.dot(&point),
            origin: point,
            u,
            w,
            polygon: Vec::new(),
        }
    }

    /// (u, w) coordinates of a point's projection onto the plane.
    pub fn in_plane(&self, p: &Vec3) -> [f64; 2] {
        let d = p - self.origin;
        [d.dot(&self.u), d.dot(&self.w)]
    }

    /// Signed distance of a point in front of the wall (outward positive).
    pub fn depth_of(&self, p: &Vec3) -> f64 {
        self.normal.dot(p) - self.offset
    }

    /// The ray parameter where `center + s·ray` meets the plane offset by `depth` along the normal (eq. 14).
    pub fn ray_parameter(&self, center: &Vec3, ray: &Vec3, depth: f64) -> Option<f64> {
        let denom = self.normal.dot(ray);
        (denom.abs() > 1e-12).then(|| (self.offset + depth - self.normal.dot(center)) / denom)
    }

    /// Whether the point's projection lies inside the polygon grown by `margin` metres (always for unbounded walls).
    pub fn contains(&self, p: &Vec3, margin: f64) -> bool {
        if self.polygon.is_empty() {
            return true;
        }
        let q = self.in_plane(p);
        point_in_polygon(q, &self.polygon) || polygon_distance(q, &self.polygon) <= margin
    }
}

fn polygon_distance(q: [f64; 2], poly: &[[f64; 2]]) -> f64 {
    let mut best = f64::INFINITY;
    for (k, a) in poly.iter().enumerate() {
        let b = poly[(k + 1) % poly.len()];
        let (dx, dy) = (b[0] - a[0], b[1] - a[1]);
        let len2 = dx * dx + dy * dy;
        let t = if len2 > 0.0 {
            (((q[0] - a[0]) * dx + (q[1] - a[1]) * dy) / len2).clamp(0.0, 1.0)
        } else {
            0.0
        };
        best = best.min((q[0] - a[0] - t * dx).hypot(q[1] - a[1] - t * dy));
    }
    best
}

/// The wall a viewing ray belongs to (the thesis's visibility test, eq. 13, with Mᵀ): among the walls whose front
/// the ray sees (θ > 90°) and whose polygon, grown by `margin`, it hits, the nearest.
pub fn wall_of_ray(walls: &[WallPlane], center: &Vec3, ray: &Vec3, margin: f64) -> Option<usize> {
    walls
        .iter()
        .enumerate()
        .filter(|(_, w)| w.normal.dot(ray) < 0.0)
        .filter_map(|(k, w)| {
            let s = w.ray_parameter(center, ray, 0.0)?;
            (s > 0.0 && w.contains(&(center + s * ray), margin)).then_some((k, s))
        })
        .min_by(|a, b| a.1.total_cmp(&b.1))
        .map(|(k, _)| k)
}

/// A wall fitted to object points (tie points) by RANSAC and a least-squares refit of the inliers, with its normal
/// turned towards `viewpoint` (a camera centre). `None` when fewer than `min_inliers` points lie within `tolerance`
/// metres of any plane.
pub fn fit_wall(points: &[Vec3], viewpoint: &Vec3, tolerance: f64, min_inliers: usize) -> Option<WallPlane> {
    if points.len() < 3 || points.len() < min_inliers {
        return None;
    }
    let on_plane = |(n, a): &(Vec3, Vec3)| points.iter().filter(|p| n.dot(&(*p - a)).abs() <= tolerance).count();
    let through = |s: &[usize]| {
        let (a, b, c) = (points[s[0]], points[s[1]], points[s[2]]);
        (b - a).cross(&(c - a)).try_normalize(1e-9).map(|n| (n, a))
    };
    let sampling = Sampling {
        iterations: 500,
        seed: 0x9E37_79B9_7F4A_7C15,
    };
    let ((n, a), count) = best_of_samples(points.len(), 3, sampling, through, on_plane)?;
    if count < min_inliers {
        return None;
    }
    let inliers: Vec<Vec3> = points.iter().filter(|p| n.dot(&(*p - a)).abs() <= tolerance).copied().collect();
    let (centroid, normal) = plane_of(&inliers)?;
    let normal = if normal.dot(&(viewpoint - centroid)) < 0.0 {
        -normal
    } else {
        normal
    };
    Some(WallPlane::from_plane("fitted", normal, centroid))
}

/// Tie points within this distance of a fitted wall's plane count as on it, metres.
pub const WALL_TOLERANCE_M: f64 = 0.05;
/// A fitted wall needs at least this many tie points on it (or a tenth of those left, if more).
pub const WALL_MIN_POINTS: usize = 50;

/// No wall plane among the intersected tie points.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct NoWall {
    /// How many tie points there were.
    pub intersected: usize,
}

impl std::fmt::Display for NoWall {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "no site model, and no wall plane among the {} tie points intersected so far (a wall needs {WALL_MIN_POINTS} \
             within {:.0} cm of a plane)",
            self.intersected,
            WALL_TOLERANCE_M * 100.0
        )
    }
}

/// The walls of a scene without a site model: up to four planes, each fitted ([`fit_wall`]) to the intersected tie
/// points the previous ones left, normals towards `viewpoint`.
pub fn fit_walls(points: &[Vec3], viewpoint: &Vec3) -> Result<Vec<WallPlane>, NoWall> {
    let mut left = points.to_vec();
    let mut walls = Vec::new();
    while walls.len() < 4 {
        let Some(w) = fit_wall(&left, viewpoint, WALL_TOLERANCE_M, WALL_MIN_POINTS.max(left.len() / 10)) else {
            break;
        };
        left.retain(|p| w.depth_of(p).abs() > WALL_TOLERANCE_M);
        walls.push(w);
    }
    if walls.is_empty() {
        Err(NoWall { intersected: points.len() })
    } else {
        Ok(walls)
    }
}

/// Least-squares plane: centroid and the unit normal (smallest principal axis).
fn plane_of(points: &[Vec3]) -> Option<(Vec3, Vec3)> {
    let c = points.iter().sum::<Vec3>() / points.len() as f64;
    let mut cov = lineflow_photogrammetry::Mat3::zeros();
    for p in points {
        let d = p - c;
        cov += d * d.transpose();
    }
    let eig = cov.symmetric_eigen();
    let k = eig.eigenvalues.imin();
    Some((c, eig.eigenvectors.column(k).into_owned().try_normalize(1e-12)?))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn south() -> WallPlane {
        // Counter-clockwise seen from outside (from −Y looking +Y): the normal is −Y.
        let c = [[0.0, 0.0, 0.0], [30.0, 0.0, 0.0], [30.0, 0.0, 20.0], [0.0, 0.0, 20.0]].map(Vec3::from);
        WallPlane::from_corners("south", &c).unwrap()
    }

    #[test]
    fn the_conventions_example_faces_the_street() {
        let w = south();
        assert!((w.normal - Vec3::new(0.0, -1.0, 0.0)).norm() < 1e-12);
        assert!(w.w.z > 0.99 && w.u.z.abs() < 1e-12);
        assert!((w.depth_of(&Vec3::new(5.0, -2.0, 3.0)) - 2.0).abs() < 1e-12);
    }

    #[test]
    fn a_ray_meets_the_offset_plane_at_the_requested_depth() {
        let w = south();
        let (c, r) = (Vec3::new(3.0, -20.0, 1.6), Vec3::new(0.1, 1.0, 0.05).normalize());
        for depth in [-1.0, 0.0, 0.37] {
            let s = w.ray_parameter(&c, &r, depth).unwrap();
            assert!((w.depth_of(&(c + s * r)) - depth).abs() < 1e-12);
        }
        assert_eq!(wall_of_ray(std::slice::from_ref(&w), &c, &r, 0.0), Some(0));
        // From behind the wall it is not visible.
        assert_eq!(wall_of_ray(std::slice::from_ref(&w), &Vec3::new(3.0, 20.0, 1.6), &-r, 0.0), None);
        // Outside the polygon (beyond the margin) no wall.
        assert_eq!(wall_of_ray(&[w], &Vec3::new(-10.0, -20.0, 1.6), &Vec3::y(), 0.5), None);
    }

    #[test]
    fn a_plane_is_recovered_from_noisy_points_with_outliers() {
        let mut pts = Vec::new();
        for i in 0..20 {
            for j in 0..10 {
                let noise = 0.002 * (((i * 7 + j * 13) % 11) as f64 / 10.0 - 0.5);
                pts.push(Vec3::new(i as f64 * 0.5, noise, j as f64 * 0.4));
            }
        }
        for k in 0..60 {
            pts.push(Vec3::new(k as f64 * 0.1, -1.0 - (k % 5) as f64, 2.0));
        }
        let w = fit_wall(&pts, &Vec3::new(5.0, -20.0, 1.6), 0.01, 50).unwrap();
        assert!(w.normal.dot(&Vec3::new(0.0, -1.0, 0.0)) > 0.9999, "{:?}", w.normal);
        assert!(w.depth_of(&Vec3::new(3.0, 0.0, 1.0)).abs() < 0.002);
    }

    #[test]
    fn two_walls_are_found_and_too_few_points_are_named() {
        // A corner of two walls, 120 points each, seen from the street.
        let mut pts = Vec::new();
        for i in 0..12 {
            for j in 0..10 {
                let (s, z) = (i as f64 * 0.8, j as f64 * 0.5);
                pts.push(Vec3::new(s, 0.0, z));
                pts.push(Vec3::new(0.0, -0.5 - s, z));
            }
        }
        let walls = fit_walls(&pts, &Vec3::new(10.0, -20.0, 1.6)).unwrap();
        assert_eq!(walls.len(), 2);
        let normals: Vec<Vec3> = walls.iter().map(|w| w.normal).collect();
        assert!(normals.iter().any(|n| n.dot(&-Vec3::y()) > 0.999), "{normals:?}");
        assert!(normals.iter().any(|n| n.dot(&Vec3::x()) > 0.999), "{normals:?}");

        let e = fit_walls(&pts[..30], &Vec3::new(10.0, -20.0, 1.6)).unwrap_err();
        assert_eq!(e.intersected, 30);
        assert!(e.to_string().contains("among the 30 tie points"), "{e}");
        assert!(fit_walls(&[], &Vec3::zeros()).is_err());
    }
}
