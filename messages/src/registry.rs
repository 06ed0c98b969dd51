//! The message registry: every message type by its launch-file name.
use iceoryx2::prelude::ZeroCopySend;

use crate::*;

/// A message type: a header starting with a [`Stamp`] plus a slice of `Element`s.
pub trait Message: 'static {
    /// The iceoryx2 user header.
    type Header: ZeroCopySend + Default + Copy + std::fmt::Debug + 'static;
    /// The payload element.
    type Element: ZeroCopySend + Default + Copy + std::fmt::Debug + 'static;
    /// Which message this is.
    const KIND: MessageKind;
    /// The stamp of a header.
    fn stamp(header: &Self::Header) -> &Stamp;
    /// The stamp of a header, mutable.
    fn stamp_mut(header: &mut Self::Header) -> &mut Stamp;
}

macro_rules! messages {
    ($($name:ident => $header:ty, $element:ty, latched = $latched:expr, $doc:literal;)*) => {
        /// Every message type of the pipeline, named as in launch files.
        #[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
        pub enum MessageKind {
            $(#[doc = $doc] $name,)*
        }

        impl MessageKind {
            /// Every kind.
            pub const ALL: &'static [MessageKind] = &[$(MessageKind::$name,)*];

            /// The launch-file name (`Image`, `Lines2D`, ...).
            pub fn name(self) -> &'static str {
                match self { $(MessageKind::$name => stringify!($name),)* }
            }

            /// Parses a launch-file name.
            pub fn from_name(name: &str) -> Option<Self> {
                match name { $(stringify!($name) => Some(MessageKind::$name),)* _ => None }
            }

            /// Whether a late subscriber still gets the last message (camera, control data, site).
            pub fn latched(self) -> bool {
                match self { $(MessageKind::$name => $latched,)* }
            }

            /// Size of the header in bytes.
            pub fn header_size(self) -> usize {
                match self { $(MessageKind::$name => size_of::<$header>(),)* }
            }

            /// Size of one payload element in bytes.
            pub fn element_size(self) -> usize {
                match self { $(MessageKind::$name => size_of::<$element>(),)* }
            }
        }

        pub mod kinds {
            //! Marker types implementing [`Message`](super::Message), one per message kind.
            use super::*;
            $(
                #[doc = $doc]
                #[derive(Debug, Clone, Copy)]
                pub struct $name;
                impl Message for $name {
                    type Header = $header;
                    type Element = $element;
                    const KIND: MessageKind = MessageKind::$name;
                    fn stamp(h: &$header) -> &Stamp { &h.stamp }
                    fn stamp_mut(h: &mut $header) -> &mut Stamp { &mut h.stamp }
                }
            )*
        }
    };
}

messages! {
    Image => ImageHeader, u8, latched = false, "A camera frame.";
    CameraModel => CameraModelHeader, u8, latched = true, "Interior orientation (empty payload).";
    ControlPoints => ControlPointsHeader, ControlPoint, latched = true, "Surveyed control and check points.";
    Observations => ObservationsHeader, Observation, latched = true, "Image measurements of the surveyed points.";
    Site => SiteHeader, Wall, latched = true, "Approximate building model (walls).";
    Keypoints => KeypointsHeader, u8, latched = false, "Interest points with descriptors (two-part bytes).";
    TiePoints => TiePointsHeader, TiePoint, latched = false, "Tie-point observations of one frame.";
    Poses => PosesHeader, Pose, latched = false, "Exterior orientations with revisions.";
    EdgeMap => EdgeMapHeader, EdgePixel, latched = false, "Edge pixels with gradients.";
    Lines2D => Lines2DHeader, u8, latched = false, "2-D segments and their pixel chains (two-part bytes).";
    Points3D => Points3DHeader, u8, latched = false, "Matched object points per 2-D line (two-part bytes).";
    Lines3D => Lines3DHeader, Line3, latched = false, "3-D segments.";
    Wireframe => WireframeHeader, u8, latched = false, "Wire-frame model (two-part bytes).";
    ModelFaces => ModelFacesHeader, FaceVertex, latched = false, "Faces of a wire-frame model: rings of vertex indices.";
}

/// Runs `$body` with the type alias `$M` bound to the [`kinds`] marker type of a runtime [`MessageKind`], for code
/// that handles every message type alike (the recorder, the player).
///
/// ```
/// use lineflow_messages::{with_kind, Message, MessageKind};
/// let size = with_kind!(MessageKind::Poses, M => size_of::<<M as Message>::Element>());
/// assert_eq!(size, MessageKind::Poses.element_size());
/// ```
#[macro_export]
macro_rules! with_kind {
    ($kind:expr, $M:ident => $body:expr) => {{
        use $crate::MessageKind as K;
        match $kind {
            K::Image => {
                type $M = $crate::kinds::Image;
                $body
            }
            K::CameraModel => {
                type $M = $crate::kinds::CameraModel;
                $body
            }
            K::ControlPoints => {
                type $M = $crate::kinds::ControlPoints;
                $body
            }
            K::Observations => {
                type $M = $crate::kinds::Observations;
                $body
            }
            K::Site => {
                type $M = $crate::kinds::Site;
                $body
            }
            K::Keypoints => {
                type $M = $crate::kinds::Keypoints;
                $body
            }
            K::TiePoints => {
                type $M = $crate::kinds::TiePoints;
                $body
            }
            K::Poses => {
                type $M = $crate::kinds::Poses;
                $body
            }
            K::EdgeMap => {
                type $M = $crate::kinds::EdgeMap;
                $body
            }
            K::Lines2D => {
                type $M = $crate::kinds::Lines2D;
                $body
            }
            K::Points3D => {
                type $M = $crate::kinds::Points3D;
                $body
            }
            K::Lines3D => {
                type $M = $crate::kinds::Lines3D;
                $body
            }
            K::Wireframe => {
                type $M = $crate::kinds::Wireframe;
                $body
            }
            K::ModelFaces => {
                type $M = $crate::kinds::ModelFaces;
                $body
            }
        }
    }};
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn layouts_are_pinned() {
        assert_eq!(size_of::<Stamp>(), 32);
        assert_eq!(size_of::<ImageHeader>(), 32 + 16 + 64);
        assert_eq!(size_of::<CameraModelHeader>(), 32 + 8 + 8 * 9);
        assert_eq!(size_of::<ControlPoint>(), 16 + 48 + 8);
        assert_eq!(size_of::<Observation>(), 8 + 16 + 16);
        assert_eq!(size_of::<Wall>(), 32 + 8 + 16 * 24);
        assert_eq!(size_of::<Keypoint>(), 24);
        assert_eq!(size_of::<TiePoint>(), 32);
        assert_eq!(size_of::<Pose>(), 16 + 8 * 18);
        assert_eq!(size_of::<EdgePixel>(), 12);
        assert_eq!(size_of::<Segment2>(), 48);
        assert_eq!(size_of::<Point3>(), 32);
        assert_eq!(size_of::<Line3>(), 8 + 48 + 8 + 8 + 8);
        assert_eq!(size_of::<WireEdge>(), 20);
    }

    #[test]
    fn every_kind_round_trips_its_name() {
        for &kind in MessageKind::ALL {
            assert_eq!(MessageKind::from_name(kind.name()), Some(kind));
        }
        assert_eq!(MessageKind::from_name("Imgae"), None);
    }

    #[test]
    fn two_part_payload_round_trips() {
        let segs = [Segment2 {
            id: 7,
            chain_start: 0,
            chain_len: 2,
            reserved: 0,
            start_px: [1.0, 2.0],
            end_px: [3.0, 4.0],
        }];
        let chain = [[1u16, 2], [3, 4]];
        let mut buf = vec![0u64; 8];
        let bytes: &mut [u8] = unsafe { std::slice::from_raw_parts_mut(buf.as_mut_ptr().cast(), 64) };
        let len = parts::two_part_len::<Segment2, [u16; 2]>(1, 2);
        parts::write(&mut bytes[..len], &segs, &chain);
        let (a, b) = parts::split::<Segment2, [u16; 2]>(&bytes[..len], 1, 2).unwrap();
        assert_eq!(a, &segs);
        assert_eq!(b, &chain);
        assert!(parts::split::<Segment2, [u16; 2]>(&bytes[..len - 1], 1, 2).is_err());
    }
}
