//! `lineflow-features`: the features stage; one Keypoints message per image (two-part payload: `[Keypoint; count]`,
//! then the descriptors): `impl = "surf"` with `count × 64` `f32`, `impl = "orb"` with `count × 32` bytes.
use anyhow::{bail, Result};
use lineflow_features::orb::{orb, OrbParams};
use lineflow_features::surf::{surf_in, Feature, SurfParams, SurfScratch};
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
    match ctx.implementation("surf") {
        "surf" => run_surf(ctx),
        "orb" => run_orb(ctx),
        other => bail!("node '{}': unknown features impl '{other}' (available: surf, orb)", ctx.name()),
    }
}

/// One Keypoints message per grey image, from `describe` (keypoints, their descriptors, and the header's kind,
/// length and detector).
fn run_images<D: lineflow_runtime::ZeroCopySend + Copy>(
    ctx: NodeContext,
    mut describe: impl FnMut(&[u8], usize, usize) -> (Vec<Keypoint>, Vec<D>),
    kind: u32,
    descriptor_len: u32,
    detector: &str,
) -> Result<()> {
    let input = ctx.input::<kinds::Image>("images")?;
    let output = ctx.output::<kinds::Keypoints>("keypoints")?;
    ctx.connect()?;
    let mut gray = Vec::new();
    ctx.run(|| {
        lineflow_imaging::for_each_gray(&input, &mut gray, |h, gray| {
            let (kps, descriptors) = describe(gray, h.width as usize, h.height as usize);
            let header = KeypointsHeader {
                stamp: h.stamp,
                count: kps.len() as u32,
                descriptor_len,
                descriptor_kind: kind,
                detector: fixed_str(detector),
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

fn run_surf(ctx: NodeContext) -> Result<()> {
    let p: SurfParams = ctx.params()?;
    let threshold_ok = p.hessian_threshold.is_finite() && p.hessian_threshold >= 0.0;
    if !threshold_ok || !(1..=6).contains(&p.octaves) || !(1..=4).contains(&p.init_sample) {
        bail!(
            "node '{}': hessian_threshold must be >= 0, octaves in 1..=6, init_sample in 1..=4",
            ctx.name()
        );
    }
    let mut scratch = SurfScratch::default();
    let describe = move |gray: &[u8], w: usize, h: usize| {
        let features = surf_in(&mut scratch, gray, w, h, &p);
        let kps: Vec<Keypoint> = features.iter().map(keypoint).collect();
        let descriptors: Vec<f32> = features.iter().flat_map(|f| f.descriptor).collect();
        (kps, descriptors)
    };
    run_images(ctx, describe, KeypointsHeader::FLOAT, 64, "surf")
}

fn run_orb(ctx: NodeContext) -> Result<()> {
    let p: OrbParams = ctx.params()?;
    if let Err(e) = p.validate() {
        bail!("node '{}': {e}", ctx.name());
    }
    let describe = move |gray: &[u8], w: usize, h: usize| {
        let features = orb(gray, w, h, &p);
        let kps: Vec<Keypoint> = features
            .iter()
            .map(|f| Keypoint {
                col: f.col,
                row: f.row,
                scale_px: f.scale_px,
                orientation_rad: f.orientation,
                response: f.response,
                laplacian_sign: 0,
            })
            .collect();
        let descriptors: Vec<u8> = features.iter().flat_map(|f| f.descriptor).collect();
        (kps, descriptors)
    };
    run_images(ctx, describe, KeypointsHeader::BINARY, 32, "orb")
}
