//! `CameraModel`: the interior orientation of `camera.toml` (`conventions.md`). Latched; empty payload.
use iceoryx2::prelude::ZeroCopySend;

use crate::Stamp;

/// Header of a `CameraModel` message; the payload is empty.
#[derive(Debug, Default, Clone, Copy, PartialEq, ZeroCopySend)]
#[repr(C)]
#[type_name("lineflow/CameraModel/v1")]
pub struct CameraModelHeader {
    /// Common stamp.
    pub stamp: Stamp,
    /// Image width in pixels.
    pub width: u32,
    /// Image height in pixels.
    pub height: u32,
    /// Pixel pitch in millimetres.
    pub pixel_size_mm: f64,
    /// Principal distance in millimetres.
    pub focal_mm: f64,
    /// Principal point (x0, y0) in photo coordinates, millimetres.
    pub principal_point_mm: [f64; 2],
    /// Radial correction k1, k2, k3 (mm⁻², mm⁻⁴, mm⁻⁶).
    pub radial: [f64; 3],
    /// Decentering correction p1, p2 (mm⁻¹).
    pub decentering: [f64; 2],
}

impl CameraModelHeader {
    /// The header of a camera (stamp left default).
    pub fn from_camera(c: &lineflow_photogrammetry::Camera) -> Self {
        CameraModelHeader {
            stamp: Stamp::default(),
            width: c.width,
            height: c.height,
            pixel_size_mm: c.pixel_size_mm,
            focal_mm: c.focal_mm,
            principal_point_mm: c.principal_point_mm,
            radial: c.radial,
            decentering: c.decentering,
        }
    }

    /// The camera this header describes.
    pub fn camera(&self) -> lineflow_photogrammetry::Camera {
        lineflow_photogrammetry::Camera {
            width: self.width,
            height: self.height,
            pixel_size_mm: self.pixel_size_mm,
            focal_mm: self.focal_mm,
            principal_point_mm: self.principal_point_mm,
            radial: self.radial,
            decentering: self.decentering,
        }
    }
}
