//! The receive loop of the stages that work on grey images, whichever encoding the images arrive in.
use lineflow_messages::kinds::Image;
use lineflow_messages::ImageHeader;

use lineflow_runtime::Input;

use crate::gray::gray_of_image;

/// Takes every image waiting on `input`, converts it to 8-bit grey in `buffer` (reused from frame to frame) and
/// calls `f` with its header and the grey pixels: the receive loop of the stages that work on grey images.
///
/// # Errors
/// A receive or conversion failure, or the first error of `f`.
pub fn for_each_gray(
    input: &Input<Image>,
    buffer: &mut Vec<u8>,
    mut f: impl FnMut(&ImageHeader, &[u8]) -> anyhow::Result<()>,
) -> anyhow::Result<()> {
    while let Some(msg) = input.receive()? {
        let h = *msg.user_header();
        buffer.resize(h.width as usize * h.height as usize, 0);
        gray_of_image(&h, msg.payload(), buffer)?;
        drop(msg);
        f(&h, buffer)?;
    }
    Ok(())
}
