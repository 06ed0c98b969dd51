//! The `synthetic` capture's process: [`lineflow_capture::synthetic_source`] published frame by frame, with the
//! survey topics once and the ground truth on `gt/*`.
use anyhow::Result;
use lineflow_capture::pacer::Pacer;
use lineflow_capture::synthetic_source::{SyntheticParams, SyntheticSource};
use lineflow_messages::{kinds, CameraModelHeader, Lines3DHeader, PosesHeader, StampFlags};
use lineflow_runtime::NodeContext;

use crate::source::{sent, Survey};

pub fn run(ctx: NodeContext) -> Result<()> {
    let p: SyntheticParams = ctx.stage_params()?;
    let images = ctx.output::<kinds::Image>("images")?;
    // The supervisor sizes the image edge from the preset unless the launch file does.
    if let Some(preset) = lineflow_synthetic::preset(&p.preset, p.seed) {
        let c = preset.camera.scaled(p.scale.clamp(1e-3, 2.0));
        ctx.declare_max_payload("images", c.width as u64 * c.height as u64 * 3);
    }
    let survey_out = Survey::open(&ctx)?;
    let gt_poses = ctx.optional_output::<kinds::Poses>("gt/poses")?;
    let gt_lines = ctx.optional_output::<kinds::Lines3D>("gt/lines3d")?;

    let source = SyntheticSource::new(&p).map_err(|e| anyhow::anyhow!("node '{}': {e}", ctx.name()))?;
    let cam = *source.scene.camera();
    let frames = if source.total == u64::MAX {
        "frames until stopped".to_owned()
    } else {
        format!("{} frames", source.total)
    };
    tracing::info!(
        "{} at scale {} ({}x{}), {frames}, seed {}",
        p.preset,
        p.scale,
        cam.width,
        cam.height,
        p.seed
    );
    let (control, observations, walls) = source.survey();
    ctx.connect()?;

    let pacer = Pacer::new(p.fps, p.use_clock)?;
    let once = pacer.once();
    survey_out.publish(once, CameraModelHeader::from_camera(&cam), &control, &observations, &walls)?;
    if let Some(o) = &gt_poses {
        let mut stamp = once;
        stamp.flags |= StampFlags::FINAL;
        let header = PosesHeader {
            stamp,
            sigma0: f64::NAN,
            rms_px: f64::NAN,
        };
        o.publish(header, &source.true_poses())?;
        o.end_of_stream()?;
    }
    if let Some(o) = &gt_lines {
        o.publish(Lines3DHeader { stamp: once }, &source.true_lines())?;
        o.end_of_stream()?;
    }
    let mut published = 0;
    for frame in 0..source.total {
        if ctx.should_stop() {
            break;
        }
        let (header, rgb) = source.frame(frame, pacer.frame(frame))?;
        if !sent(&ctx, frame, images.publish(header, &rgb))? {
            break;
        }
        published += 1;
        tracing::debug!(frame, "rendered and published");
    }
    images.end_of_stream()?;
    tracing::info!("{published} frames published");
    ctx.finish();
    Ok(())
}
