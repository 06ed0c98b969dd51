//! `EdgeMap`, `Lines2D`, `Points3D` and `Lines3D`: the line pipeline.
use iceoryx2::prelude::ZeroCopySend;

use crate::Stamp;

/// Header of an `EdgeMap` message; the payload is `[EdgePixel]` in row-major order.
#[derive(Debug, Clone, Copy, ZeroCopySend)]
#[repr(C)]
#[type_name("lineflow/EdgeMap/v2")]
pub struct EdgeMapHeader {
    /// Common stamp.
    pub stamp: Stamp,
    /// Image width in pixels.
    pub width: u32,
    /// Image height in pixels.
    pub height: u32,
    /// Detector id, NUL-padded (`canny`, `sobel`, `log`).
    pub detector: [u8; 16],
    /// File name of the source image, NUL-padded UTF-8 (as in `ImageHeader`).
    pub name: [u8; 64],
}

impl Default for EdgeMapHeader {
    fn default() -> Self {
        Self {
            stamp: Stamp::default(),
            width: 0,
            height: 0,
            detector: [0; 16],
            name: [0; 64],
        }
    }
}

impl EdgeMapHeader {
    /// The source image's file name.
    pub fn name(&self) -> &str {
        crate::str_from_fixed(&self.name)
    }
}

/// One edge pixel with its gradient.
#[derive(Debug, Default, Clone, Copy, PartialEq, ZeroCopySend)]
#[repr(C)]
#[type_name("lineflow/EdgePixel/v1")]
pub struct EdgePixel {
    /// Pixel column.
    pub col: u16,
    /// Pixel row.
    pub row: u16,
    /// Gradient magnitude (3×3 Sobel on the 8-bit image).
    pub magnitude: f32,
    /// Gradient direction in radians, atan2(gy, gx) with y down.
    pub direction_rad: f32,
}

/// Header of a `Lines2D` message. Two-part byte payload (see [`crate::parts`]): `[Segment2; n_segments]`, then
/// `[[u16; 2]; n_chain]`, the (col, row) pixel chains the segments were fitted to.
#[derive(Debug, Clone, Copy, ZeroCopySend)]
#[repr(C)]
#[type_name("lineflow/Lines2D/v2")]
pub struct Lines2DHeader {
    /// Common stamp.
    pub stamp: Stamp,
    /// Number of segments.
    pub n_segments: u32,
    /// Number of chain pixels over all segments.
    pub n_chain: u32,
    /// File name of the source image, NUL-padded UTF-8.
    pub name: [u8; 64],
}

impl Lines2DHeader {
    /// The segments of a Lines2D payload and their concatenated pixel chains.
    ///
    /// # Errors
    /// When the payload is shorter than the header's counts need (the message names the frame).
    pub fn split<'a>(&self, payload: &'a [u8]) -> Result<(&'a [Segment2], &'a [[u16; 2]]), String> {
        crate::parts::split::<Segment2, [u16; 2]>(payload, self.n_segments as usize, self.n_chain as usize)
            .map_err(|e| format!("lines2d of frame {}: {e}", self.stamp.frame))
    }
}

impl Default for Lines2DHeader {
    fn default() -> Self {
        Self {
            stamp: Stamp::default(),
            n_segments: 0,
            n_chain: 0,
            name: [0; 64],
        }
    }
}

impl Lines2DHeader {
    /// The source image's file name.
    pub fn name(&self) -> &str {
        crate::str_from_fixed(&self.name)
    }
}

/// A 2-D segment; endpoints in measured pixel coordinates, straight in corrected coordinates.
#[derive(Debug, Default, Clone, Copy, PartialEq, ZeroCopySend)]
#[repr(C)]
#[type_name("lineflow/Segment2/v1")]
pub struct Segment2 {
    /// Segment id, unique within the frame.
    pub id: u32,
    /// First chain pixel of this segment.
    pub chain_start: u32,
    /// Number of chain pixels.
    pub chain_len: u32,
    /// Padding, zero.
    pub reserved: u32,
    /// First endpoint (col, row).
    pub start_px: [f64; 2],
    /// Second endpoint (col, row).
    pub end_px: [f64; 2],
}

/// Header of a `Points3D` message. Two-part byte payload: `[PointGroup; n_groups]`, then `[Point3; n_points]`.
#[derive(Debug, Default, Clone, Copy, ZeroCopySend)]
#[repr(C)]
#[type_name("lineflow/Points3D/v1")]
pub struct Points3DHeader {
    /// Common stamp.
    pub stamp: Stamp,
    /// Number of groups (one per matched 2-D line).
    pub n_groups: u32,
    /// Number of points over all groups.
    pub n_points: u32,
}

/// The matched object points of one 2-D line.
#[derive(Debug, Default, Clone, Copy, PartialEq, ZeroCopySend)]
#[repr(C)]
#[type_name("lineflow/PointGroup/v2")]
pub struct PointGroup {
    /// Id of the 2-D segment in the master frame (`stamp.frame`).
    pub segment_id: u32,
    /// First point of the group.
    pub start: u32,
    /// Number of points.
    pub len: u32,
    /// Images that took part in the matching: the master and the slaves that see the line's wall.
    pub n_views: u32,
}

/// A matched object point.
#[derive(Debug, Default, Clone, Copy, PartialEq, ZeroCopySend)]
#[repr(C)]
#[type_name("lineflow/Point3/v1")]
pub struct Point3 {
    /// Object coordinates in metres.
    pub xyz: [f64; 3],
    /// Mean normalised cross-correlation over the slaves.
    pub sncc: f64,
}

/// Header of a `Lines3D` message; the payload is `[Line3]`.
#[derive(Debug, Default, Clone, Copy, ZeroCopySend)]
#[repr(C)]
#[type_name("lineflow/Lines3D/v1")]
pub struct Lines3DHeader {
    /// Common stamp.
    pub stamp: Stamp,
}

/// A 3-D segment (`lines3d.csv`).
#[derive(Debug, Default, Clone, Copy, PartialEq, ZeroCopySend)]
#[repr(C)]
#[type_name("lineflow/Line3/v2")]
pub struct Line3 {
    /// Line id.
    pub id: u64,
    /// First endpoint in metres.
    pub start_m: [f64; 3],
    /// Second endpoint in metres.
    pub end_m: [f64; 3],
    /// Supporting points.
    pub n_points: u32,
    /// Supporting images.
    pub n_images: u32,
    /// RMS distance of the inliers from the line, metres.
    pub rms_m: f64,
    /// What the line is, a [`LineClass`] as its number: 0 not classed, 1 structure, 2 texture.
    pub class: u32,
    /// Padding, zero.
    pub reserved: u32,
}

/// What a 3-D line is on the building. Structure: an edge where surfaces meet or the depth steps (an opening's
/// outline, a reveal, a frame, a sill, a cornice, a corner, a roof edge), what a model is made of. Texture: a line
/// lying inside a surface (mortar, tile and panel joints, painted lines), real, but no edge of the model.
#[derive(Debug, Default, Clone, Copy, PartialEq, Eq, Hash)]
pub enum LineClass {
    /// Not classed (a stage that does not class its lines, or a file without the column).
    #[default]
    Unknown,
    /// An edge of the building.
    Structure,
    /// A line inside a surface.
    Texture,
}

impl LineClass {
    /// The number a `Line3` carries.
    pub fn code(self) -> u32 {
        match self {
            LineClass::Unknown => 0,
            LineClass::Structure => 1,
            LineClass::Texture => 2,
        }
    }

    /// The class of a `Line3`'s number; numbers this version does not know read as `Unknown`.
    pub fn from_code(code: u32) -> Self {
        match code {
            1 => LineClass::Structure,
            2 => LineClass::Texture,
            _ => LineClass::Unknown,
        }
    }

    /// The word `lines3d.csv` writes: `structure`, `texture`, or empty.
    pub fn name(self) -> &'static str {
        match self {
            LineClass::Unknown => "",
            LineClass::Structure => "structure",
            LineClass::Texture => "texture",
        }
    }

    /// The class a word of `lines3d.csv` names, `None` for a word that is no class.
    pub fn from_name(name: &str) -> Option<Self> {
        match name {
            "" => Some(LineClass::Unknown),
            "structure" => Some(LineClass::Structure),
            "texture" => Some(LineClass::Texture),
            _ => None,
        }
    }
}
