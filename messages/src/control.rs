//! `ControlPoints`, `Observations` and `Site`: the survey data of a project folder. All latched.
use iceoryx2::prelude::ZeroCopySend;

use crate::Stamp;

/// Header of a `ControlPoints` message; the payload is `[ControlPoint]`.
#[derive(Debug, Default, Clone, Copy, ZeroCopySend)]
#[repr(C)]
#[type_name("lineflow/ControlPoints/v1")]
pub struct ControlPointsHeader {
    /// Common stamp.
    pub stamp: Stamp,
}

/// One surveyed point (`control_points.csv`).
#[derive(Debug, Default, Clone, Copy, PartialEq, ZeroCopySend)]
#[repr(C)]
#[type_name("lineflow/ControlPoint/v1")]
pub struct ControlPoint {
    /// Point id, NUL-padded UTF-8.
    pub id: [u8; 16],
    /// Object coordinates X, Y, Z in metres.
    pub xyz: [f64; 3],
    /// Standard deviations in metres (NaN when not given).
    pub sigma_m: [f64; 3],
    /// 0 = control (used in the adjustment), 1 = check (held out).
    pub role: u32,
    /// Padding, zero.
    pub reserved: u32,
}

impl ControlPoint {
    /// Role value of a control point.
    pub const CONTROL: u32 = 0;
    /// Role value of a check point.
    pub const CHECK: u32 = 1;
    /// The point id.
    pub fn id(&self) -> &str {
        crate::str_from_fixed(&self.id)
    }
}

/// Header of an `Observations` message; the payload is `[Observation]`.
#[derive(Debug, Default, Clone, Copy, ZeroCopySend)]
#[repr(C)]
#[type_name("lineflow/Observations/v1")]
pub struct ObservationsHeader {
    /// Common stamp.
    pub stamp: Stamp,
}

/// An image measurement of a control or check point (`observations.csv`).
#[derive(Debug, Default, Clone, Copy, PartialEq, ZeroCopySend)]
#[repr(C)]
#[type_name("lineflow/Observation/v1")]
pub struct Observation {
    /// Frame number of the image (its position in file-name order).
    pub frame: u64,
    /// Point id, NUL-padded UTF-8.
    pub point_id: [u8; 16],
    /// Measured pixel column.
    pub col: f64,
    /// Measured pixel row.
    pub row: f64,
}

impl Observation {
    /// The observed point's id.
    pub fn point_id(&self) -> &str {
        crate::str_from_fixed(&self.point_id)
    }
}

/// Header of a `Site` message; the payload is `[Wall]`.
#[derive(Debug, Default, Clone, Copy, ZeroCopySend)]
#[repr(C)]
#[type_name("lineflow/Site/v1")]
pub struct SiteHeader {
    /// Common stamp.
    pub stamp: Stamp,
}

/// A planar wall polygon of `site.toml`, counter-clockwise seen from outside.
#[derive(Debug, Default, Clone, Copy, PartialEq, ZeroCopySend)]
#[repr(C)]
#[type_name("lineflow/Wall/v1")]
pub struct Wall {
    /// Wall name, NUL-padded UTF-8.
    pub name: [u8; 32],
    /// Number of valid entries in `corners`.
    pub n_corners: u32,
    /// Padding, zero.
    pub reserved: u32,
    /// Corners in metres; entries past `n_corners` are zero.
    pub corners: [[f64; 3]; Wall::MAX_CORNERS],
}

impl Wall {
    /// Largest polygon a wall message carries.
    pub const MAX_CORNERS: usize = 16;
    /// A wall of up to [`MAX_CORNERS`](Self::MAX_CORNERS) corners (further corners are dropped: validate first).
    pub fn new(name: &str, corners: &[[f64; 3]]) -> Self {
        let n = corners.len().min(Self::MAX_CORNERS);
        let mut wall = Wall {
            name: crate::fixed_str(name),
            n_corners: n as u32,
            ..Default::default()
        };
        wall.corners[..n].copy_from_slice(&corners[..n]);
        wall
    }
    /// The wall name.
    pub fn name(&self) -> &str {
        crate::str_from_fixed(&self.name)
    }
    /// The valid corners.
    pub fn corners(&self) -> &[[f64; 3]] {
        &self.corners[..(self.n_corners as usize).min(Self::MAX_CORNERS)]
    }
}
