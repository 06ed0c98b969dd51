//! Exterior orientation and collinearity.
use crate::{Camera, Mat3, Vec3};

/// The exterior orientation of one image: perspective centre and rotation M (object → image).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Pose {
    /// Perspective centre (XL, YL, ZL), metres.
    pub center: Vec3,
    /// M = R3(κ)·R2(φ)·R1(ω).
    pub rotation: Mat3,
}

impl Pose {
    /// The rotated object vector (u, v, w) of a point; in front of the camera w < 0.
    pub fn to_camera(&self, point: &Vec3) -> Vec3 {
        self.rotation * (point - self.center)
    }

    /// The ideal photo point (relative to the principal point) of an object point, if it is in front of the camera.
    pub fn project_ideal(&self, camera: &Camera, point: &Vec3) -> Option<[f64; 2]> {
        let uvw = self.to_camera(point);
        (uvw.z < 0.0).then(|| [-camera.focal_mm * uvw.x / uvw.z, -camera.focal_mm * uvw.y / uvw.z])
    }

    /// The measured pixel position of an object point (collinearity, then the inverse correction).
    pub fn project(&self, camera: &Camera, point: &Vec3) -> Option<[f64; 2]> {
        self.project_ideal(camera, point).and_then(|i| camera.ideal_to_pixel(i))
    }

    #[inline]
    /// The unit viewing ray, in object space, of an ideal photo point: `Mᵀ · (xi, yi, −f)`.
    pub fn ray_of_ideal(&self, camera: &Camera, ideal: [f64; 2]) -> Vec3 {
        (self.rotation.transpose() * Vec3::new(ideal[0], ideal[1], -camera.focal_mm)).normalize()
    }

    #[inline]
    /// The unit viewing ray of a measured pixel position (closed form through the correction model).
    pub fn ray_of_pixel(&self, camera: &Camera, px: [f64; 2]) -> Vec3 {
        self.ray_of_ideal(camera, camera.pixel_to_ideal(px))
    }

    /// The camera's viewing direction (its −z axis) in object space.
    pub fn axis(&self) -> Vec3 {
        -self.rotation.row(2).transpose()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::rotation_from_opk;

    fn camera() -> Camera {
        Camera {
            width: 4288,
            height: 2848,
            pixel_size_mm: 0.0055,
            focal_mm: 17.606,
            principal_point_mm: [-0.107, 0.016],
            radial: [3.5e-5, 0.0, 0.0],
            decentering: [6e-6, -4e-6],
        }
    }

    /// `conventions.md`: ω = 90°, φ = κ = 0 looks along +Y with image x along +X and image y along +Z.
    #[test]
    fn worked_example_of_the_conventions() {
        let pose = Pose {
            center: Vec3::new(0.0, -20.0, 0.0),
            rotation: rotation_from_opk(90f64.to_radians(), 0.0, 0.0),
        };
        assert!((pose.axis() - Vec3::y()).norm() < 1e-12, "looks along +Y");
        let c = Camera {
            radial: [0.0; 3],
            decentering: [0.0; 2],
            principal_point_mm: [0.0; 2],
            ..camera()
        };
        let centre = pose.project(&c, &Vec3::zeros()).unwrap();
        let right = pose.project(&c, &Vec3::new(1.0, 0.0, 0.0)).unwrap();
        let up = pose.project(&c, &Vec3::new(0.0, 0.0, 1.0)).unwrap();
        assert!(right[0] > centre[0] && (right[1] - centre[1]).abs() < 1e-9, "+X is image right");
        assert!(up[1] < centre[1] && (up[0] - centre[0]).abs() < 1e-9, "+Z is image up");
        // 1 m at 20 m is f/20 mm on the sensor.
        assert!(((right[0] - centre[0]) * c.pixel_size_mm - c.focal_mm / 20.0).abs() < 1e-9);
        assert!(pose.project(&c, &Vec3::new(0.0, -40.0, 0.0)).is_none(), "behind the camera");
        // The façade Y = 0 seen from Y = -20: its outward normal (-Y) points at the camera.
        assert!(pose.axis().dot(&-Vec3::y()) < 0.0);
    }

    #[test]
    fn rays_and_projections_agree() {
        let pose = Pose {
            center: Vec3::new(3.0, -19.3, 1.6),
            rotation: rotation_from_opk(100f64.to_radians(), 5f64.to_radians(), -2f64.to_radians()),
        };
        let c = camera();
        for &px in &[[0.0, 0.0], [4287.0, 2847.0], [1000.5, 2000.25], [2143.5, 1423.5]] {
            let ray = pose.ray_of_pixel(&c, px);
            let point = pose.center + ray * 17.0;
            let back = pose.project(&c, &point).unwrap();
            assert!(
                (back[0] - px[0]).abs() < 1e-6 && (back[1] - px[1]).abs() < 1e-6,
                "{px:?} -> {back:?}"
            );
        }
    }
}
