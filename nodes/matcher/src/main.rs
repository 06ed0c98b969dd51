//! `lineflow-matcher`: the matcher stage. Joins the latched camera with each frame's keypoints and publishes, per
//! frame, the new tie-point observations (of this frame, and of earlier frames' keypoints that start a track).
//! With the grey images wired (input `images`), every observation is refined by least-squares matching; a frame's
//! keypoints then wait for its image.
use anyhow::{bail, Result};
use std::collections::BTreeMap;

use lineflow_matcher::descriptors::{Descriptors, FrameFeatures};
use lineflow_matcher::lsm::Gray;
use lineflow_matcher::{Matcher, MatcherParams};
use lineflow_messages::{kinds, parts, Keypoint, KeypointsHeader, TiePoint, TiePointsHeader};
use lineflow_runtime::{Flow, NodeContext};

fn main() -> std::process::ExitCode {
    lineflow_runtime::run_node(body)
}

/// The features of a Keypoints message: float (SURF) or binary (ORB) descriptors.
fn features(h: &KeypointsHeader, payload: &[u8]) -> Result<FrameFeatures> {
    let (n, len) = (h.count as usize, h.descriptor_len as usize);
    let malformed = |e| anyhow::anyhow!("frame {}: {e}", h.stamp.frame);
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
        other => bail!(
            "frame {}: unknown descriptor kind {other} from detector '{}'",
            h.stamp.frame,
            lineflow_messages::str_from_fixed(&h.detector)
        ),
    };
    Ok(FrameFeatures {
        px: kps.iter().map(|k| [k.col as f64, k.row as f64]).collect(),
        signs: kps.iter().map(|k| k.laplacian_sign).collect(),
        descriptors,
    })
}

fn body() -> Result<()> {
    let ctx = NodeContext::from_env()?;
    if ctx.implementation("ratio") != "ratio" {
        bail!(
            "node '{}': unknown matcher impl '{}' (available: ratio)",
            ctx.name(),
            ctx.implementation("ratio")
        );
    }
    let p: MatcherParams = ctx.params()?;
    if !(p.ratio > 0.0 && p.ratio <= 1.0 && p.threshold_px > 0.0 && p.iterations > 0 && p.min_inliers >= 8) {
        bail!(
            "node '{}': ratio must be in (0, 1], threshold_px > 0, iterations > 0, min_inliers >= 8",
            ctx.name()
        );
    }
    let keypoints = ctx.input::<kinds::Keypoints>("keypoints")?;
    let camera_in = ctx.input::<kinds::CameraModel>("camera")?;
    let images = ctx.optional_input::<kinds::Image>("images")?;
    let output = ctx.output::<kinds::TiePoints>("tiepoints")?;
    ctx.connect()?;
    let mut matcher: Option<Matcher> = None;
    // Keypoints that arrive before the camera wait for it, in order.
    let mut waiting: Vec<(KeypointsHeader, Vec<u8>)> = Vec::new();
    let mut grays: BTreeMap<u64, Gray> = BTreeMap::new();
    let mut buffer = Vec::new();
    ctx.run(|| {
        // Without refinement the images are only drained.
        if let Some(input) = images.as_ref().filter(|_| !p.refine) {
            while input.receive()?.is_some() {}
        }
        if let Some(input) = images.as_ref().filter(|_| p.refine) {
            lineflow_imaging::for_each_gray(input, &mut buffer, |h, g| {
                let gray = Gray {
                    width: h.width as usize,
                    height: h.height as usize,
                    data: g.to_vec(),
                };
                grays.insert(h.stamp.frame, gray);
                Ok(())
            })?;
        }
        while let Some(m) = camera_in.receive()? {
            matcher.get_or_insert_with(|| Matcher::new(p.clone(), m.user_header().camera()));
        }
        while let Some(m) = keypoints.receive()? {
            waiting.push((*m.user_header(), m.payload().to_vec()));
        }
        // Frames are matched in arrival order; with images wired, each waits for its own image.
        let images_done = images.as_ref().is_none_or(|i| i.is_ended()) || !p.refine;
        let ready = waiting
            .iter()
            .take_while(|(h, _)| images_done || grays.contains_key(&h.stamp.frame))
            .count();
        if let Some(matcher) = matcher.as_mut() {
            for (h, payload) in waiting.drain(..ready) {
                // Copied out of shared memory unaligned; `parts::split` wants 8-byte alignment.
                let mut aligned = vec![0u64; payload.len().div_ceil(8)];
                // SAFETY: `aligned` holds at least payload.len() bytes.
                let bytes = unsafe { std::slice::from_raw_parts_mut(aligned.as_mut_ptr().cast::<u8>(), payload.len()) };
                bytes.copy_from_slice(&payload);
                let gray = grays.remove(&h.stamp.frame);
                if let Some(g) = &gray {
                    let (w, ht) = (matcher.camera().width as usize, matcher.camera().height as usize);
                    if (g.width, g.height) != (w, ht) {
                        bail!(
                            "frame {}: image {}x{} differs from the camera's {w}x{ht}",
                            h.stamp.frame,
                            g.width,
                            g.height
                        );
                    }
                }
                let result = matcher.add_frame(h.stamp.frame, features(&h, bytes)?, gray);
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
                output.publish(TiePointsHeader { stamp: h.stamp }, &ties)?;
            }
        }
        if keypoints.is_ended() && matcher.is_none() {
            bail!("node '{}': the keypoints ended but no camera model arrived", ctx.name());
        }
        Ok(if keypoints.is_ended() && waiting.is_empty() {
            Flow::Stop
        } else {
            Flow::Continue
        })
    })?;
    output.end_of_stream()?;
    ctx.finish();
    Ok(())
}
