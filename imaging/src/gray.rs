//! 8-bit grey from any image message: what the convert stage's `gray` publishes and what every stage working on
//! grey values computes from the `images` topic when it is wired to it directly.
use lineflow_messages::{Encoding, ImageHeader};

/// Why an image cannot be made grey.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum GrayError {
    /// The header's encoding code is none of [`Encoding`].
    #[error("unknown encoding {0}")]
    UnknownEncoding(u32),
    /// The payload or the output buffer does not match the size and step.
    #[error("{encoding} image {width}x{height} with step {step}: payload has {have} bytes, need {need}")]
    Size {
        /// The encoding's name.
        encoding: &'static str,
        /// Columns.
        width: usize,
        /// Rows.
        height: usize,
        /// Bytes per row.
        step: usize,
        /// Payload bytes.
        have: usize,
        /// Bytes the size needs.
        need: usize,
    },
    /// A received image's error, with its frame and name.
    #[error("frame {frame} ({image}): {cause}")]
    Frame {
        /// The frame.
        frame: u64,
        /// The image's name.
        image: String,
        /// What is wrong.
        cause: Box<GrayError>,
    },
}

/// Writes the 8-bit grey version of a received image (`header` and its payload `src`) into `dst`
/// (`width * height` bytes).
///
/// # Errors
/// An unknown encoding or a payload that does not match the header, named with the frame and image.
pub fn gray_of_image(header: &ImageHeader, src: &[u8], dst: &mut [u8]) -> Result<(), GrayError> {
    let frame = |cause: GrayError| GrayError::Frame {
        frame: header.stamp.frame,
        image: header.name().to_owned(),
        cause: Box::new(cause),
    };
    let encoding = Encoding::from_u32(header.encoding).ok_or_else(|| frame(GrayError::UnknownEncoding(header.encoding)))?;
    let (width, height, step) = (header.width as usize, header.height as usize, header.step as usize);
    gray_into(encoding, width, height, step, src, dst).map_err(frame)
}

/// Writes the 8-bit grey version of `src` (rows of `step` bytes in `encoding`) into `dst` (`width * height` bytes).
///
/// RGB uses the integer BT.601 luma `(77 R + 150 G + 29 B + 128) >> 8`, identical on every machine; 16-bit samples
/// keep their high byte.
///
/// # Errors
/// When `src` is shorter than `step * height` or `dst` is not `width * height` long.
pub fn gray_into(encoding: Encoding, width: usize, height: usize, step: usize, src: &[u8], dst: &mut [u8]) -> Result<(), GrayError> {
    let bpp = encoding.bytes_per_pixel();
    if step < width * bpp || src.len() < step * height || dst.len() != width * height {
        return Err(GrayError::Size {
            encoding: encoding.name(),
            width,
            height,
            step,
            have: src.len(),
            need: step * height,
        });
    }
    let hi = |p: &[u8], i: usize| u16::from_ne_bytes([p[2 * i], p[2 * i + 1]]) >> 8;
    for (row, out) in dst.chunks_exact_mut(width.max(1)).enumerate().take(height) {
        let px = &src[row * step..row * step + width * bpp];
        match encoding {
            Encoding::Mono8 => out.copy_from_slice(px),
            Encoding::Rgb8 => {
                for (o, c) in out.iter_mut().zip(px.chunks_exact(3)) {
                    *o = luma(c[0] as u32, c[1] as u32, c[2] as u32);
                }
            }
            Encoding::Mono16 => {
                for (i, o) in out.iter_mut().enumerate() {
                    *o = hi(px, i) as u8;
                }
            }
            Encoding::Rgb16 => {
                for (i, o) in out.iter_mut().enumerate() {
                    *o = luma(hi(px, 3 * i) as u32, hi(px, 3 * i + 1) as u32, hi(px, 3 * i + 2) as u32);
                }
            }
        }
    }
    Ok(())
}

fn luma(r: u32, g: u32, b: u32) -> u8 {
    ((77 * r + 150 * g + 29 * b + 128) >> 8) as u8
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rgb_white_and_black_map_to_extremes_and_mono_is_copied() {
        let src = [255, 255, 255, 0, 0, 0, 255, 0, 0];
        let mut dst = [0u8; 3];
        gray_into(Encoding::Rgb8, 3, 1, 9, &src, &mut dst).unwrap();
        assert_eq!(dst, [255, 0, 77]);
        let mut dst = [0u8; 2];
        gray_into(Encoding::Mono8, 2, 1, 4, &[9, 8, 7, 6], &mut dst).unwrap();
        assert_eq!(dst, [9, 8]);
    }

    #[test]
    fn short_payloads_are_errors() {
        let mut dst = [0u8; 4];
        assert!(gray_into(Encoding::Rgb8, 2, 2, 6, &[0; 11], &mut dst).is_err());
    }
}
