//! Images recorded compressed (`[record] images = "png" | "jpeg"`): the `Image` message with its pixels replaced by
//! a PNG or JPEG file, on a channel of schema [`COMPRESSED_IMAGE`] whose metadata [`IMAGE_FORMAT_KEY`] names the
//! format. Every reader restores the `Image` message ([`restore`]) before a graph or a tool sees it: from PNG byte
//! for byte (a replay stays identical), from JPEG with JPEG's loss.
//!
//! A PNG holds the pixels in the image's own colour type when rows are unpadded; padded rows (or a payload the
//! header does not describe) go in as a grey image one byte per pixel and `step` wide, so that every payload
//! survives, padding included.
use anyhow::{bail, Context, Result};
use image::codecs::jpeg::JpegEncoder;
use image::codecs::png::{CompressionType, FilterType, PngEncoder};
use image::{ExtendedColorType, ImageEncoder};
use lineflow_messages::schema::{decode_view, encode, read_pod, Decoded};
use lineflow_messages::{Encoding, ImageHeader, MessageKind};

/// Schema name of a compressed image channel.
pub const COMPRESSED_IMAGE: &str = "lineflow_msgs/msg/CompressedImage";
/// Channel metadata key naming the file format of a compressed image channel (`png` or `jpeg`).
pub const IMAGE_FORMAT_KEY: &str = "lineflow.image_format";

/// The ros2msg text of [`COMPRESSED_IMAGE`]: `Image`'s fields, `data` holding a file.
pub fn compressed_image_schema() -> String {
    format!(
        "# lineflow_msgs/msg/Image with `data` holding the pixels as a PNG or JPEG file; the channel metadata\n\
         # '{IMAGE_FORMAT_KEY}' names the format. width, height, step and encoding describe the restored pixels.\n{}",
        MessageKind::Image.schema().ros2msg()
    )
}

pub use lineflow_messages::image::{ImageFormat, DEFAULT_JPEG_QUALITY};

/// The chunk compression that suits a recording of images stored as `format`: none for raw images (they barely
/// compress and it would halve the recorder's throughput), zstd once they are compressed (the other topics then make
/// most of the file).
pub fn chunk_compression(format: ImageFormat) -> crate::Compression {
    match format {
        ImageFormat::Raw => crate::Compression::None,
        ImageFormat::Png | ImageFormat::Jpeg => crate::Compression::Zstd,
    }
}

/// Reusable buffers of a compressor.
#[derive(Default)]
pub struct ImageCompressor {
    scratch: Decoded,
    file: Vec<u8>,
}

impl ImageCompressor {
    /// The compressed form of an `Image` message's CDR, into `out`.
    ///
    /// # Errors
    /// When `cdr` is not an `Image` message or the encoder fails.
    pub fn compress(&mut self, cdr: &[u8], format: ImageFormat, jpeg_quality: u8, out: &mut Vec<u8>) -> Result<()> {
        let (header, payload) = decode_view(MessageKind::Image, cdr, &mut self.scratch).context("not an Image message")?;
        pack(header, payload, format, jpeg_quality, &mut self.file, out)
    }

    /// [`compress`](Self::compress) of an `Image` message given as its header's bytes and its pixels, as a
    /// subscriber holds it: no CDR of the raw image is made first.
    ///
    /// # Errors
    /// When the encoder fails.
    pub fn compress_parts(
        &mut self,
        header: &[u8],
        payload: &[u8],
        format: ImageFormat,
        jpeg_quality: u8,
        out: &mut Vec<u8>,
    ) -> Result<()> {
        pack(header, payload, format, jpeg_quality, &mut self.file, out)
    }
}

/// An `Image` message with its pixels packed as `format`, into `out`; `file` holds the packed pixels on the way.
fn pack(header: &[u8], payload: &[u8], format: ImageFormat, jpeg_quality: u8, file: &mut Vec<u8>, out: &mut Vec<u8>) -> Result<()> {
    let h: ImageHeader = read_pod(header);
    file.clear();
    let natural = natural_color(&h, payload.len());
    match (format, natural) {
        (ImageFormat::Jpeg, Some(color @ (ExtendedColorType::L8 | ExtendedColorType::Rgb8))) => {
            JpegEncoder::new_with_quality(&mut *file, jpeg_quality.clamp(1, 100))
                .write_image(payload, h.width, h.height, color)
                .context("JPEG encoding")?;
        }
        (ImageFormat::Raw, _) => bail!("raw images are not compressed"),
        _ => {
            // Fast deflate with per-row adaptive filters: 2.5-3× smaller than raw on rendered façades at the
            // recorder's speed (`lineflow bench record`); the default level is several times slower.
            let encoder = PngEncoder::new_with_quality(&mut *file, CompressionType::Fast, FilterType::Adaptive);
            let (w, ht, color) = match natural {
                Some(color) => (h.width, h.height, color),
                None => grey_of(&h, payload.len()),
            };
            encoder.write_image(payload, w, ht, color).context("PNG encoding")?;
        }
    }
    encode(MessageKind::Image, header, file, out);
    Ok(())
}

/// The colour type that holds `payload` as an image of the header's size, when rows are unpadded.
fn natural_color(h: &ImageHeader, payload_len: usize) -> Option<ExtendedColorType> {
    let enc = h.encoding()?;
    let tight = h.width as usize * enc.bytes_per_pixel();
    if h.step as usize != tight || payload_len != h.payload_len() || h.width == 0 || h.height == 0 {
        return None;
    }
    Some(match enc {
        Encoding::Mono8 => ExtendedColorType::L8,
        Encoding::Rgb8 => ExtendedColorType::Rgb8,
        Encoding::Mono16 => ExtendedColorType::L16,
        Encoding::Rgb16 => ExtendedColorType::Rgb16,
    })
}

/// Any payload as a grey image: `step` bytes wide when the rows are whole, else one row.
fn grey_of(h: &ImageHeader, payload_len: usize) -> (u32, u32, ExtendedColorType) {
    let step = h.step as usize;
    if step > 0 && payload_len > 0 && payload_len.is_multiple_of(step) {
        (h.step, (payload_len / step) as u32, ExtendedColorType::L8)
    } else {
        (payload_len.max(1) as u32, 1, ExtendedColorType::L8)
    }
}

/// The `Image` message's CDR from its compressed form, into `out`.
///
/// # Errors
/// When the message or its file is damaged, or the file's size disagrees with the header.
pub fn restore(cdr: &[u8], scratch: &mut Decoded, out: &mut Vec<u8>) -> Result<()> {
    let (header, pixels) = restore_parts(cdr, scratch)?;
    encode(MessageKind::Image, &header, &pixels, out);
    Ok(())
}

/// [`restore`] as the `Image` message's header bytes and pixels, for a publisher that writes them into its own
/// sample: no CDR of the restored image is made.
///
/// # Errors
/// When the message or its file is damaged, or the file's size disagrees with the header.
pub fn restore_parts(cdr: &[u8], scratch: &mut Decoded) -> Result<(Vec<u8>, Vec<u8>)> {
    let (header, file) = decode_view(MessageKind::Image, cdr, scratch).context("not a compressed Image message")?;
    let h: ImageHeader = read_pod(header);
    let decoded = image::load_from_memory(file).context("the image file inside the message is damaged")?;
    let (w, ht) = (decoded.width(), decoded.height());
    let natural = natural_color(&h, h.payload_len()).filter(|_| (w, ht) == (h.width, h.height));
    let pixels: Vec<u8> = match (natural, decoded) {
        (Some(ExtendedColorType::L8), image::DynamicImage::ImageLuma8(b)) => b.into_raw(),
        (Some(ExtendedColorType::Rgb8), image::DynamicImage::ImageRgb8(b)) => b.into_raw(),
        (Some(ExtendedColorType::L16), image::DynamicImage::ImageLuma16(b)) => b.into_raw().iter().flat_map(|v| v.to_ne_bytes()).collect(),
        (Some(ExtendedColorType::Rgb16), image::DynamicImage::ImageRgb16(b)) => b.into_raw().iter().flat_map(|v| v.to_ne_bytes()).collect(),
        (None, image::DynamicImage::ImageLuma8(b)) if grey_of(&h, w as usize * ht as usize) == (w, ht, ExtendedColorType::L8) => {
            b.into_raw()
        }
        (_, d) => bail!(
            "a {w}×{ht} {:?} file for a {}×{} image of encoding {}",
            d.color(),
            h.width,
            h.height,
            h.encoding
        ),
    };
    Ok((header.to_vec(), pixels))
}

/// The restored message's size without restoring it: what a graph edge must carry.
pub fn restored_len(cdr: &[u8]) -> Option<u64> {
    let mut scratch = Decoded::default();
    let (header, file) = decode_view(MessageKind::Image, cdr, &mut scratch).ok()?;
    let h: ImageHeader = read_pod(header);
    // `data` is the last field, a byte sequence without padding after it.
    Some((cdr.len() - file.len()) as u64 + h.payload_len() as u64)
}

/// A recorded message's size as a graph carries it: a compressed image's restored size, any other message's own.
pub fn carried_len(data: &[u8], compressed: bool) -> u64 {
    compressed.then(|| restored_len(data)).flatten().unwrap_or(data.len() as u64)
}

#[cfg(test)]
mod tests {
    use super::*;
    use lineflow_messages::schema::bytes_of;
    use lineflow_messages::Stamp;

    fn image(width: u32, height: u32, step: u32, enc: Encoding, seed: u8) -> Vec<u8> {
        let h = ImageHeader {
            stamp: Stamp {
                frame: 3,
                capture_time_ns: 17,
                ..Default::default()
            },
            width,
            height,
            step,
            encoding: enc as u32,
            ..Default::default()
        };
        let pixels: Vec<u8> = (0..step * height).map(|i| (i as u8).wrapping_mul(seed) ^ (i >> 7) as u8).collect();
        let mut cdr = Vec::new();
        encode(MessageKind::Image, bytes_of(&h), &pixels, &mut cdr);
        cdr
    }

    #[test]
    fn png_restores_every_encoding_byte_for_byte_padding_included() {
        let mut c = ImageCompressor::default();
        let (mut packed, mut back, mut scratch) = (Vec::new(), Vec::new(), Decoded::default());
        for (w, ht, step, enc) in [
            (37, 21, 37, Encoding::Mono8),
            (37, 21, 111, Encoding::Rgb8),
            (37, 21, 74, Encoding::Mono16),
            (37, 21, 222, Encoding::Rgb16),
            (37, 21, 40, Encoding::Mono8), // padded rows
            (37, 21, 120, Encoding::Rgb8), // padded rows
        ] {
            let cdr = image(w, ht, step, enc, 7);
            c.compress(&cdr, ImageFormat::Png, 90, &mut packed).unwrap();
            restore(&packed, &mut scratch, &mut back).unwrap();
            assert!(back == cdr, "{enc:?} step {step}");
            assert_eq!(restored_len(&packed), Some(cdr.len() as u64), "{enc:?} step {step}");
        }
    }

    #[test]
    fn packing_the_parts_is_packing_the_message_and_restoring_the_parts_gives_them_back() {
        let cdr = image(37, 21, 111, Encoding::Rgb8, 5);
        let mut scratch = Decoded::default();
        let (header, payload) = decode_view(MessageKind::Image, &cdr, &mut scratch).unwrap();
        let (header, payload) = (header.to_vec(), payload.to_vec());
        let mut c = ImageCompressor::default();
        let (mut whole, mut parts) = (Vec::new(), Vec::new());
        c.compress(&cdr, ImageFormat::Png, 90, &mut whole).unwrap();
        c.compress_parts(&header, &payload, ImageFormat::Png, 90, &mut parts).unwrap();
        assert!(whole == parts);
        assert_eq!(restore_parts(&parts, &mut scratch).unwrap(), (header, payload));
    }

    #[test]
    fn jpeg_keeps_the_header_and_the_size_and_leaves_16_bit_images_lossless() {
        let mut c = ImageCompressor::default();
        let (mut packed, mut back, mut scratch) = (Vec::new(), Vec::new(), Decoded::default());
        let cdr = image(64, 48, 192, Encoding::Rgb8, 1);
        c.compress(&cdr, ImageFormat::Jpeg, 90, &mut packed).unwrap();
        restore(&packed, &mut scratch, &mut back).unwrap();
        assert_eq!(back.len(), cdr.len());
        let cdr = image(64, 48, 128, Encoding::Mono16, 3);
        c.compress(&cdr, ImageFormat::Jpeg, 90, &mut packed).unwrap();
        restore(&packed, &mut scratch, &mut back).unwrap();
        assert!(back == cdr, "16-bit images go in as PNG");
    }

    #[test]
    fn a_damaged_file_or_a_size_that_disagrees_is_an_error() {
        let mut c = ImageCompressor::default();
        let (mut packed, mut back, mut scratch) = (Vec::new(), Vec::new(), Decoded::default());
        let cdr = image(37, 21, 111, Encoding::Rgb8, 5);
        c.compress(&cdr, ImageFormat::Png, 90, &mut packed).unwrap();
        let mut cut = packed.clone();
        let n = cut.len();
        cut[n - 40] ^= 0xff;
        assert!(restore(&cut, &mut scratch, &mut back).is_err());
        // The same file under a header that claims another size.
        let other = image(38, 21, 114, Encoding::Rgb8, 5);
        let (h, _) = decode_view(MessageKind::Image, &other, &mut scratch).unwrap();
        let h = h.to_vec();
        let (_, file) = decode_view(MessageKind::Image, &packed, &mut scratch).unwrap();
        let file = file.to_vec();
        let mut lying = Vec::new();
        encode(MessageKind::Image, &h, &file, &mut lying);
        let err = restore(&lying, &mut scratch, &mut back).unwrap_err();
        assert!(format!("{err:#}").contains("for a 38×21 image"), "{err:#}");
    }
}
