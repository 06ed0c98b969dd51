//! `lineflow-features`: the features stage's process; one Keypoints message per grey image (two-part payload:
//! `[Keypoint; count]`, then the descriptors), laid out by [`lineflow_features::describe`].
use anyhow::Result;
use lineflow_features::describe::{describe_orb, Described, SurfDescriber};
use lineflow_features::orb::OrbParams;
use lineflow_features::surf::SurfParams;
use lineflow_messages::{kinds, Stamp};
use lineflow_runtime::{Flow, NodeContext, ZeroCopySend};

fn main() -> std::process::ExitCode {
    lineflow_runtime::run_stage("features", "surf", &[("surf", run_surf), ("orb", run_orb)])
}

/// One Keypoints message per grey image, from `describe`.
fn run_images<D: ZeroCopySend + Copy>(
    ctx: NodeContext,
    mut describe: impl FnMut(Stamp, &[u8], usize, usize) -> Described<D>,
) -> Result<()> {
    let input = ctx.input::<kinds::Image>("images")?;
    let output = ctx.output::<kinds::Keypoints>("keypoints")?;
    ctx.connect()?;
    let mut gray = Vec::new();
    ctx.run(|| {
        lineflow_imaging::for_each_gray(&input, &mut gray, |h, gray| {
            let m = describe(h.stamp, gray, h.width as usize, h.height as usize);
            output.publish_parts(m.header, &m.keypoints, &m.descriptors)?;
            tracing::debug!(frame = h.stamp.frame, keypoints = m.keypoints.len(), "described");
            Ok(())
        })?;
        Ok(if input.is_ended() { Flow::Stop } else { Flow::Continue })
    })?;
    output.end_of_stream()?;
    ctx.finish();
    Ok(())
}

fn run_surf(ctx: NodeContext) -> Result<()> {
    let mut surf = SurfDescriber::new(ctx.stage_params::<SurfParams>()?);
    run_images(ctx, move |stamp, gray, w, h| surf.describe(stamp, gray, w, h))
}

fn run_orb(ctx: NodeContext) -> Result<()> {
    let p: OrbParams = ctx.stage_params()?;
    run_images(ctx, move |stamp, gray, w, h| describe_orb(&p, stamp, gray, w, h))
}
