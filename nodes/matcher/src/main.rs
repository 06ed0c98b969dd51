//! `lineflow-matcher`: the matcher stage's process. Feeds the state machine of [`lineflow_matcher::stage`] with
//! the latched camera, each frame's keypoints and (when least-squares refinement is on and they are wired) the grey
//! images, and publishes per frame the new tie-point observations (of this frame, and of earlier frames' keypoints
//! that start a track).
use anyhow::Result;
use lineflow_matcher::stage::{MatcherError, MatcherStage};
use lineflow_matcher::MatcherParams;
use lineflow_messages::{kinds, TiePointsHeader};
use lineflow_runtime::{Flow, Input, NodeContext};

fn main() -> std::process::ExitCode {
    lineflow_runtime::run_stage("matcher", "ratio", &[("ratio", run)])
}

fn run(ctx: NodeContext) -> Result<()> {
    let p: MatcherParams = ctx.stage_params()?;
    let keypoints = ctx.input::<kinds::Keypoints>("keypoints")?;
    let camera_in = ctx.input::<kinds::CameraModel>("camera")?;
    let images = ctx.optional_input::<kinds::Image>("images")?;
    let output = ctx.output::<kinds::TiePoints>("tiepoints")?;
    ctx.connect()?;
    let mut stage = MatcherStage::new(p, images.is_some());
    let mut buffer = Vec::new();
    let named = |e: MatcherError| anyhow::anyhow!("node '{}': {e}", ctx.name());
    ctx.run(|| {
        if let Some(input) = &images {
            if stage.uses_images() {
                lineflow_imaging::for_each_gray(input, &mut buffer, |h, g| {
                    stage.on_gray(h.stamp.frame, h.width as usize, h.height as usize, g);
                    Ok(())
                })?;
            } else {
                while input.receive()?.is_some() {}
            }
        }
        while let Some(m) = camera_in.receive()? {
            stage.on_camera(m.user_header().camera());
        }
        while let Some(m) = keypoints.receive()? {
            stage.on_keypoints(*m.user_header(), m.payload());
        }
        let images_ended = images.as_ref().is_none_or(Input::is_ended);
        while let Some(frame) = stage.next_frame(images_ended) {
            let frame = frame.map_err(named)?;
            output.publish(TiePointsHeader { stamp: frame.stamp }, &frame.ties)?;
        }
        stage.check_camera(keypoints.is_ended()).map_err(named)?;
        Ok(if keypoints.is_ended() && !stage.has_waiting() {
            Flow::Stop
        } else {
            Flow::Continue
        })
    })?;
    output.end_of_stream()?;
    ctx.finish();
    Ok(())
}
