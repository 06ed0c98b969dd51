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
    f: impl FnMut(&ImageHeader, &[u8]) -> anyhow::Result<()>,
) -> anyhow::Result<()> {
    for_each_gray_up_to(input, buffer, usize::MAX, f)
}

/// [`for_each_gray`] for at most `max` images: the rest stay in the edge's buffer, so that a stage that holds the
/// images it took bounds its memory and a lossless edge passes the back-pressure on to its publisher.
///
/// # Errors
/// As [`for_each_gray`].
pub fn for_each_gray_up_to(
    input: &Input<Image>,
    buffer: &mut Vec<u8>,
    max: usize,
    mut f: impl FnMut(&ImageHeader, &[u8]) -> anyhow::Result<()>,
) -> anyhow::Result<()> {
    for _ in 0..max {
        let Some(msg) = input.receive()? else { break };
        let h = *msg.user_header();
        buffer.resize(h.width as usize * h.height as usize, 0);
        gray_of_image(&h, msg.payload(), buffer)?;
        drop(msg);
        f(&h, buffer)?;
    }
    Ok(())
}
