//! The latched survey topics every capture source publishes once (camera, control points, observations, site).
use anyhow::Result;
use lineflow_messages::{
    kinds, CameraModelHeader, ControlPoint, ControlPointsHeader, Observation, ObservationsHeader, SiteHeader, Stamp, Wall,
};
use lineflow_runtime::{NodeContext, Output};

/// The latched survey outputs; each is optional in the launch graph.
pub struct Survey {
    camera: Option<Output<kinds::CameraModel>>,
    control: Option<Output<kinds::ControlPoints>>,
    observations: Option<Output<kinds::Observations>>,
    site: Option<Output<kinds::Site>>,
}

impl Survey {
    /// Opens the outputs the graph connects.
    pub fn open(ctx: &NodeContext) -> Result<Survey> {
        Ok(Survey {
            camera: ctx.optional_output::<kinds::CameraModel>("camera")?,
            control: ctx.optional_output::<kinds::ControlPoints>("control_points")?,
            observations: ctx.optional_output::<kinds::Observations>("observations")?,
            site: ctx.optional_output::<kinds::Site>("site")?,
        })
    }

    /// Publishes each once. Latched topics carry no end-of-stream, so that late joiners still get them.
    pub fn publish(
        &self,
        stamp: Stamp,
        camera: CameraModelHeader,
        control: &[ControlPoint],
        observations: &[Observation],
        walls: &[Wall],
    ) -> Result<()> {
        if let Some(o) = &self.camera {
            o.publish(CameraModelHeader { stamp, ..camera }, &[])?;
        }
        if let Some(o) = &self.control {
            o.publish(ControlPointsHeader { stamp }, control)?;
        }
        if let Some(o) = &self.observations {
            o.publish(ObservationsHeader { stamp }, observations)?;
        }
        if let Some(o) = &self.site {
            o.publish(SiteHeader { stamp }, walls)?;
        }
        Ok(())
    }
}

/// Whether a frame went out. A send that fails once the run is being stopped is the end of the stream, not an
/// error: SIGINT or SIGTERM while the frame waited for a subscriber on a full lossless edge makes iceoryx2's send
/// give up (`InternalError`), and the frames already sent are all there.
pub fn sent(ctx: &NodeContext, frame: u64, result: Result<()>) -> Result<bool> {
    match result {
        Ok(()) => Ok(true),
        Err(e) if ctx.should_stop() => {
            tracing::info!("stopped while frame {frame} waited for a subscriber: not sent ({e:#})");
            Ok(false)
        }
        Err(e) => Err(e),
    }
}
