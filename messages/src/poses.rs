//! `Poses`: exterior orientations, republished with higher revisions as adjustments improve them.
use iceoryx2::prelude::ZeroCopySend;

use crate::Stamp;

/// Header of a `Poses` message; the payload is `[Pose]`.
#[derive(Debug, Default, Clone, Copy, ZeroCopySend)]
#[repr(C)]
#[type_name("lineflow/Poses/v1")]
pub struct PosesHeader {
    /// Common stamp; `stamp.revision` counts the adjustments of this set.
    pub stamp: Stamp,
    /// A-posteriori σ0 of the adjustment (NaN when none ran).
    pub sigma0: f64,
    /// Reprojection RMS of the tie points in pixels.
    pub rms_px: f64,
}

/// The exterior orientation of one frame.
#[derive(Debug, Default, Clone, Copy, PartialEq, ZeroCopySend)]
#[repr(C)]
#[type_name("lineflow/Pose/v1")]
pub struct Pose {
    /// Frame number.
    pub frame: u64,
    /// Revision of this frame's pose.
    pub revision: u32,
    /// Bit 0: oriented; bit 1: settled (the sliding window moved past it); bit 2: final; bit 3: in the control
    /// points' frame (georeferenced).
    pub flags: u32,
    /// Perspective centre (XL, YL, ZL) in metres.
    pub center_m: [f64; 3],
    /// Rotation M (object to image), row-major (`conventions.md`).
    pub rotation: [f64; 9],
    /// Standard deviations of the centre in metres (NaN when not estimated).
    pub sigma_center_m: [f64; 3],
    /// Standard deviations of ω, φ, κ in radians (NaN when not estimated).
    pub sigma_angles_rad: [f64; 3],
}

impl Pose {
    /// Bit of `flags`: the frame is oriented.
    pub const ORIENTED: u32 = 1;
    /// Bit of `flags`: the sliding window has moved past the frame.
    pub const SETTLED: u32 = 2;
    /// Bit of `flags`: the end-of-stream adjustment has run.
    pub const FINAL: u32 = 4;
    /// Bit of `flags`: the pose is in the frame of the control points (before three are seen, the block has the
    /// arbitrary frame of its first pair).
    pub const GEOREFERENCED: u32 = 8;

    /// The message element of an exterior orientation, without standard deviations.
    pub fn from_exterior(frame: u64, revision: u32, flags: u32, pose: &lineflow_photogrammetry::Pose) -> Self {
        let m = &pose.rotation;
        Pose {
            frame,
            revision,
            flags,
            center_m: pose.center.into(),
            rotation: std::array::from_fn(|k| m[(k / 3, k % 3)]),
            sigma_center_m: [f64::NAN; 3],
            sigma_angles_rad: [f64::NAN; 3],
        }
    }

    /// The exterior orientation this element holds.
    pub fn exterior(&self) -> lineflow_photogrammetry::Pose {
        lineflow_photogrammetry::Pose {
            center: self.center_m.into(),
            rotation: lineflow_photogrammetry::Mat3::from_row_slice(&self.rotation),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn exterior_orientation_round_trips_row_major() {
        let pose = lineflow_photogrammetry::Pose {
            center: lineflow_photogrammetry::Vec3::new(1.0, -19.3, 1.6),
            rotation: lineflow_photogrammetry::rotation_from_opk(1.8, 0.1, -0.3),
        };
        let msg = Pose::from_exterior(3, 0, Pose::ORIENTED, &pose);
        assert_eq!(msg.rotation[1], pose.rotation[(0, 1)], "row-major");
        assert_eq!(msg.exterior(), pose);
    }
}
