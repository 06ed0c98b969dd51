//! What the stage makes: a 3-D line segment with the evidence behind it.
use lineflow_photogrammetry::{Mat3, Vec3};

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
    /// Covariance of its position across itself from its segments' planes, m² (`MultiviewLine::across_cov`).
    pub across_cov: Mat3,
    /// Made from a corner with a vertical line: its depth comes from that line, not from its own segments.
    pub from_corner: bool,
}

impl MappedLine {
    /// Standard deviation of its position along the unit direction `w` across it, metres.
    pub fn sigma_along(&self, w: &Vec3) -> f64 {
        w.dot(&(self.across_cov * w)).max(0.0).sqrt()
    }
}
