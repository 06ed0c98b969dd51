//! Circular survey targets (a white disc inside a black ring, as printed for close-range photogrammetry) found in
//! the images with sub-pixel centres ([`detect`]), and named by the surveyed points they fit ([`name`]): the
//! detections are intersected into 3-D points with the images' poses, in whatever frame those are (a first run
//! without control points leaves them in the frame of its first pair), and the similarity that lays the most of
//! them onto `control_points.csv` names them. What `lineflow targets` writes is `observations.csv`.
#![warn(missing_docs)]

pub mod detect;
pub mod name;

pub use detect::{detect, DetectSettings, Detection};
pub use name::{name, Face, NameSettings, Named, Naming, NamingError, TargetView};
