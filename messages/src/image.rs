//! `Image`: one camera frame, pixels as the payload bytes.
use iceoryx2::prelude::ZeroCopySend;

use crate::Stamp;

/// Pixel encodings of an [`ImageHeader`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[repr(u32)]
pub enum Encoding {
    /// 8-bit grey.
    Mono8 = 0,
    /// 8-bit RGB, interleaved.
    Rgb8 = 1,
    /// 16-bit grey, native-endian.
    Mono16 = 2,
    /// 16-bit RGB, interleaved, native-endian.
    Rgb16 = 3,
}

impl Encoding {
    /// Decodes the `encoding` field of a header.
    pub fn from_u32(v: u32) -> Option<Self> {
        Some(match v {
            0 => Self::Mono8,
            1 => Self::Rgb8,
            2 => Self::Mono16,
            3 => Self::Rgb16,
            _ => return None,
        })
    }
    /// Bytes per pixel.
    pub fn bytes_per_pixel(self) -> usize {
        match self {
            Self::Mono8 => 1,
            Self::Rgb8 => 3,
            Self::Mono16 => 2,
            Self::Rgb16 => 6,
        }
    }
    /// Name used by Foxglove and ROS (`mono8`, `rgb8`, `mono16`, `rgb16`).
    pub fn name(self) -> &'static str {
        match self {
            Self::Mono8 => "mono8",
            Self::Rgb8 => "rgb8",
            Self::Mono16 => "mono16",
            Self::Rgb16 => "rgb16",
        }
    }
}

/// Header of an `Image` message; the payload is `height` rows of `step` bytes.
#[derive(Debug, Clone, Copy, ZeroCopySend)]
#[repr(C)]
#[type_name("lineflow/Image/v1")]
pub struct ImageHeader {
    /// Common stamp.
    pub stamp: Stamp,
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// Bytes per row.
    pub step: u32,
    /// An [`Encoding`] as `u32`.
    pub encoding: u32,
    /// Source file name (NUL-padded UTF-8), empty for synthetic frames.
    pub name: [u8; 64],
}

impl Default for ImageHeader {
    fn default() -> Self {
        Self {
            stamp: Stamp::default(),
            width: 0,
            height: 0,
            step: 0,
            encoding: 0,
            name: [0; 64],
        }
    }
}

impl ImageHeader {
    /// The encoding, if the field holds a known one.
    pub fn encoding(&self) -> Option<Encoding> {
        Encoding::from_u32(self.encoding)
    }
    /// Source file name.
    pub fn name(&self) -> &str {
        crate::str_from_fixed(&self.name)
    }
    /// Payload bytes this header describes.
    pub fn payload_len(&self) -> usize {
        self.step as usize * self.height as usize
    }
}

/// A zero-copy view of an 8-bit grey image payload as an `image::ImageBuffer`.
///
/// Returns `None` when the encoding is not `Mono8`, rows are padded, or the payload is shorter than the header says.
pub fn as_gray8<'a>(header: &ImageHeader, payload: &'a [u8]) -> Option<::image::ImageBuffer<::image::Luma<u8>, &'a [u8]>> {
    if header.encoding() != Some(Encoding::Mono8) || header.step != header.width {
        return None;
    }
    ::image::ImageBuffer::from_raw(header.width, header.height, &payload[..header.payload_len().min(payload.len())])
}

/// A zero-copy view of an 8-bit RGB image payload as an `image::ImageBuffer`.
pub fn as_rgb8<'a>(header: &ImageHeader, payload: &'a [u8]) -> Option<::image::ImageBuffer<::image::Rgb<u8>, &'a [u8]>> {
    if header.encoding() != Some(Encoding::Rgb8) || header.step != header.width * 3 {
        return None;
    }
    ::image::ImageBuffer::from_raw(header.width, header.height, &payload[..header.payload_len().min(payload.len())])
}

/// How images are packed where they are stored or sent (`[record] images`, `[bridge] images`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Deserialize, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum ImageFormat {
    /// The pixels as the graph carries them (fastest, largest).
    #[default]
    Raw,
    /// Lossless PNG: the pixels come back byte for byte.
    Png,
    /// JPEG at a quality: smallest, lossy (the pixels come back changed); 16-bit images go in as PNG.
    Jpeg,
}

/// JPEG quality unless set.
pub const DEFAULT_JPEG_QUALITY: u8 = 90;

impl ImageFormat {
    /// The format's name (`png`, `jpeg`); `None` for raw.
    pub fn name(self) -> Option<&'static str> {
        match self {
            Self::Raw => None,
            Self::Png => Some("png"),
            Self::Jpeg => Some("jpeg"),
        }
    }
}

impl std::str::FromStr for ImageFormat {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        Ok(match s {
            "raw" => Self::Raw,
            "png" => Self::Png,
            "jpeg" => Self::Jpeg,
            _ => return Err(format!("unknown image format '{s}' (raw, png, jpeg)")),
        })
    }
}
