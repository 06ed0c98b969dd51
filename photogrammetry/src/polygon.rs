//! Plane polygons: the signed area and the even-odd point test of rings of 2-D points, and the normal of a ring
//! of 3-D points.
use crate::Vec3;

/// The signed area of a ring: positive when it runs counter-clockwise.
pub fn signed_area(p: &[[f64; 2]]) -> f64 {
    let n = p.len();
    (0..n)
        .map(|i| p[i][0] * p[(i + 1) % n][1] - p[(i + 1) % n][0] * p[i][1])
        .sum::<f64>()
        / 2.0
}

/// Whether `q` lies inside the ring `poly` (even-odd rule; a point on the boundary may fall either side).
pub fn point_in_polygon(q: [f64; 2], poly: &[[f64; 2]]) -> bool {
    let mut inside = false;
    let n = poly.len();
    for i in 0..n {
        let (a, b) = (poly[i], poly[(i + 1) % n]);
        if (a[1] > q[1]) != (b[1] > q[1]) && q[0] < a[0] + (q[1] - a[1]) / (b[1] - a[1]) * (b[0] - a[0]) {
            inside = !inside;
        }
    }
    inside
}

/// The unit normal of a ring of 3-D points by Newell's method (robust for non-convex and slightly non-planar rings),
/// if it has an area. It points to where the ring runs counter-clockwise.
pub fn polygon_normal(corners: &[Vec3]) -> Option<Vec3> {
    let mut n = Vec3::zeros();
    for (k, a) in corners.iter().enumerate() {
        let b = corners[(k + 1) % corners.len()];
        n += Vec3::new((a.y - b.y) * (a.z + b.z), (a.z - b.z) * (a.x + b.x), (a.x - b.x) * (a.y + b.y));
    }
    n.try_normalize(1e-12)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_normal_of_a_ring_follows_its_turn_and_ignores_non_convexity() {
        // An L-shaped wall in the plane y = 2, running counter-clockwise seen from -y.
        let ring: Vec<Vec3> = [[0.0, 0.0], [4.0, 0.0], [4.0, 1.0], [1.0, 1.0], [1.0, 3.0], [0.0, 3.0]]
            .iter()
            .map(|&[x, z]| Vec3::new(x, 2.0, z))
            .collect();
        let n = polygon_normal(&ring).unwrap();
        assert!((n - Vec3::new(0.0, -1.0, 0.0)).norm() < 1e-12, "{n}");
        let reversed: Vec<Vec3> = ring.iter().rev().copied().collect();
        assert!((polygon_normal(&reversed).unwrap() + n).norm() < 1e-12);
        let collinear = [Vec3::zeros(), Vec3::x(), Vec3::x() * 2.0];
        assert_eq!(polygon_normal(&collinear), None);
    }

    #[test]
    fn area_and_inside() {
        let square = [[0.0, 0.0], [2.0, 0.0], [2.0, 2.0], [0.0, 2.0]];
        assert_eq!(signed_area(&square), 4.0);
        assert!(point_in_polygon([1.0, 1.0], &square));
        assert!(!point_in_polygon([3.0, 1.0], &square));
    }
}
