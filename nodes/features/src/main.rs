//! `lineflow-features`: the features stage (`impl = "surf"`); one Keypoints message per image, keypoints with
//! float descriptors (two-part payload: `[Keypoint; count]`, then `count × 64` `f32`).
use anyhow::{bail, Result};
use lineflow_features::surf::{surf, Feature, SurfParams};
use lineflow_messages::{fixed_str, kinds, Keypoint, KeypointsHeader};
use lineflow_runtime::{Flow, NodeContext};

fn main() -> std::process::ExitCode {
    lineflow_runtime::run_node(body)
}

fn keypoint(f: &Feature) -> Keypoint {
    Keypoint {
        col: f.at.col,
        row: f.at.row,
        scale_px: f.at.scale,
        orientation_rad: f.orientation,
        response: f.at.response,
        laplacian_sign: f.at.laplacian_sign,
    }
}

fn body() -> Result<()> {
    let ctx = NodeContext::from_env()?;
    let impl_ = ctx.implementation("surf").to_owned();
    if impl_ != "surf" {
        bail!("node '{}': unknown features impl '{impl_}' (available: surf)", ctx.name());
    }
    let p: SurfParams = ctx.params()?;
    let threshold_ok = p.hessian_threshold.is_finite() && p.hessian_threshold >= 0.0;
    if !threshold_ok || !(1..=6).contains(&p.octaves) || !(1..=4).contains(&p.init_sample) {
        bail!(
            "node '{}': hessian_threshold must be >= 0, octaves in 1..=6, init_sample in 1..=4",
            ctx.name()
        );
    }
    let input = ctx.input::<kinds::Image>("images")?;
    let output = ctx.output::<kinds::Keypoints>("keypoints")?;
    ctx.connect()?;
    let mut gray = Vec::new();
    ctx.run(|| {
        lineflow_convert::for_each_gray(&input, &mut gray, |h, gray| {
            let features = surf(gray, h.width as usize, h.height as usize, &p);
            let kps: Vec<Keypoint> = features.iter().map(keypoint).collect();
            let descriptors: Vec<f32> = features.iter().flat_map(|f| f.descriptor).collect();
            let header = KeypointsHeader {
                stamp: h.stamp,
                count: kps.len() as u32,
                descriptor_len: 64,
                descriptor_kind: KeypointsHeader::FLOAT,
                detector: fixed_str("surf"),
            };
            output.publish_parts(header, &kps, &descriptors)?;
            tracing::debug!(frame = h.stamp.frame, keypoints = kps.len(), "described");
            Ok(())
        })?;
        Ok(if input.is_ended() { Flow::Stop } else { Flow::Continue })
    })?;
    output.end_of_stream()?;
    ctx.finish();
    Ok(())
}
