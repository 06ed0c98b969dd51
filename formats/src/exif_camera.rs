//! A nominal camera from a photo's EXIF: the focal length, and the pixel pitch from the focal-plane resolution or,
//! failing that, from the 35 mm equivalent focal length. No principal point offset and no distortion: a starting
//! point for a camera, not a calibration.
use std::path::Path;

use exif::{In, Tag, Value};

use crate::foreign_file::ForeignFileError;

/// 35 mm film's diagonal, mm (36 × 24).
const FULL_FRAME_DIAGONAL_MM: f64 = 43.266_615_305_567_87;

/// What a photo's EXIF says of its camera.
#[derive(Debug, Clone, PartialEq)]
pub struct ExifCamera {
    /// Make and model, as far as given.
    pub name: String,
    /// Focal length, mm.
    pub focal_mm: f64,
    /// Pixel pitch of the image as stored, mm.
    pub pixel_size_mm: f64,
    /// Where the pitch came from.
    pub pitch_from: String,
    /// Disagreements and assumptions, for the user to read.
    pub notes: Vec<String>,
}

/// The nominal camera of an image of `width × height` pixels (after its EXIF orientation) from its EXIF.
///
/// # Errors
/// No EXIF, no focal length, or neither a focal-plane resolution nor a 35 mm equivalent to give the pixel pitch.
pub fn exif_camera(path: &Path, width: u32, height: u32) -> Result<ExifCamera, ForeignFileError> {
    let fail = |message: String| ForeignFileError {
        path: path.to_owned(),
        message,
    };
    let file = std::fs::File::open(path).map_err(|e| fail(e.to_string()))?;
    let exif = exif::Reader::new()
        .read_from_container(&mut std::io::BufReader::new(file))
        .map_err(|e| fail(format!("no EXIF to start a camera from ({e}): give a camera.toml")))?;
    let number = |tag: Tag| -> Option<f64> {
        let field = exif.get_field(tag, In::PRIMARY)?;
        let v = match &field.value {
            Value::Rational(r) => r.first().map(|r| r.to_f64()),
            Value::SRational(r) => r.first().map(|r| r.to_f64()),
            other => other.get_uint(0).map(f64::from),
        }?;
        (v.is_finite() && v > 0.0).then_some(v)
    };
    let text = |tag: Tag| -> Option<String> {
        let field = exif.get_field(tag, In::PRIMARY)?;
        match &field.value {
            Value::Ascii(parts) => parts.first().map(|b| String::from_utf8_lossy(b).trim().to_owned()),
            _ => None,
        }
    };
    let name = [text(Tag::Make), text(Tag::Model)]
        .into_iter()
        .flatten()
        .collect::<Vec<_>>()
        .join(" ");
    let focal_mm = number(Tag::FocalLength).ok_or_else(|| fail("its EXIF gives no focal length: give a camera.toml".into()))?;
    let (long_side, diagonal) = (width.max(height) as f64, (width as f64).hypot(height as f64));
    // The focal-plane resolution counts pixels of the sensor's full readout; a scaled-down image has larger pixels.
    let stored = [Tag::PixelXDimension, Tag::PixelYDimension].map(number);
    let readout = stored.iter().flatten().fold(0.0f64, |a, &b| a.max(b));
    let scale = if readout > 0.0 { readout / long_side } else { 1.0 };
    let from_plane = number(Tag::FocalPlaneXResolution).and_then(|per_unit| {
        let unit_mm = match number(Tag::FocalPlaneResolutionUnit).map(|u| u as u32) {
            Some(3) => 10.0,
            Some(4) => 1.0,
            _ => 25.4,
        };
        let pitch = unit_mm / per_unit * scale;
        (pitch > 1e-4 && pitch < 0.1).then_some(pitch)
    });
    let from_35mm = number(Tag::FocalLengthIn35mmFilm).map(|f35| focal_mm / f35 * FULL_FRAME_DIAGONAL_MM / diagonal);
    if let Some(p) = from_35mm.filter(|p| !(1e-4..0.1).contains(p)) {
        return Err(fail(format!(
            "its 35 mm equivalent gives {p} mm pixels for a {width}x{height} image: no camera's; give a camera.toml"
        )));
    }
    let mut notes = Vec::new();
    let (pixel_size_mm, pitch_from) = match (from_plane, from_35mm) {
        (Some(p), Some(q)) => {
            if (p / q - 1.0).abs() > 0.05 {
                notes.push(format!(
                    "the focal-plane resolution gives {p:.5} mm pixels, the 35 mm equivalent {q:.5} mm: the first is taken"
                ));
            }
            (p, "the focal-plane resolution")
        }
        (Some(p), None) => (p, "the focal-plane resolution"),
        (None, Some(q)) => (q, "the 35 mm equivalent focal length"),
        (None, None) => {
            return Err(fail(
                "its EXIF gives neither the focal-plane resolution nor a 35 mm equivalent focal length, so the pixel \
                 pitch is unknown: give a camera.toml (or `lineflow camera import --pixel-size-mm` on a calibration)"
                    .into(),
            ))
        }
    };
    Ok(ExifCamera {
        name,
        focal_mm,
        pixel_size_mm,
        pitch_from: pitch_from.into(),
        notes,
    })
}

/// What a camera writes of itself into a photo's EXIF, as far as [`exif_camera`] reads it.
#[derive(Debug, Clone, PartialEq)]
pub struct ExifTags {
    /// Make.
    pub make: String,
    /// Model.
    pub model: String,
    /// The focal length as the lens marks it, mm.
    pub focal_mm: f64,
    /// The sensor's pixel pitch, mm (written as the focal-plane resolution, pixels per mm).
    pub pixel_size_mm: f64,
    /// The image's size, pixels.
    pub width: u32,
    /// The image's height, pixels.
    pub height: u32,
}

/// `jpeg` (a complete JPEG file) with `tags` in an EXIF APP1 segment after its start marker (kamadak-exif's
/// writer); `None` when `jpeg` does not start with one or the tags cannot be encoded.
pub fn with_exif(jpeg: &[u8], tags: &ExifTags) -> Option<Vec<u8>> {
    use exif::experimental::Writer;
    use exif::{Field, Rational};
    if jpeg.get(..2) != Some(&[0xFF, 0xD8]) {
        return None;
    }
    // Thousandths: a marked focal length and a pitch in pixels per mm need no more.
    let thousandths = |v: f64| Value::Rational(vec![Rational::from(((v * 1000.0).round() as u32, 1000))]);
    let field = |tag, value| Field {
        tag,
        ifd_num: In::PRIMARY,
        value,
    };
    let fields = [
        field(Tag::Make, Value::Ascii(vec![tags.make.as_bytes().to_vec()])),
        field(Tag::Model, Value::Ascii(vec![tags.model.as_bytes().to_vec()])),
        field(Tag::FocalLength, thousandths(tags.focal_mm)),
        field(Tag::FocalPlaneXResolution, thousandths(1.0 / tags.pixel_size_mm)),
        field(Tag::FocalPlaneYResolution, thousandths(1.0 / tags.pixel_size_mm)),
        // 4: millimetres (EXIF 2.3).
        field(Tag::FocalPlaneResolutionUnit, Value::Short(vec![4])),
        field(Tag::PixelXDimension, Value::Long(vec![tags.width])),
        field(Tag::PixelYDimension, Value::Long(vec![tags.height])),
    ];
    let mut writer = Writer::new();
    for f in &fields {
        writer.push_field(f);
    }
    let mut tiff = std::io::Cursor::new(Vec::new());
    writer.write(&mut tiff, false).ok()?;
    let payload = [b"Exif\x00\x00".as_slice(), &tiff.into_inner()].concat();
    let length = u16::try_from(payload.len() + 2).ok()?;
    let mut out = vec![0xFF, 0xD8, 0xFF, 0xE1];
    out.extend(length.to_be_bytes());
    out.extend(payload);
    out.extend(&jpeg[2..]);
    Some(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A TIFF-structured EXIF block (big-endian): IFD0 with Make and the Exif IFD pointer; the Exif IFD with the
    /// given (tag, type, value) entries, RATIONAL values as (numerator, 1).
    fn exif_block(entries: &[(u16, u16, u32)]) -> Vec<u8> {
        let mut t: Vec<u8> = b"MM\x00\x2a\x00\x00\x00\x08".to_vec();
        // IFD0 at 8: two entries (Make "LF", ExifIFD pointer), next IFD 0.
        let exif_ifd = 8 + 2 + 2 * 12 + 4;
        t.extend([0, 2]);
        t.extend([0x01, 0x0F, 0, 2, 0, 0, 0, 3, b'L', b'F', 0, 0]);
        t.extend([0x87, 0x69, 0, 4, 0, 0, 0, 1]);
        t.extend((exif_ifd as u32).to_be_bytes());
        t.extend([0, 0, 0, 0]);
        let data_at = exif_ifd + 2 + entries.len() * 12 + 4;
        let mut data = Vec::new();
        t.extend((entries.len() as u16).to_be_bytes());
        for &(tag, kind, value) in entries {
            t.extend(tag.to_be_bytes());
            t.extend(kind.to_be_bytes());
            t.extend(1u32.to_be_bytes());
            if kind == 5 {
                t.extend(((data_at + data.len()) as u32).to_be_bytes());
                data.extend(value.to_be_bytes());
                data.extend(1u32.to_be_bytes());
            } else if kind == 3 {
                t.extend((value as u16).to_be_bytes());
                t.extend([0, 0]);
            } else {
                t.extend(value.to_be_bytes());
            }
        }
        t.extend([0, 0, 0, 0]);
        t.extend(data);
        t
    }

    /// A small JPEG carrying `exif` in its APP1 segment.
    fn jpeg_with(exif: &[u8]) -> Vec<u8> {
        // The smallest baseline JPEG the decoders take is not needed here: the EXIF reader stops at APP1.
        let payload = [b"Exif\x00\x00".as_slice(), exif].concat();
        let mut out = vec![0xFF, 0xD8, 0xFF, 0xE1];
        out.extend(((payload.len() + 2) as u16).to_be_bytes());
        out.extend(payload);
        out.extend([0xFF, 0xD9]);
        out
    }

    fn camera_of(entries: &[(u16, u16, u32)], width: u32, height: u32) -> Result<ExifCamera, ForeignFileError> {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("IMG.jpg");
        std::fs::write(&p, jpeg_with(&exif_block(entries))).unwrap();
        exif_camera(&p, width, height)
    }

    const FOCAL_24: (u16, u16, u32) = (0x920A, 5, 24);

    #[test]
    fn the_pitch_comes_from_the_focal_plane_resolution_scaled_to_the_stored_image() {
        // 250 pixels per mm on a 6000-pixel readout, stored at 3000: 0.008 mm pixels.
        let c = camera_of(&[FOCAL_24, (0xA002, 4, 6000), (0xA20E, 5, 250), (0xA210, 3, 4)], 3000, 2000).unwrap();
        assert_eq!(c.focal_mm, 24.0);
        assert!((c.pixel_size_mm - 0.008).abs() < 1e-12, "{c:?}");
        assert_eq!(c.name, "LF");
    }

    #[test]
    fn else_from_the_35mm_equivalent() {
        // 24 mm on full frame (f35 = 24): the 36 × 24 mm sensor over 6000 × 4000 pixels, 0.006 mm each.
        let c = camera_of(&[FOCAL_24, (0xA405, 3, 24)], 6000, 4000).unwrap();
        assert!((c.pixel_size_mm - 0.006).abs() < 1e-9, "{c:?}");
        assert_eq!(c.pitch_from, "the 35 mm equivalent focal length");
    }

    #[test]
    fn what_with_exif_writes_is_read_back() {
        let tags = ExifTags {
            make: "lineflow".into(),
            model: "synthetic A55".into(),
            focal_mm: 18.0,
            pixel_size_mm: 0.016,
            width: 1474,
            height: 979,
        };
        // A real (1 × 1) JPEG, so that the image decoders take the file too.
        let mut jpeg = Vec::new();
        image::codecs::jpeg::JpegEncoder::new(&mut jpeg)
            .encode(&[128, 128, 128], 1, 1, image::ExtendedColorType::Rgb8)
            .unwrap();
        let file = with_exif(&jpeg, &tags).unwrap();
        assert!(image::load_from_memory(&file).is_ok());
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("IMG.jpg");
        std::fs::write(&p, &file).unwrap();
        let c = exif_camera(&p, 1474, 979).unwrap();
        assert_eq!(c.focal_mm, 18.0);
        assert!((c.pixel_size_mm - 0.016).abs() < 1e-9, "{c:?}");
        assert_eq!(c.name, "lineflow synthetic A55");
        assert!(with_exif(b"not a jpeg", &tags).is_none());
    }

    #[test]
    fn without_a_focal_length_or_a_pitch_the_error_says_what_is_missing() {
        let e = camera_of(&[(0xA405, 3, 24)], 600, 400).unwrap_err().to_string();
        assert!(e.contains("no focal length"), "{e}");
        let e = camera_of(&[FOCAL_24], 600, 400).unwrap_err().to_string();
        assert!(e.contains("pixel pitch is unknown"), "{e}");
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("bare.jpg");
        std::fs::write(&p, [0xFF, 0xD8, 0xFF, 0xD9]).unwrap();
        let e = exif_camera(&p, 10, 10).unwrap_err().to_string();
        assert!(e.contains("no EXIF"), "{e}");
    }
}
