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
    /// Bit 0: oriented; bit 1: settled (the sliding window moved past it); bit 2: final.
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
