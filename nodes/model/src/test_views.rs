//! Cameras in front of a wall and the 2-D lines they measure, for the tests of the stages that look in the images.
use lineflow_photogrammetry::{Camera, Mat3, Pose, Vec3};

use crate::refine::ImageLines;

/// Cameras 5 m in front of the wall y = 0, at the given x, looking along +y.
pub(crate) fn cameras(xs: &[f64]) -> (Camera, Vec<Pose>) {
    let camera = Camera::pinhole(2000, 1500, 0.005, 8.0);
    let rotation = Mat3::new(1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, -1.0, 0.0);
    let poses = xs
        .iter()
        .map(|&x| Pose {
            center: Vec3::new(x, -5.0, 0.5),
            rotation,
        })
        .collect();
    (camera, poses)
}

/// The image lines `pose` measures of `edges`, each moved `shift_px` along the image's x.
pub(crate) fn image_lines(camera: &Camera, pose: &Pose, edges: &[(Vec3, Vec3)], shift_px: f64) -> ImageLines {
    let measured: Vec<([f64; 2], [f64; 2])> = edges
        .iter()
        .map(|(a, b)| {
            let (p, q) = (pose.project(camera, a).unwrap(), pose.project(camera, b).unwrap());
            ([p[0] + shift_px, p[1]], [q[0] + shift_px, q[1]])
        })
        .collect();
    ImageLines::new(camera, Some(*pose), &measured, 20.0)
}
