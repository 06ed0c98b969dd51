//! `lineflow-orientation`: the orientation stage's process, implementations `bundle` (the default), `essential`
//! (seed 001's chained essential matrices) and `file` (the user's poses). It moves messages between the ports and
//! the state machine of [`lineflow_orientation::stage`], publishes what that returns, and at end-of-stream writes
//! `poses.csv`, `checkpoints.csv` and `colmap/` into the run's output folder.
use anyhow::Result;
use lineflow_messages::kinds;
use lineflow_orientation::results::write_results;
use lineflow_orientation::stage::OrientationStage;
use lineflow_orientation::{Method, OrientationParams};
use lineflow_runtime::{Flow, Input, NodeContext, Output};

fn main() -> std::process::ExitCode {
    lineflow_runtime::run_stage(
        "orientation",
        "bundle",
        &[("bundle", run_bundle), ("essential", run_essential), ("file", run_file)],
    )
}

/// Parameters of `impl = "file"` (the `bundle` parameters a launch file may carry are ignored).
#[derive(Debug, serde::Deserialize)]
struct FileParams {
    /// The poses, in the `poses.csv` format of `docs/conventions.md` (relative to the launch file).
    poses: std::path::PathBuf,
}

/// The stage's ports. Tie points drive `bundle` and `essential`; images drive `file` (tie points, if wired, are
/// drained).
struct Ports {
    camera: Input<kinds::CameraModel>,
    control: Option<Input<kinds::ControlPoints>>,
    observations: Option<Input<kinds::Observations>>,
    images: Option<Input<kinds::Image>>,
    ties: Option<Input<kinds::TiePoints>>,
    poses: Output<kinds::Poses>,
}

impl Ports {
    fn open(ctx: &NodeContext, driven_by_images: bool) -> Result<Ports> {
        let (images, ties) = if driven_by_images {
            (Some(ctx.input("images")?), ctx.optional_input("tiepoints")?)
        } else {
            (ctx.optional_input("images")?, Some(ctx.input("tiepoints")?))
        };
        Ok(Ports {
            camera: ctx.input("camera")?,
            control: ctx.optional_input("control_points")?,
            observations: ctx.optional_input("observations")?,
            images,
            ties,
            poses: ctx.output("poses")?,
        })
    }

    /// Whether the input that drives the stage (images or tie points) has ended.
    fn driver_ended(&self, driven_by_images: bool) -> bool {
        if driven_by_images {
            self.images.as_ref().is_some_and(Input::is_ended)
        } else {
            self.ties.as_ref().is_some_and(Input::is_ended)
        }
    }

    /// Hands every waiting message to the stage, the latched inputs first.
    fn receive(&self, stage: &mut OrientationStage) -> Result<()> {
        while let Some(m) = self.camera.receive()? {
            stage.on_camera(m.user_header().camera());
        }
        if let Some(input) = &self.control {
            while let Some(m) = input.receive()? {
                stage.on_control_points(m.payload());
            }
        }
        if let Some(input) = &self.observations {
            while let Some(m) = input.receive()? {
                stage.on_observations(m.payload());
            }
        }
        if let Some(input) = &self.images {
            while let Some(m) = input.receive()? {
                stage.on_image(m.user_header().stamp, m.user_header().name());
            }
        }
        if let Some(input) = &self.ties {
            while let Some(m) = input.receive()? {
                stage.on_tie_points(m.user_header().stamp, m.payload());
            }
        }
        Ok(())
    }
}

fn run_bundle(ctx: NodeContext) -> Result<()> {
    run(ctx, Some(Method::Bundle))
}

fn run_essential(ctx: NodeContext) -> Result<()> {
    run(ctx, Some(Method::Essential))
}

fn run_file(ctx: NodeContext) -> Result<()> {
    run(ctx, None)
}

/// `method` None: the `file` implementation.
fn run(ctx: NodeContext, method: Option<Method>) -> Result<()> {
    let ports = Ports::open(&ctx, method.is_none())?;
    let mut stage = match method {
        Some(method) => {
            let params: OrientationParams = ctx.stage_params()?;
            OrientationStage::from_tie_points(params, method, ports.control.is_some(), ports.observations.is_some())
        }
        None => {
            let p: FileParams = ctx.params()?;
            let base = ctx.graph().source.parent().map(std::path::Path::to_path_buf).unwrap_or_default();
            let path = lineflow_runtime::launch::resolve_param_path(&base, &p.poses.display().to_string());
            let rows = lineflow_formats::read_poses(&path).map_err(|e| anyhow::anyhow!("node '{}': {e}", ctx.name()))?;
            tracing::info!("{} poses from {}", rows.len(), path.display());
            OrientationStage::from_file(rows, path)
        }
    };
    ctx.connect()?;
    ctx.run(|| {
        ports.receive(&mut stage)?;
        let ended = ports.driver_ended(method.is_none());
        for m in stage.step(ended).map_err(|e| anyhow::anyhow!("node '{}': {e}", ctx.name()))? {
            ports.poses.publish(m.header, &m.poses)?;
        }
        Ok(if ended && !stage.has_waiting() {
            Flow::Stop
        } else {
            Flow::Continue
        })
    })?;
    if method.is_none() {
        // Supplied poses serve the check points: a survey that arrives last still counts.
        ports.receive(&mut stage)?;
    }
    if let Some((last, block, names)) = stage.finish() {
        ports.poses.publish(last.header, &last.poses)?;
        write_results(&ctx.out_dir(), block, names)?;
    }
    ports.poses.end_of_stream()?;
    ctx.finish();
    Ok(())
}
