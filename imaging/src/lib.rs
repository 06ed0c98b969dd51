//! Raster operations the image stages share: 8-bit grey from any image message (and the receive loop that
//! hands a stage its images in grey), bilinear sampling, the 3×3 Sobel gradient, and sub-pixel positions of edge pixels. The stages' own algorithms (Canny, LoG, line tracing, SURF) stay in their
//! stages; what two stages both need lives here, so that no stage imports another.
#![warn(missing_docs)]

pub mod gradient;
pub mod gray;
pub mod receive;
pub mod sample;
pub mod subpixel;

pub use gradient::{
    gradient, gradient_at, gradient_row, rgb_planes, rgb_planes_into, ColourEdges, Gradient, GradientRow, Planes, RowScratch,
};
pub use gray::{gray_into, gray_of_image, GrayError};
pub use receive::{for_each_gray, for_each_gray_up_to, for_each_planes, PlaneBuffers};
pub use sample::bilinear;
pub use subpixel::{subpixel_positions, subpixel_positions_in};
