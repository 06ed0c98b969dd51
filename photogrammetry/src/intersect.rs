//! Forward intersection of viewing rays, and the 7-parameter similarity between two point sets (the datum
//! transformation into the control frame).
use nalgebra::{Matrix3, SVD};

use crate::{Mat3, Vec3};

/// The point closest, in the least-squares sense, to rays `center + t · direction` (directions need not be unit),
/// with the smallest angle between any two rays, radians. `None` for fewer than two rays or parallel rays.
pub fn intersect_rays(rays: &[(Vec3, Vec3)]) -> Option<(Vec3, f64)> {
    if rays.len() < 2 {
        return None;
    }
    let mut a = Matrix3::zeros();
    let mut b = Vec3::zeros();
    for (c, d) in rays {
        let d = d.normalize();
        // Projector onto the plane normal to the ray: the distance of X from the ray is |P (X − c)|.
        let p = Matrix3::identity() - d * d.transpose();
        a += p;
        b += p * c;
    }
    let x = a.try_inverse()? * b;
    let mut widest = 0.0f64;
    for i in 0..rays.len() {
        for j in i + 1..rays.len() {
            widest = widest.max(rays[i].1.normalize().dot(&rays[j].1.normalize()).clamp(-1.0, 1.0).acos());
        }
    }
    (widest > 1e-6).then_some((x, widest))
}

/// A similarity `y = scale · R · x + t`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Similarity {
    /// Scale.
    pub scale: f64,
    /// Rotation.
    pub rotation: Mat3,
    /// Translation.
    pub translation: Vec3,
}

impl Similarity {
    /// Applies the transformation to a point.
    pub fn apply(&self, x: &Vec3) -> Vec3 {
        self.scale * (self.rotation * x) + self.translation
    }
}

/// The similarity taking `from` onto `to` in the least-squares sense (Umeyama 1991), `None` with fewer than three
/// points or collinear ones.
pub fn similarity(from: &[Vec3], to: &[Vec3]) -> Option<Similarity> {
    let n = from.len();
    if n < 3 || n != to.len() {
        return None;
    }
    let mx = from.iter().sum::<Vec3>() / n as f64;
    let my = to.iter().sum::<Vec3>() / n as f64;
    let mut cov = Matrix3::zeros();
    let mut var = 0.0;
    for (x, y) in from.iter().zip(to) {
        cov += (y - my) * (x - mx).transpose();
        var += (x - mx).norm_squared();
    }
    cov /= n as f64;
    var /= n as f64;
    let svd = SVD::new(cov, true, true);
    let (u, v_t) = (svd.u?, svd.v_t?);
    let s = svd.singular_values;
    // Collinear points leave the rotation about their line undetermined.
    if s[1] <= 1e-12 * s[0].max(1e-300) {
        return None;
    }
    let mut d = Matrix3::identity();
    if (u.determinant() * v_t.determinant()) < 0.0 {
        d[(2, 2)] = -1.0;
    }
    let rotation = u * d * v_t;
    let scale = (s[0] * d[(0, 0)] + s[1] * d[(1, 1)] + s[2] * d[(2, 2)]) / var;
    Some(Similarity {
        scale,
        rotation,
        translation: my - scale * rotation * mx,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::rotation_from_opk;

    #[test]
    fn rays_through_a_point_meet_there() {
        let x = Vec3::new(1.0, 2.0, 3.0);
        let centres = [Vec3::new(0.0, -10.0, 1.0), Vec3::new(2.0, -10.0, 1.5), Vec3::new(4.0, -9.0, 0.0)];
        let rays: Vec<(Vec3, Vec3)> = centres.iter().map(|c| (*c, (x - c) * 3.0)).collect();
        let (p, angle) = intersect_rays(&rays).unwrap();
        assert!((p - x).norm() < 1e-9);
        assert!(angle > 0.1);
        assert!(intersect_rays(&rays[..1]).is_none());
        assert!(
            intersect_rays(&[(centres[0], Vec3::x()), (centres[1], Vec3::x())]).is_none(),
            "parallel rays"
        );
    }

    #[test]
    fn the_similarity_between_two_frames_is_recovered() {
        let r = rotation_from_opk(0.3, -0.2, 1.1);
        let t = Vec3::new(100.0, -5.0, 2.0);
        let from = [
            Vec3::new(0.0, 0.0, 0.0),
            Vec3::new(10.0, 0.0, 0.0),
            Vec3::new(0.0, 0.0, 8.0),
            Vec3::new(5.0, 0.2, 3.0),
        ];
        let to: Vec<Vec3> = from.iter().map(|x| 2.5 * (r * x) + t).collect();
        let s = similarity(&from, &to).unwrap();
        assert!((s.scale - 2.5).abs() < 1e-12);
        assert!((s.rotation - r).norm() < 1e-12);
        assert!(to.iter().zip(&from).all(|(y, x)| (s.apply(x) - y).norm() < 1e-9));
        let line = [Vec3::zeros(), Vec3::x(), 2.0 * Vec3::x()];
        assert!(similarity(&line, &line).is_none(), "collinear points leave a rotation free");
    }
}

/// Forward intersection by least squares on the collinearity equations: the object point minimising the image
/// residuals of its ideal photo coordinates `ideal[i]` (mm) in the cameras `poses[i]`, iterated (Gauss–Newton) from
/// the rays' closest point. `None` for fewer than two views or a point behind a camera.
pub fn intersect_collinearity(focal_mm: f64, poses: &[crate::Pose], ideal: &[[f64; 2]]) -> Option<Vec3> {
    if poses.len() < 2 || poses.len() != ideal.len() {
        return None;
    }
    let rays: Vec<(Vec3, Vec3)> = poses
        .iter()
        .zip(ideal)
        .map(|(p, i)| (p.center, p.rotation.transpose() * Vec3::new(i[0], i[1], -focal_mm)))
        .collect();
    let (mut x, _) = intersect_rays(&rays)?;
    for _ in 0..10 {
        let mut ata = Matrix3::zeros();
        let mut atb = Vec3::zeros();
        for (p, obs) in poses.iter().zip(ideal) {
            let u = p.to_camera(&x);
            if u.z >= 0.0 {
                return None;
            }
            let (fx, fy) = (-focal_mm * u.x / u.z, -focal_mm * u.y / u.z);
            // d(−f·u/w)/dX = −f/w · (∂u − u/w · ∂w), rows of M.
            let m = &p.rotation;
            let row = |k: usize, v: f64| -> nalgebra::RowVector3<f64> { -focal_mm / u.z * (m.row(k) - v / u.z * m.row(2)) };
            let (jx, jy) = (row(0, u.x), row(1, u.y));
            for (j, r) in [(jx, obs[0] - fx), (jy, obs[1] - fy)] {
                ata += j.transpose() * j;
                atb += j.transpose() * r;
            }
        }
        let dx = ata.try_inverse()? * atb;
        x += dx;
        if dx.norm() < 1e-9 {
            break;
        }
    }
    Some(x)
}

/// A 3-D affine transformation `y = A · x + t` (12 parameters).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Affine {
    /// Linear part.
    pub linear: Mat3,
    /// Translation.
    pub translation: Vec3,
}

impl Affine {
    /// Applies the transformation to a point.
    pub fn apply(&self, x: &Vec3) -> Vec3 {
        self.linear * x + self.translation
    }
}

/// The 3-D affine transformation taking `from` onto `to` by linear least squares (seed 001 eq. 4-25), `None` with
/// fewer than four points or points (nearly) in one plane, where the twelve parameters are not determined.
pub fn affine(from: &[Vec3], to: &[Vec3]) -> Option<Affine> {
    let n = from.len();
    if n < 4 || n != to.len() {
        return None;
    }
    // Centred, the three rows of A separate into three 3×3 normal systems with one matrix.
    let mx = from.iter().sum::<Vec3>() / n as f64;
    let my = to.iter().sum::<Vec3>() / n as f64;
    let mut xx = Matrix3::zeros();
    let mut yx = Matrix3::zeros();
    for (x, y) in from.iter().zip(to) {
        let (dx, dy) = (x - mx, y - my);
        xx += dx * dx.transpose();
        yx += dy * dx.transpose();
    }
    let eig = xx.symmetric_eigen().eigenvalues;
    let (lo, hi) = (eig.min(), eig.max());
    if hi <= 0.0 || lo / hi < 1e-10 {
        return None;
    }
    let linear = yx * xx.try_inverse()?;
    Some(Affine {
        linear,
        translation: my - linear * mx,
    })
}

#[cfg(test)]
mod collinearity_tests {
    use super::*;
    use crate::rotation_from_opk;

    #[test]
    fn collinearity_intersection_recovers_an_exact_point() {
        let poses = [
            crate::Pose {
                center: Vec3::new(0.0, 0.0, 100.0),
                rotation: rotation_from_opk(0.01, -0.02, 0.3),
            },
            crate::Pose {
                center: Vec3::new(30.0, 2.0, 101.0),
                rotation: rotation_from_opk(-0.05, 0.04, 0.1),
            },
        ];
        let x = Vec3::new(12.0, -7.0, 15.0);
        let ideal: Vec<[f64; 2]> = poses
            .iter()
            .map(|p| {
                let u = p.to_camera(&x);
                [-28.0 * u.x / u.z, -28.0 * u.y / u.z]
            })
            .collect();
        let y = intersect_collinearity(28.0, &poses, &ideal).unwrap();
        assert!((y - x).norm() < 1e-9, "{y}");
    }

    #[test]
    fn an_affine_is_recovered_from_four_points_and_refused_on_a_plane() {
        let a = Affine {
            linear: Mat3::new(1.1, 0.2, -0.1, 0.05, 0.9, 0.3, -0.2, 0.1, 1.3),
            translation: Vec3::new(5.0, -2.0, 1.0),
        };
        let from = [
            Vec3::new(0.0, 0.0, 0.0),
            Vec3::new(1.0, 0.0, 0.0),
            Vec3::new(0.0, 1.0, 0.0),
            Vec3::new(0.0, 0.0, 1.0),
            Vec3::new(1.0, 1.0, 1.0),
        ];
        let to: Vec<Vec3> = from.iter().map(|x| a.apply(x)).collect();
        let b = affine(&from, &to).unwrap();
        assert!((b.linear - a.linear).norm() < 1e-12 && (b.translation - a.translation).norm() < 1e-12);
        let flat = [from[0], from[1], from[2], Vec3::new(1.0, 1.0, 0.0)];
        let to: Vec<Vec3> = flat.iter().map(|x| a.apply(x)).collect();
        assert!(affine(&flat, &to).is_none());
    }
}
