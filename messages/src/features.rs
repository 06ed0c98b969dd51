//! `Keypoints` and `TiePoints`: the orientation stage's inputs.
use iceoryx2::prelude::ZeroCopySend;

use crate::Stamp;

/// Header of a `Keypoints` message. Two-part byte payload (see [`crate::parts`]): `[Keypoint; count]`, then
/// `count * descriptor_len` descriptor values of type `f32` (float descriptors such as SURF) or `u8` (binary
/// descriptors such as ORB), as `descriptor_kind` says.
#[derive(Debug, Default, Clone, Copy, ZeroCopySend)]
#[repr(C)]
#[type_name("lineflow/Keypoints/v1")]
pub struct KeypointsHeader {
    /// Common stamp.
    pub stamp: Stamp,
    /// Number of keypoints.
    pub count: u32,
    /// Values per descriptor (64 for SURF).
    pub descriptor_len: u32,
    /// [`KeypointsHeader::FLOAT`] or [`KeypointsHeader::BINARY`].
    pub descriptor_kind: u32,
    /// Detector id, NUL-padded (`surf`, `orb`).
    pub detector: [u8; 12],
}

impl KeypointsHeader {
    /// Descriptors are `f32`.
    pub const FLOAT: u32 = 0;
    /// Descriptors are bytes compared by Hamming distance.
    pub const BINARY: u32 = 1;
}

/// A detected interest point.
#[derive(Debug, Default, Clone, Copy, PartialEq, ZeroCopySend)]
#[repr(C)]
#[type_name("lineflow/Keypoint/v1")]
pub struct Keypoint {
    /// Measured pixel column.
    pub col: f32,
    /// Measured pixel row.
    pub row: f32,
    /// Scale (σ of the detector) in pixels.
    pub scale_px: f32,
    /// Orientation in radians.
    pub orientation_rad: f32,
    /// Detector response.
    pub response: f32,
    /// Sign of the Laplacian (+1, -1, 0 when unknown).
    pub laplacian_sign: i32,
}

/// Header of a `TiePoints` message; the payload is `[TiePoint]`: the observations of one frame.
#[derive(Debug, Default, Clone, Copy, ZeroCopySend)]
#[repr(C)]
#[type_name("lineflow/TiePoints/v1")]
pub struct TiePointsHeader {
    /// Common stamp.
    pub stamp: Stamp,
}

/// One observation of a tie point; `track` keeps its identity across frames.
#[derive(Debug, Default, Clone, Copy, PartialEq, ZeroCopySend)]
#[repr(C)]
#[type_name("lineflow/TiePoint/v1")]
pub struct TiePoint {
    /// Track id, the same in every frame that sees the point.
    pub track: u64,
    /// Frame that observed it.
    pub frame: u64,
    /// Measured pixel column.
    pub col: f64,
    /// Measured pixel row.
    pub row: f64,
}
