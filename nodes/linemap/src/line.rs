//! What the stage makes: a 3-D line segment with the evidence behind it.
use lineflow_photogrammetry::Vec3;

/// A reconstructed 3-D line.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MappedLine {
    /// First endpoint.
    pub start: Vec3,
    /// Second endpoint.
    pub end: Vec3,
    /// 2-D segments along it.
    pub n_segments: u32,
    /// Images those segments come from.
    pub n_images: u32,
    /// RMS distance of the segments' planes from the line, metres.
    pub rms_m: f64,
}
