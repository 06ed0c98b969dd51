//! What every capture source shares: stamps from a fixed start (or the clock), pacing at `fps`, and the
//! latched survey topics (camera, control points, observations, site).
use std::time::{Duration, Instant};

use anyhow::Result;
use lineflow_messages::{
    kinds, CameraModelHeader, ControlPoint, ControlPointsHeader, Observation, ObservationsHeader, SiteHeader, Stamp, Wall,
};
use lineflow_runtime::{NodeContext, Output};

/// Fixed capture start (2020-09-13T12:26:40Z) so that runs and replays carry the same stamps.
pub const FIXED_START_NS: u64 = 1_600_000_000_000_000_000;

/// Frame stamps `start + k / fps` and, for a live source, the wait until frame k is due.
pub struct Pacer {
    start_ns: u64,
    period_ns: u64,
    live: bool,
    t0: Instant,
}

impl Pacer {
    /// A pacer at `fps` (0 = as fast as the graph accepts, stamped one second apart).
    pub fn new(fps: f64, use_clock: bool) -> Result<Pacer> {
        let start_ns = if use_clock {
            std::time::SystemTime::now().duration_since(std::time::UNIX_EPOCH)?.as_nanos() as u64
        } else {
            FIXED_START_NS
        };
        Ok(Pacer {
            start_ns,
            period_ns: if fps > 0.0 { (1e9 / fps) as u64 } else { 1_000_000_000 },
            live: fps > 0.0,
            t0: Instant::now(),
        })
    }

    /// The stamp of the latched topics.
    pub fn once(&self) -> Stamp {
        Stamp {
            capture_time_ns: self.start_ns,
            ..Default::default()
        }
    }

    /// Sleeps until frame `frame` is due (live sources only) and returns its stamp.
    pub fn frame(&self, frame: u64) -> Stamp {
        if self.live {
            let due = self.t0 + Duration::from_nanos(frame * self.period_ns);
            if let Some(wait) = due.checked_duration_since(Instant::now()) {
                std::thread::sleep(wait);
            }
        }
        Stamp {
            frame,
            capture_time_ns: self.start_ns + frame * self.period_ns,
            ..Default::default()
        }
    }
}

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
