//! One grey image's keypoints and descriptors laid out as the two parts of a `Keypoints` message, for each
//! implementation: what the process publishes per image, testable without one.
use lineflow_messages::{fixed_str, Keypoint, KeypointsHeader, Stamp};

use crate::orb::{orb, OrbFeature, OrbParams};
use crate::surf::{surf_in, Feature, SurfParams, SurfScratch};

/// A `Keypoints` message: its header, the keypoints, then `count × descriptor_len` descriptor values.
#[derive(Debug, Clone)]
pub struct Described<D> {
    /// The header (stamp, count, descriptor length and kind, detector).
    pub header: KeypointsHeader,
    /// The keypoints.
    pub keypoints: Vec<Keypoint>,
    /// Their descriptors, one after the other.
    pub descriptors: Vec<D>,
}

impl<D> Described<D> {
    fn new(stamp: Stamp, keypoints: Vec<Keypoint>, descriptors: Vec<D>, kind: u32, len: u32, detector: &str) -> Self {
        Described {
            header: KeypointsHeader {
                stamp,
                count: keypoints.len() as u32,
                descriptor_len: len,
                descriptor_kind: kind,
                detector: fixed_str(detector),
            },
            keypoints,
            descriptors,
        }
    }
}

/// `impl = "surf"`: 64 `f32` per keypoint. Keeps its scratch buffers between images.
#[derive(Debug, Default)]
pub struct SurfDescriber {
    params: SurfParams,
    scratch: SurfScratch,
}

impl SurfDescriber {
    /// A describer with these settings.
    pub fn new(params: SurfParams) -> Self {
        SurfDescriber {
            params,
            scratch: SurfScratch::default(),
        }
    }

    /// The message for one `width × height` grey image.
    pub fn describe(&mut self, stamp: Stamp, gray: &[u8], width: usize, height: usize) -> Described<f32> {
        let features = surf_in(&mut self.scratch, gray, width, height, &self.params);
        let keypoints = features.iter().map(surf_keypoint).collect();
        let descriptors = features.iter().flat_map(|f| f.descriptor).collect();
        Described::new(stamp, keypoints, descriptors, KeypointsHeader::FLOAT, 64, "surf")
    }
}

/// `impl = "orb"`: 32 bytes (256 bits) per keypoint.
pub fn describe_orb(params: &OrbParams, stamp: Stamp, gray: &[u8], width: usize, height: usize) -> Described<u8> {
    let features = orb(gray, width, height, params);
    let keypoints = features.iter().map(orb_keypoint).collect();
    let descriptors = features.iter().flat_map(|f| f.descriptor).collect();
    Described::new(stamp, keypoints, descriptors, KeypointsHeader::BINARY, 32, "orb")
}

fn surf_keypoint(f: &Feature) -> Keypoint {
    Keypoint {
        col: f.at.col,
        row: f.at.row,
        scale_px: f.at.scale,
        orientation_rad: f.orientation,
        response: f.at.response,
        laplacian_sign: f.at.laplacian_sign,
    }
}

fn orb_keypoint(f: &OrbFeature) -> Keypoint {
    Keypoint {
        col: f.col,
        row: f.row,
        scale_px: f.scale_px,
        orientation_rad: f.orientation,
        response: f.response,
        // ORB has no Laplacian; 0 lets the matcher compare every pair.
        laplacian_sign: 0,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Dark squares on a bright ground: corners for ORB, blobs for SURF.
    fn squares(w: usize, h: usize) -> Vec<u8> {
        (0..w * h)
            .map(|i| {
                let (x, y) = (i % w, i / w);
                if (x / 24 + y / 24) % 2 == 0 && x % 24 > 4 && y % 24 > 4 {
                    30
                } else {
                    220
                }
            })
            .collect()
    }

    fn stamp() -> Stamp {
        Stamp {
            frame: 7,
            ..Stamp::default()
        }
    }

    #[test]
    fn a_surf_message_has_one_64_float_descriptor_per_keypoint_and_the_frame_stamp() {
        let gray = squares(160, 120);
        let mut surf = SurfDescriber::new(SurfParams::default());
        let m = surf.describe(stamp(), &gray, 160, 120);
        assert!(m.header.count > 10, "{} keypoints", m.header.count);
        assert_eq!(m.keypoints.len(), m.header.count as usize);
        assert_eq!(m.descriptors.len(), 64 * m.keypoints.len());
        assert_eq!((m.header.stamp.frame, m.header.descriptor_kind), (7, KeypointsHeader::FLOAT));
        assert_eq!(lineflow_messages::str_from_fixed(&m.header.detector), "surf");
        // The scratch kept between images changes nothing.
        let again = surf.describe(stamp(), &gray, 160, 120);
        assert_eq!((again.keypoints, again.descriptors), (m.keypoints, m.descriptors));
    }

    #[test]
    fn an_orb_message_has_32_bytes_per_keypoint_and_no_laplacian() {
        let gray = squares(160, 120);
        let m = describe_orb(&OrbParams::default(), stamp(), &gray, 160, 120);
        assert!(m.header.count > 10, "{} keypoints", m.header.count);
        assert_eq!(m.descriptors.len(), 32 * m.keypoints.len());
        assert_eq!((m.header.descriptor_len, m.header.descriptor_kind), (32, KeypointsHeader::BINARY));
        assert!(m.keypoints.iter().all(|k| k.laplacian_sign == 0));
    }

    #[test]
    fn an_empty_image_gives_an_empty_message() {
        let m = describe_orb(&OrbParams::default(), stamp(), &[], 0, 0);
        assert_eq!((m.header.count, m.descriptors.len()), (0, 0));
    }
}
