//! Decoding image files into message pixels: 8- and 16-bit, grey or RGB, EXIF orientation applied.
use std::path::{Path, PathBuf};

use image::{DynamicImage, ImageDecoder, ImageReader};
use lineflow_messages::Encoding;

/// A decoded image ready to publish.
#[derive(Debug, Clone)]
pub struct DecodedImage {
    /// Width in pixels after orientation.
    pub width: u32,
    /// Height in pixels after orientation.
    pub height: u32,
    /// Pixel encoding.
    pub encoding: Encoding,
    /// Rows of `width * bytes_per_pixel` bytes, native-endian for 16-bit.
    pub bytes: Vec<u8>,
}

/// Why an image file could not be decoded; each names the file.
#[derive(Debug, thiserror::Error)]
pub enum DecodeError {
    /// The file cannot be opened or read.
    #[error("{}: cannot {what}: {source}", path.display())]
    Io {
        /// The file.
        path: PathBuf,
        /// "open" or "read".
        what: &'static str,
        /// The cause.
        source: std::io::Error,
    },
    /// Not an image format the build decodes.
    #[error("{}: not a supported image: {source}", path.display())]
    Unsupported {
        /// The file.
        path: PathBuf,
        /// The cause.
        source: image::ImageError,
    },
    /// The header claims more pixels than any camera makes (a damaged or hostile file).
    #[error("{}: the header claims {width} x {height} pixels ({bytes} bytes decoded), more than the {MAX_DECODED_BYTES} bytes lineflow decodes: a damaged file?", path.display())]
    TooLarge {
        /// The file.
        path: PathBuf,
        /// Width the header claims.
        width: u32,
        /// Height the header claims.
        height: u32,
        /// Bytes the decoded pixels would take.
        bytes: u64,
    },
    /// A JPEG far too short for the pixels its header claims. Decoding one fills the missing pixels, which took 1.9 s
    /// for 1,177 bytes claiming 73 MP (found by the coverage-guided fuzzer, `fuzz/run`).
    #[error("{}: its {bytes} bytes cannot hold the {width} x {height} pixels the header claims (a JPEG codes every 8 x 8 block in at least one bit): a truncated or damaged file", path.display())]
    TooShort {
        /// The file.
        path: PathBuf,
        /// Width the header claims.
        width: u32,
        /// Height the header claims.
        height: u32,
        /// The file's size.
        bytes: u64,
    },
    /// The pixels cannot be decoded.
    #[error("{}: corrupt or truncated image: {source}", path.display())]
    Corrupt {
        /// The file.
        path: PathBuf,
        /// The cause.
        source: image::ImageError,
    },
}

/// Most bytes an image's decoded pixels may take: 1 GiB, a 170 MP 16-bit RGB frame. image 0.25 checks its
/// allocation limit against a TIFF's intermediate buffers but not against the pixels themselves, so a damaged
/// header asked for 79 GB and aborted the process (found by `lineflow bench fuzz`).
pub const MAX_DECODED_BYTES: u64 = 1 << 30;

/// Decodes `path`, applying its EXIF orientation. Alpha is dropped; grey stays grey.
///
/// # Errors
/// The file cannot be opened or is not a complete, supported image.
pub fn decode_file(path: &Path) -> Result<DecodedImage, DecodeError> {
    decode_oriented(path, None)
}

/// Decodes `path` for a camera whose sensor is `sensor` (width, height) pixels: with its EXIF orientation applied,
/// unless the image as stored, and not the turned one, has the sensor's size. A portrait photo from a landscape
/// camera is stored as the sensor recorded it and tagged "turn 90°"; the camera model (principal point,
/// distortion) belongs to the sensor's raster, so that raster is used and the pose takes up the turn.
///
/// # Errors
/// As [`decode_file`].
pub fn decode_file_for(path: &Path, sensor: (u32, u32)) -> Result<DecodedImage, DecodeError> {
    decode_oriented(path, Some(sensor))
}

fn decode_oriented(path: &Path, sensor: Option<(u32, u32)>) -> Result<DecodedImage, DecodeError> {
    let io = |what| {
        move |source| DecodeError::Io {
            path: path.to_owned(),
            what,
            source,
        }
    };
    let reader = ImageReader::open(path)
        .map_err(io("open"))?
        .with_guessed_format()
        .map_err(io("read"))?;
    let jpeg = reader.format() == Some(image::ImageFormat::Jpeg);
    let mut decoder = reader.into_decoder().map_err(|source| DecodeError::Unsupported {
        path: path.to_owned(),
        source,
    })?;
    if jpeg {
        let (width, height) = decoder.dimensions();
        let bytes = std::fs::metadata(path).map_err(io("read"))?.len();
        // Huffman coding spends at least one bit on every 8 x 8 block's DC term: pixels / 512 bytes at the least.
        // Half of that leaves room for headers' rounding and keeps every real file.
        if bytes < u64::from(width) * u64::from(height) / 1024 {
            return Err(DecodeError::TooShort {
                path: path.to_owned(),
                width,
                height,
                bytes,
            });
        }
    }
    if decoder.total_bytes() > MAX_DECODED_BYTES {
        let (width, height) = decoder.dimensions();
        return Err(DecodeError::TooLarge {
            path: path.to_owned(),
            width,
            height,
            bytes: decoder.total_bytes(),
        });
    }
    let mut orientation = decoder.orientation().unwrap_or(image::metadata::Orientation::NoTransforms);
    let stored = decoder.dimensions();
    if sensor.is_some_and(|s| s != shown_size(stored, orientation) && s == stored) {
        orientation = image::metadata::Orientation::NoTransforms;
    }
    let mut img = DynamicImage::from_decoder(decoder).map_err(|source| DecodeError::Corrupt {
        path: path.to_owned(),
        source,
    })?;
    img.apply_orientation(orientation);
    Ok(from_dynamic(img))
}

/// The size of an image of `stored` (width, height) once `orientation` is applied.
fn shown_size(stored: (u32, u32), orientation: image::metadata::Orientation) -> (u32, u32) {
    use image::metadata::Orientation::*;
    match orientation {
        Rotate90 | Rotate270 | Rotate90FlipH | Rotate270FlipH => (stored.1, stored.0),
        _ => stored,
    }
}

/// An image's size after its EXIF orientation, from its header alone.
///
/// # Errors
/// The file cannot be opened or is no supported image.
pub fn image_size(path: &Path) -> Result<(u32, u32), DecodeError> {
    let mut decoder = ImageReader::open(path)
        .and_then(|r| r.with_guessed_format())
        .map_err(|source| DecodeError::Io {
            path: path.to_owned(),
            what: "open",
            source,
        })?
        .into_decoder()
        .map_err(|source| DecodeError::Unsupported {
            path: path.to_owned(),
            source,
        })?;
    let orientation = decoder.orientation().unwrap_or(image::metadata::Orientation::NoTransforms);
    Ok(shown_size(decoder.dimensions(), orientation))
}

/// Converts a decoded image into message pixels.
pub fn from_dynamic(img: DynamicImage) -> DecodedImage {
    let (width, height) = (img.width(), img.height());
    let (encoding, bytes) = match img {
        DynamicImage::ImageLuma8(b) => (Encoding::Mono8, b.into_raw()),
        DynamicImage::ImageRgb8(b) => (Encoding::Rgb8, b.into_raw()),
        DynamicImage::ImageLuma16(b) => (Encoding::Mono16, u16_bytes(b.into_raw())),
        DynamicImage::ImageRgb16(b) => (Encoding::Rgb16, u16_bytes(b.into_raw())),
        DynamicImage::ImageLumaA8(_) => (Encoding::Mono8, img.to_luma8().into_raw()),
        DynamicImage::ImageLumaA16(_) => (Encoding::Mono16, u16_bytes(img.to_luma16().into_raw())),
        DynamicImage::ImageRgba16(_) => (Encoding::Rgb16, u16_bytes(img.to_rgb16().into_raw())),
        other => (Encoding::Rgb8, other.to_rgb8().into_raw()),
    };
    DecodedImage {
        width,
        height,
        encoding,
        bytes,
    }
}

fn u16_bytes(v: Vec<u16>) -> Vec<u8> {
    v.into_iter().flat_map(u16::to_ne_bytes).collect()
}

pub use lineflow_formats::project::is_image_name;

/// Whether the bytes of a file end as a complete image of its kind does (JPEG end-of-image marker, PNG `IEND`
/// chunk). TIFF has no trailer; for it the answer is `true` and the watcher relies on a stable size.
pub fn looks_complete(bytes: &[u8]) -> bool {
    if bytes.starts_with(&[0xFF, 0xD8]) {
        let tail = &bytes[bytes.len().saturating_sub(64)..];
        return tail.windows(2).any(|w| w == [0xFF, 0xD9]);
    }
    if bytes.starts_with(b"\x89PNG") {
        return bytes.len() >= 12 && &bytes[bytes.len() - 8..bytes.len() - 4] == b"IEND";
    }
    !bytes.is_empty()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_header_claiming_gigabytes_is_refused_before_decoding() {
        // The TIFF `lineflow bench fuzz` made: its header claims 79 GB of pixels; decoding it aborted the process.
        let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/huge-header.tif");
        let e = decode_file(&path).unwrap_err();
        assert!(matches!(e, DecodeError::TooLarge { .. }), "{e}");
        assert!(e.to_string().contains("huge-header.tif"), "{e}");
    }

    #[test]
    fn a_jpeg_far_too_short_for_its_header_is_refused_before_decoding() {
        let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../fuzz/regressions/jpeg/huge-header-slow.jpg");
        let e = decode_file(&path).unwrap_err();
        assert!(
            matches!(
                e,
                DecodeError::TooShort {
                    width: 23824,
                    height: 3072,
                    bytes: 1177,
                    ..
                }
            ),
            "{e}"
        );
        assert!(e.to_string().contains("huge-header-slow.jpg"), "{e}");
    }

    #[test]
    fn exif_orientation_is_applied() {
        // A 2x1 JPEG tagged "rotate 90° clockwise" must come out 1x2.
        let dir = tempfile::tempdir().unwrap();
        let img = image::RgbImage::from_fn(16, 8, |x, _| image::Rgb([if x < 8 { 0 } else { 255 }, 0, 0]));
        let mut jpeg = Vec::new();
        image::codecs::jpeg::JpegEncoder::new_with_quality(&mut jpeg, 95)
            .encode_image(&img)
            .unwrap();
        // APP1 Exif segment with one IFD0 entry: Orientation (0x0112) = 6.
        let tiff: Vec<u8> = [
            b"MM\x00\x2a\x00\x00\x00\x08".as_slice(),
            &[0, 1],
            &[0x01, 0x12, 0, 3, 0, 0, 0, 1, 0, 6, 0, 0],
            &[0, 0, 0, 0],
        ]
        .concat();
        let payload = [b"Exif\x00\x00".as_slice(), &tiff].concat();
        let mut app1 = vec![0xFF, 0xE1];
        app1.extend_from_slice(&((payload.len() + 2) as u16).to_be_bytes());
        app1.extend_from_slice(&payload);
        let tagged = [&jpeg[..2], &app1[..], &jpeg[2..]].concat();
        let p = dir.path().join("o.jpg");
        std::fs::write(&p, tagged).unwrap();
        let sut = decode_file(&p).unwrap();
        assert_eq!((sut.width, sut.height), (8, 16));
        // For a 16 x 8 sensor the photo is used as the sensor recorded it; for an 8 x 16 one, turned.
        let raw = decode_file_for(&p, (16, 8)).unwrap();
        assert_eq!((raw.width, raw.height), (16, 8));
        assert_eq!(raw.bytes[..3], [0, 0, 0][..], "the left half is black as stored");
        let turned = decode_file_for(&p, (8, 16)).unwrap();
        assert_eq!((turned.width, turned.height), (8, 16));
        let other = decode_file_for(&p, (20, 10)).unwrap();
        assert_eq!((other.width, other.height), (8, 16), "no match: as shown, for the caller to refuse");
    }

    #[test]
    fn truncated_files_are_errors_not_panics() {
        let dir = tempfile::tempdir().unwrap();
        let img = image::GrayImage::from_fn(64, 64, |x, y| image::Luma([(x * y) as u8]));
        let p = dir.path().join("t.png");
        img.save(&p).unwrap();
        let bytes = std::fs::read(&p).unwrap();
        assert!(looks_complete(&bytes));
        std::fs::write(&p, &bytes[..bytes.len() / 2]).unwrap();
        assert!(!looks_complete(&bytes[..bytes.len() / 2]));
        let err = decode_file(&p).unwrap_err();
        assert!(matches!(err, DecodeError::Corrupt { .. }), "{err}");
        assert!(err.to_string().contains("t.png: corrupt or truncated image"), "{err}");
    }

    #[test]
    fn sixteen_bit_stays_sixteen_bit() {
        let dir = tempfile::tempdir().unwrap();
        let img = image::ImageBuffer::<image::Luma<u16>, _>::from_fn(4, 3, |x, _| image::Luma([x as u16 * 1000]));
        let p = dir.path().join("s.png");
        img.save(&p).unwrap();
        let sut = decode_file(&p).unwrap();
        assert_eq!(sut.encoding, Encoding::Mono16);
        assert_eq!(sut.bytes.len(), 4 * 3 * 2);
    }
}
