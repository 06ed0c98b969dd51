//! Message types shared by every lineflow node.
//!
//! Every message is one iceoryx2 sample: a `#[repr(C)]` header (the iceoryx2 *user header*) plus a slice of
//! fixed-size elements (the payload). Every header starts with the same [`Stamp`]. Where a message needs two
//! variable parts (segments and their pixel chains, keypoints and their descriptors) the payload is a byte slice
//! whose layout the header states with counts and byte offsets; [`parts`] reads and writes such layouts.
//!
//! The byte layout of every type is part of the node contract (`docs/nodes.md`): nodes in other languages open
//! the same services with the same type names. Layout tests pin the sizes.
#![warn(missing_docs)]

pub mod camera;
pub mod checksum;
pub mod control;
pub mod features;
pub mod image;
pub mod lines;
pub mod model;
pub mod parts;
pub mod poses;
pub mod registry;
pub mod schema;
pub mod stamp;
pub mod status;

pub use camera::CameraModelHeader;
pub use control::{ControlPoint, ControlPointsHeader, Observation, ObservationsHeader, SiteHeader, Wall};
pub use features::{Keypoint, KeypointsHeader, TiePoint, TiePointsHeader};
pub use image::{Encoding, ImageHeader};
pub use lines::{EdgeMapHeader, EdgePixel, Line3, LineClass, Lines2DHeader, Lines3DHeader, Point3, PointGroup, Points3DHeader, Segment2};
pub use model::{FaceVertex, ModelFacesHeader, WireEdge, WireframeHeader};
pub use poses::{Pose, PosesHeader};
pub use registry::{kinds, Message, MessageKind};
pub use stamp::{Stamp, StampFlags};
pub use status::NodeStatus;

/// Copies `s` into a fixed, NUL-padded byte array (truncating at a character boundary).
pub fn fixed_str<const N: usize>(s: &str) -> [u8; N] {
    let mut out = [0u8; N];
    let mut end = s.len().min(N);
    while !s.is_char_boundary(end) {
        end -= 1;
    }
    out[..end].copy_from_slice(&s.as_bytes()[..end]);
    out
}

/// Reads a NUL-padded byte array written by [`fixed_str`].
pub fn str_from_fixed(bytes: &[u8]) -> &str {
    let end = bytes.iter().position(|&b| b == 0).unwrap_or(bytes.len());
    std::str::from_utf8(&bytes[..end]).unwrap_or("")
}
