//! Geometry of 2-D line segments in oriented images, shared by the stages that turn them into 3-D lines: each
//! image's segments indexed in ideal photo coordinates ([`segments`]) and the estimate of a 3-D line from the
//! interpretation planes of every image's segment of it ([`multiview`]), the poses adjusted together with the lines on
//! those segments ([`line_bundle`]), and the 2-D line segments are measured
//! against ([`line2`]), whether a 3-D line is an edge of the building or lies inside a surface ([`class`]), and
//! the plumb and level directions lines nearly following them are turned onto ([`plumb_level`]), and how much of
//! one set of lines another covers, to join two line stages' sets ([`fuse`]).
#![warn(missing_docs)]

pub mod class;
pub mod fuse;
mod grid;
pub mod layers;
pub mod line2;
pub mod line_bundle;
pub mod multiview;
pub mod photo;
pub mod plumb_level;
pub mod segments;
pub mod sides;

pub use class::{classify, classify_elements, classify_supported, ClassRule, RuleError, Sight};
pub use fuse::{covered_shares, uncovered_stretches, Cover};
pub use layers::{snap_to_layers, LayerParams, LayerStats};
pub use line2::Line2;
pub use line_bundle::{adjust_with_lines, LineBundle, LineBundleParams};
pub use multiview::{line_support, refine_line, refine_line_along, MultiviewLine, MultiviewParams};
pub use photo::Photo;
pub use plumb_level::{azimuth_mod_quarter, plan_azimuth, signed_quarter, snap_plumb_and_level};
pub use segments::{FrameSegments, SlaveSegments};
pub use sides::{reclass, sides, PhotoView, SideCounts, SideReport, SideRule, Verdict};
