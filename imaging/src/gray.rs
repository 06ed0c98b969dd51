//! 8-bit grey from any image message: what the convert stage's `gray` publishes and what every stage working on
//! grey values computes from the `images` topic when it is wired to it directly.
use lineflow_messages::{Encoding, ImageHeader};

/// Writes the 8-bit grey version of a received image (`header` and its payload `src`) into `dst`
/// (`width * height` bytes).
///
/// # Errors
/// An unknown encoding or a payload that does not match the header; the message names the frame and image.
pub fn gray_of_image(header: &ImageHeader, src: &[u8], dst: &mut [u8]) -> Result<(), String> {
    let why = |m: String| format!("frame {} ({}): {m}", header.stamp.frame, header.name());
    let encoding = Encoding::from_u32(header.encoding).ok_or_else(|| why(format!("unknown encoding {}", header.encoding)))?;
    gray_into(
        encoding,
        header.width as usize,
        header.height as usize,
        header.step as usize,
        src,
        dst,
    )
    .map_err(why)
}

/// Writes the 8-bit grey version of `src` (rows of `step` bytes in `encoding`) into `dst` (`width * height` bytes).
///
/// RGB uses the integer BT.601 luma `(77 R + 150 G + 29 B + 128) >> 8`, identical on every machine; 16-bit samples
/// keep their high byte.
///
/// # Errors
/// When `src` is shorter than `step * height` or `dst` is not `width * height` long.
pub fn gray_into(encoding: Encoding, width: usize, height: usize, step: usize, src: &[u8], dst: &mut [u8]) -> Result<(), String> {
    let bpp = encoding.bytes_per_pixel();
    if step < width * bpp || src.len() < step * height || dst.len() != width * height {
        return Err(format!(
            "{} image {width}x{height} with step {step}: payload has {} bytes, need {}",
            encoding.name(),
            src.len(),
            step * height
        ));
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
