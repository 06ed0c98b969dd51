//! Pure photogrammetric geometry, no I/O: the camera model of `conventions.md` (a correction model in
//! millimetres), rotations in the ω-φ-κ convention, and collinearity.
//!
//! Rotations are kept as matrices; ω, φ, κ appear only at file boundaries ([`opk_from_rotation`]).
#![warn(missing_docs)]

pub mod bundle;
mod camera;
pub mod epipolar;
pub mod interior;
pub mod intersect;
pub mod lens;
mod polygon;
mod pose;
pub mod random;
pub mod ransac;
mod rotation;
mod stats;

pub use camera::Camera;
pub use interior::{Interior, InteriorReport, SelfCalibration};
pub use lens::{camera_from_opencv, opencv_from_camera, FitResidual, OpenCvLens};
pub use polygon::{point_in_polygon, polygon_normal, signed_area};
pub use pose::Pose;
pub use rotation::{look_at, opk_from_rotation, rotation_from_opk};
pub use stats::{median, weighted_quantile};

/// Object-space 3-vector (metres).
pub type Vec3 = nalgebra::Vector3<f64>;
/// 3×3 matrix.
pub type Mat3 = nalgebra::Matrix3<f64>;
