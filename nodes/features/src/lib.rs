//! The features stage: interest points with descriptors for tie-point matching (seed 000 §2.4).
#![warn(missing_docs)]
pub mod describe;
pub mod integral;
pub mod orb;
pub mod surf;
