//! The matcher stage between frames, as a state machine the process shell feeds: keypoints wait for the latched
//! camera and, when least-squares refinement is on and the images are wired, for their frame's grey image; frames
//! are matched in arrival order, each giving the tie-point observations to publish under its stamp.
use std::collections::{BTreeMap, VecDeque};

use lineflow_messages::{parts, Keypoint, KeypointsHeader, Stamp, TiePoint};
use lineflow_photogrammetry::Camera;

use crate::descriptors::{Descriptors, FrameFeatures};
use crate::lsm::Gray;
use crate::{Matcher, MatcherParams};

/// Why the matcher stage cannot go on; each names the frame and the values.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum MatcherError {
    /// A Keypoints payload shorter than its header's counts need.
    #[error("frame {frame}: {message}")]
    Malformed {
        /// The frame.
        frame: u64,
        /// What is wrong.
        message: String,
    },
    /// A descriptor kind this matcher does not know.
    #[error("frame {frame}: unknown descriptor kind {kind} from detector '{detector}'")]
    UnknownDescriptor {
        /// The frame.
        frame: u64,
        /// The kind given.
        kind: u32,
        /// The detector that sent it.
        detector: String,
    },
    /// A grey image of another size than the camera's.
    #[error("frame {frame}: image {width}x{height} differs from the camera's {camera_width}x{camera_height}")]
    ImageSize {
        /// The frame.
        frame: u64,
        /// The image's size.
        width: usize,
        /// The image's size.
        height: usize,
        /// The camera's size.
        camera_width: usize,
        /// The camera's size.
        camera_height: usize,
    },
    /// The keypoints ended before any camera model arrived.
    #[error("the keypoints ended but no camera model arrived")]
    NoCamera,
}

/// The features of a Keypoints message (its header and payload bytes, 8-byte aligned): float (SURF) or binary
/// (ORB) descriptors.
///
/// # Errors
/// A payload too short for its counts, or an unknown descriptor kind.
pub fn features(h: &KeypointsHeader, payload: &[u8]) -> Result<FrameFeatures, MatcherError> {
    let (n, len) = (h.count as usize, h.descriptor_len as usize);
    let malformed = |e: parts::PartsError| MatcherError::Malformed {
        frame: h.stamp.frame,
        message: e.to_string(),
    };
    let (kps, descriptors) = match h.descriptor_kind {
        KeypointsHeader::FLOAT => {
            let (kps, values) = parts::split::<Keypoint, f32>(payload, n, n * len).map_err(malformed)?;
            (
                kps,
                Descriptors::Float {
                    values: values.to_vec(),
                    len,
                },
            )
        }
        KeypointsHeader::BINARY => {
            let (kps, bytes) = parts::split::<Keypoint, u8>(payload, n, n * len).map_err(malformed)?;
            (
                kps,
                Descriptors::Binary {
                    bytes: bytes.to_vec(),
                    len,
                },
            )
        }
        other => {
            return Err(MatcherError::UnknownDescriptor {
                frame: h.stamp.frame,
                kind: other,
                detector: lineflow_messages::str_from_fixed(&h.detector).to_owned(),
            })
        }
    };
    Ok(FrameFeatures {
        px: kps.iter().map(|k| [k.col as f64, k.row as f64]).collect(),
        signs: kps.iter().map(|k| k.laplacian_sign).collect(),
        descriptors,
    })
}

/// A Keypoints payload copied out of shared memory into 8-byte-aligned storage, as [`parts::split`] wants it.
struct AlignedPayload {
    words: Vec<u64>,
    len: usize,
}

impl AlignedPayload {
    fn copy(bytes: &[u8]) -> Self {
        let mut words = vec![0u64; bytes.len().div_ceil(8)];
        for (w, chunk) in words.iter_mut().zip(bytes.chunks(8)) {
            let mut b = [0u8; 8];
            b[..chunk.len()].copy_from_slice(chunk);
            *w = u64::from_ne_bytes(b);
        }
        Self { words, len: bytes.len() }
    }

    fn bytes(&self) -> &[u8] {
        // SAFETY: `words` holds at least `len` initialised bytes; u8 has no alignment or validity requirement.
        unsafe { std::slice::from_raw_parts(self.words.as_ptr().cast::<u8>(), self.len) }
    }
}

/// One frame's tie points to publish.
#[derive(Debug, Clone, PartialEq)]
pub struct FrameTies {
    /// The stamp of the frame's keypoints.
    pub stamp: Stamp,
    /// The new observations: of this frame, and of earlier frames' keypoints that start a track.
    pub ties: Vec<TiePoint>,
}

/// The matcher stage's state.
pub struct MatcherStage {
    params: MatcherParams,
    matcher: Option<Matcher>,
    /// Whether a frame waits for its grey image: refinement on and the images wired.
    awaits_images: bool,
    waiting: VecDeque<(KeypointsHeader, AlignedPayload)>,
    grays: BTreeMap<u64, Gray>,
}

impl MatcherStage {
    /// A stage matching with `params`; `images_wired`: grey images arrive too (used when `params.refine`).
    pub fn new(params: MatcherParams, images_wired: bool) -> Self {
        Self {
            awaits_images: images_wired && params.refine,
            params,
            matcher: None,
            waiting: VecDeque::new(),
            grays: BTreeMap::new(),
        }
    }

    /// Whether the stage uses the grey images (otherwise the shell drains them).
    pub fn uses_images(&self) -> bool {
        self.awaits_images
    }

    /// The camera model (latched): the matcher starts with the first one.
    pub fn on_camera(&mut self, camera: Camera) {
        if self.matcher.is_none() {
            self.matcher = Some(Matcher::new(self.params.clone(), camera));
        }
    }

    /// A frame's grey image.
    pub fn on_gray(&mut self, frame: u64, width: usize, height: usize, gray: &[u8]) {
        let data = gray.to_vec();
        self.grays.insert(frame, Gray { width, height, data });
    }

    /// A frame's keypoints (header and payload bytes as received).
    pub fn on_keypoints(&mut self, header: KeypointsHeader, payload: &[u8]) {
        self.waiting.push_back((header, AlignedPayload::copy(payload)));
    }

    /// Whether keypoints are still waiting.
    pub fn has_waiting(&self) -> bool {
        !self.waiting.is_empty()
    }

    /// Matches the next frame if it has what it needs (frames in arrival order), `None` when none has.
    /// `images_ended`: no more grey images will come.
    ///
    /// # Errors
    /// A malformed payload, an unknown descriptor kind or an image of the wrong size.
    pub fn next_frame(&mut self, images_ended: bool) -> Option<Result<FrameTies, MatcherError>> {
        let matcher = self.matcher.as_mut()?;
        let frame = self.waiting.front()?.0.stamp.frame;
        if self.awaits_images && !images_ended && !self.grays.contains_key(&frame) {
            return None;
        }
        let (h, payload) = self.waiting.pop_front()?;
        Some(match_frame(matcher, &h, payload.bytes(), self.grays.remove(&frame)))
    }

    /// Checks that the stage can finish its stream. `keypoints_ended`: no more keypoints will come.
    ///
    /// # Errors
    /// The keypoints ended without a camera model.
    pub fn check_camera(&self, keypoints_ended: bool) -> Result<(), MatcherError> {
        if keypoints_ended && self.matcher.is_none() {
            return Err(MatcherError::NoCamera);
        }
        Ok(())
    }
}

fn match_frame(matcher: &mut Matcher, h: &KeypointsHeader, payload: &[u8], gray: Option<Gray>) -> Result<FrameTies, MatcherError> {
    if let Some(g) = &gray {
        let (w, ht) = (matcher.camera().width as usize, matcher.camera().height as usize);
        if (g.width, g.height) != (w, ht) {
            return Err(MatcherError::ImageSize {
                frame: h.stamp.frame,
                width: g.width,
                height: g.height,
                camera_width: w,
                camera_height: ht,
            });
        }
    }
    let result = matcher.add_frame(h.stamp.frame, features(h, payload)?, gray);
    let ties: Vec<TiePoint> = result
        .observations
        .iter()
        .map(|o| TiePoint {
            track: o.track,
            frame: o.frame,
            col: o.px[0],
            row: o.px[1],
        })
        .collect();
    tracing::debug!(
        frame = h.stamp.frame,
        partners = ?result.partners,
        observations = ties.len(),
        refined = result.refined,
        unrefined = result.unrefined,
        "matched"
    );
    if result.partners.iter().all(|&(_, _, inliers)| inliers == 0) && h.stamp.frame > 0 {
        tracing::warn!("frame {}: no verified tie points with any earlier frame", h.stamp.frame);
    }
    Ok(FrameTies { stamp: h.stamp, ties })
}

#[cfg(test)]
mod tests {
    use lineflow_messages::fixed_str;

    use super::*;

    const W: u32 = 400;
    const H: u32 = 300;

    fn camera() -> Camera {
        Camera::pinhole(W, H, 0.01, 4.0)
    }

    /// A Keypoints message of `frame`: 60 keypoints on a grid shifted `shift` pixels to the left, each with its
    /// own 64-float descriptor (the same point, the same descriptor, in every frame).
    fn keypoints(frame: u64, shift: f32, kind: u32) -> (KeypointsHeader, Vec<u8>) {
        let n = 60;
        let mut bytes = Vec::new();
        for i in 0..n {
            let (col, row) = (
                60.0 + (i % 10) as f32 * 25.0 - shift,
                40.0 + (i / 10) as f32 * 35.0 + (i % 3) as f32,
            );
            for v in [col, row, 2.0, 0.0, 100.0] {
                bytes.extend_from_slice(&v.to_ne_bytes());
            }
            bytes.extend_from_slice(&1i32.to_ne_bytes());
        }
        bytes.resize(bytes.len().div_ceil(8) * 8, 0);
        for i in 0..n {
            for k in 0..64 {
                let v = (((i * 7919 + k * 104_729) % 1000) as f32 / 1000.0) - 0.5;
                bytes.extend_from_slice(&v.to_ne_bytes());
            }
        }
        let header = KeypointsHeader {
            stamp: Stamp { frame, ..Stamp::default() },
            count: n as u32,
            descriptor_len: 64,
            descriptor_kind: kind,
            detector: fixed_str("surf"),
        };
        (header, bytes)
    }

    fn params(refine: bool) -> MatcherParams {
        MatcherParams {
            refine,
            ..MatcherParams::default()
        }
    }

    fn run(stage: &mut MatcherStage, images_ended: bool) -> Vec<FrameTies> {
        std::iter::from_fn(|| stage.next_frame(images_ended)).map(Result::unwrap).collect()
    }

    #[test]
    fn keypoints_wait_for_the_camera_and_frames_are_matched_in_arrival_order() {
        let mut s = MatcherStage::new(params(false), false);
        for (f, shift) in [(0, 0.0), (1, 6.0)] {
            let (h, b) = keypoints(f, shift, KeypointsHeader::FLOAT);
            s.on_keypoints(h, &b);
        }
        assert!(s.next_frame(true).is_none(), "no camera yet");
        assert_eq!(s.check_camera(true), Err(MatcherError::NoCamera));
        s.on_camera(camera());
        let out = run(&mut s, true);
        assert_eq!(out.iter().map(|f| f.stamp.frame).collect::<Vec<_>>(), [0, 1]);
        assert!(out[0].ties.is_empty(), "the first frame has no partner");
        // The second frame sees the same points moved 6 px: tracks start with both frames' observations.
        let ties = &out[1].ties;
        assert!(ties.len() >= 2 * 30, "{} observations", ties.len());
        for frame in [0, 1] {
            assert!(ties.iter().any(|t| t.frame == frame));
        }
        let t0 = ties.iter().find(|t| t.frame == 0).unwrap();
        let t1 = ties.iter().find(|t| t.frame == 1 && t.track == t0.track).unwrap();
        assert!(
            (t0.col - t1.col - 6.0).abs() < 1e-3 && (t0.row - t1.row).abs() < 1e-3,
            "{t0:?} {t1:?}"
        );
        assert!(!s.has_waiting());
    }

    #[test]
    fn with_refinement_a_frame_waits_for_its_image_until_the_images_end() {
        let mut s = MatcherStage::new(params(true), true);
        assert!(s.uses_images());
        assert!(!MatcherStage::new(params(false), true).uses_images());
        s.on_camera(camera());
        let (h, b) = keypoints(0, 0.0, KeypointsHeader::FLOAT);
        s.on_keypoints(h, &b);
        assert!(s.next_frame(false).is_none(), "frame 0's image has not come");
        s.on_gray(0, W as usize, H as usize, &vec![128; (W * H) as usize]);
        assert_eq!(run(&mut s, false).len(), 1);
        let (h, b) = keypoints(1, 6.0, KeypointsHeader::FLOAT);
        s.on_keypoints(h, &b);
        assert!(s.next_frame(false).is_none());
        assert_eq!(run(&mut s, true).len(), 1, "matched without its image once none can come");
    }

    #[test]
    fn frames_older_than_keep_frames_are_let_go_and_their_tracks_go_on_in_later_frames() {
        let params = MatcherParams {
            keep_frames: 3,
            ..params(false)
        };
        let mut s = MatcherStage::new(params, false);
        s.on_camera(camera());
        for f in 0..8u64 {
            let (h, b) = keypoints(f, 4.0 * f as f32, KeypointsHeader::FLOAT);
            s.on_keypoints(h, &b);
        }
        let out = run(&mut s, true);
        assert!(out[1..].iter().all(|f| !f.ties.is_empty()), "every frame is tied to the one before");
        // A track started by frames 0 and 1 is still extended by the last frame.
        let first = out[1].ties.iter().find(|t| t.frame == 0).unwrap().track;
        assert!(out[7].ties.iter().any(|t| t.track == first && t.frame == 7));
        let m = s.matcher.as_ref().unwrap();
        for (k, frame) in m.frames.iter().enumerate() {
            assert_eq!(frame.features.px.is_empty(), k < 5, "frame {k}");
            assert_eq!(frame.rays.is_empty(), k < 5, "frame {k}");
        }
        assert!(m.track_of.keys().all(|&(f, _)| f >= 5));
        assert!(m.planes.keys().all(|&(a, b)| a >= 5 && b >= 5));
        assert!(m.frames_of.values().flatten().all(|&f| f >= 5));
        let (h, b) = keypoints(8, 32.0, KeypointsHeader::FLOAT);
        let sample = features(&h, &b).unwrap().strongest(300);
        assert_eq!(m.partners(&sample).iter().min(), Some(&5), "only the last three are partners");
    }

    #[test]
    fn bad_messages_are_named_with_their_frame_and_values() {
        let mut s = MatcherStage::new(params(true), true);
        s.on_camera(camera());
        let (h, b) = keypoints(4, 0.0, 7);
        s.on_keypoints(h, &b);
        s.on_gray(4, W as usize, H as usize, &vec![0; (W * H) as usize]);
        let e = s.next_frame(false).unwrap().unwrap_err();
        assert_eq!(e.to_string(), "frame 4: unknown descriptor kind 7 from detector 'surf'");
        let (h, b) = keypoints(5, 0.0, KeypointsHeader::FLOAT);
        s.on_keypoints(h, &b[..100]);
        s.on_gray(5, W as usize, H as usize, &vec![0; (W * H) as usize]);
        assert!(matches!(s.next_frame(false), Some(Err(MatcherError::Malformed { frame: 5, .. }))));
        let (h, b) = keypoints(6, 0.0, KeypointsHeader::FLOAT);
        s.on_keypoints(h, &b);
        s.on_gray(6, 10, 10, &[0; 100]);
        let e = s.next_frame(false).unwrap().unwrap_err();
        assert_eq!(e.to_string(), "frame 6: image 10x10 differs from the camera's 400x300");
    }

    #[test]
    fn parameters_out_of_range_are_named_with_their_value() {
        use lineflow_runtime::StageParams;
        assert_eq!(MatcherParams::default().validate(), Ok(()));
        let ratio = MatcherParams {
            ratio: 1.5,
            ..MatcherParams::default()
        };
        assert_eq!(ratio.validate().unwrap_err().to_string(), "ratio must be in (0, 1], got 1.5");
        let inliers = MatcherParams {
            min_inliers: 5,
            ..MatcherParams::default()
        };
        assert!(inliers.validate().unwrap_err().to_string().ends_with("got 5"));
    }
}
