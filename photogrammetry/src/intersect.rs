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
