//! `M = R3(κ)·R2(φ)·R1(ω)`, the rotation from object space to image space (`conventions.md`).
use crate::{Mat3, Vec3};

/// The rotation matrix M of the angles ω, φ, κ (radians).
pub fn rotation_from_opk(omega: f64, phi: f64, kappa: f64) -> Mat3 {
    let (so, co) = omega.sin_cos();
    let (sp, cp) = phi.sin_cos();
    let (sk, ck) = kappa.sin_cos();
    Mat3::new(
        cp * ck,
        so * sp * ck + co * sk,
        -co * sp * ck + so * sk,
        -cp * sk,
        -so * sp * sk + co * ck,
        co * sp * sk + so * ck,
        sp,
        -so * cp,
        co * cp,
    )
}

/// The angles (ω, φ, κ) in radians of a rotation matrix, φ in [-π/2, π/2].
///
/// ω comes from the third row; κ and φ are then read off `M·R1(ω)ᵀ = R3(κ)·R2(φ)`, which stays exact near
/// φ = ±90° where only ω ± κ is defined (there ω = 0), so converting back always gives the same matrix.
pub fn opk_from_rotation(m: &Mat3) -> (f64, f64, f64) {
    let cp = (m[(2, 1)] * m[(2, 1)] + m[(2, 2)] * m[(2, 2)]).sqrt();
    let omega = if cp > 1e-12 { (-m[(2, 1)]).atan2(m[(2, 2)]) } else { 0.0 };
    let n = m * rotation_from_opk(omega, 0.0, 0.0).transpose();
    let kappa = n[(0, 1)].atan2(n[(1, 1)]);
    let phi = n[(2, 0)].atan2(n[(2, 2)]);
    (omega, phi, kappa)
}

/// The rotation of a camera at `center` looking at `target`, with image `y` towards `up` as far as possible.
///
/// The rows of M are the image axes in object space; the camera looks along its −z axis.
pub fn look_at(center: &Vec3, target: &Vec3, up: &Vec3) -> Mat3 {
    let look = (target - center).normalize();
    let x = look.cross(up).normalize();
    let z = -look;
    let y = z.cross(&x);
    Mat3::from_rows(&[x.transpose(), y.transpose(), z.transpose()])
}

#[cfg(test)]
mod tests {
    use super::*;

    fn close(a: &Mat3, b: &Mat3) -> bool {
        (a - b).abs().max() < 1e-12
    }

    #[test]
    fn angles_round_trip_including_gimbal_lock() {
        let d = f64::to_radians;
        for &(o, p, k) in &[
            (90.0, 0.0, 0.0),
            (105.0, -20.0, 3.0),
            (-30.0, 45.0, 170.0),
            (90.0, 90.0, 0.0),
            (10.0, -90.0, 25.0),
            (0.0, 89.9999999, 0.0),
        ] {
            let m = rotation_from_opk(d(o), d(p), d(k));
            let (o2, p2, k2) = opk_from_rotation(&m);
            assert!(close(&m, &rotation_from_opk(o2, p2, k2)), "{o} {p} {k}");
            assert!((m * m.transpose() - Mat3::identity()).abs().max() < 1e-12);
        }
    }

    #[test]
    fn look_at_agrees_with_the_worked_example() {
        let m = look_at(&Vec3::new(0.0, -20.0, 0.0), &Vec3::zeros(), &Vec3::z());
        assert!(close(&m, &rotation_from_opk(90f64.to_radians(), 0.0, 0.0)));
    }
}
