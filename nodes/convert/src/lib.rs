//! The convert stage: one grey image per image, for stages that want 8-bit grey from any camera's encoding.
//! The pixels are converted straight into the outgoing message's shared memory
//! ([`lineflow_imaging::gray_of_image`]); the header says what they became.
#![warn(missing_docs)]

use lineflow_messages::{Encoding, ImageHeader};

/// The header of the grey image made from an image with header `h`: same stamp, size and name, `Mono8`, rows
/// without padding.
pub fn gray_header(h: &ImageHeader) -> ImageHeader {
    ImageHeader {
        step: h.width,
        encoding: Encoding::Mono8 as u32,
        ..*h
    }
}

/// Bytes of the grey image's payload.
pub fn gray_len(h: &ImageHeader) -> usize {
    h.width as usize * h.height as usize
}

#[cfg(test)]
mod tests {
    use super::*;
    use lineflow_messages::{fixed_str, Stamp};

    #[test]
    fn a_padded_rgb_frame_becomes_unpadded_grey_under_the_same_stamp_and_name() {
        let h = ImageHeader {
            stamp: Stamp {
                frame: 9,
                ..Stamp::default()
            },
            width: 2,
            height: 2,
            step: 8,
            encoding: Encoding::Rgb8 as u32,
            name: fixed_str("IMG_9.jpg"),
        };
        let g = gray_header(&h);
        assert_eq!((g.width, g.height, g.step, g.encoding), (2, 2, 2, Encoding::Mono8 as u32));
        assert_eq!((g.stamp.frame, g.name()), (9, "IMG_9.jpg"));
        // Rows of 6 pixel bytes and 2 bytes of padding.
        let rgb = [255, 255, 255, 0, 0, 0, 7, 7, 10, 20, 30, 40, 50, 60, 1, 1];
        let mut grey = vec![0; gray_len(&h)];
        lineflow_imaging::gray_of_image(&h, &rgb, &mut grey).unwrap();
        assert_eq!(grey, [255, 0, 18, 48]);
    }
}
