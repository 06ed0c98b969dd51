//! Least-squares model-image fitting (LSMIF, seed 004): a wire-frame, either a parametric primitive (the seed's
//! box) or free vertices, adjusted so that its projection fits the edge pixels of every oriented image.
//!
//! The pieces are plain functions: [`observations`] puts edge pixels into ideal photo coordinates and bins them,
//! [`weights`] holds the seed's four weighting schemes, [`parametric`] what is adjusted, [`fit`] the loop with
//! the shrinking buffer, [`wireframe`] fits a whole wire-frame component by component, and [`faces`] gives the
//! fitted wire-frame its faces. The seed's experiments on synthetic aerial photos are in `lineflow-bench`.
#![warn(missing_docs)]

pub mod faces;
pub mod fit;
pub mod observations;
pub mod parametric;
pub mod sparse;
pub mod stage;
pub mod weights;
pub mod wireframe;

pub use fit::{fit, Fit, FitParams};
pub use observations::{EdgeObservation, ImageEdges};
pub use parametric::{BoxModel, FacePlane, FreeVertices, Parametric};
pub use weights::Weighting;
pub use wireframe::{fit_wireframe, WireframeFit};
