//! The `synthetic` capture without its process: a preset scene rendered frame by frame into image messages, the
//! survey data a real project would have, and the ground truth that only `eval` may read (`gt/*`).
use lineflow_messages::{fixed_str, ControlPoint, Encoding, ImageHeader, Line3, Observation, Pose, Stamp, Wall};
use lineflow_runtime::params::{self, ParamError};
use lineflow_synthetic::{Sensor, Synthetic};
use serde::Deserialize;

/// The `synthetic` implementation's launch-file parameters.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct SyntheticParams {
    /// Scene preset (`lineflow presets` lists them).
    pub preset: String,
    /// Image size relative to the preset; the field of view stays.
    pub scale: f64,
    /// Seed of everything random.
    pub seed: u64,
    /// Frames per second; 0 = as fast as the graph accepts.
    pub fps: f64,
    /// Stop after this many frames (default: all of the preset's).
    pub frames: Option<u64>,
    /// Start the strip over after its last frame (same poses, new sensor noise, new frame numbers and names) until
    /// `frames` have been published, or without `frames` until the run is stopped: a stream of any length
    /// (`lineflow bench soak`). Control-point observations and the ground truth cover the first pass only.
    pub repeat: bool,
    /// Stamp frames from the system clock instead of the fixed start.
    pub use_clock: bool,
    /// Optics and sensor (noise_dn, blur_px, vignetting, jpeg_quality, gamma); the preset's when absent.
    pub sensor: Option<Sensor>,
}

impl Default for SyntheticParams {
    fn default() -> Self {
        SyntheticParams {
            preset: lineflow_synthetic::DEFAULT_PRESET.into(),
            scale: lineflow_synthetic::DEFAULT_SCALE,
            seed: lineflow_synthetic::DEFAULT_SEED,
            fps: 0.0,
            frames: None,
            repeat: false,
            use_clock: false,
            sensor: None,
        }
    }
}

impl lineflow_runtime::StageParams for SyntheticParams {
    fn validate(&self) -> Result<(), ParamError> {
        params::non_negative("fps", self.fps)?;
        if let Some(sensor) = &self.sensor {
            let q = sensor.jpeg_quality;
            params::check(q <= 100, "sensor.jpeg_quality", "in 0..=100", q)?;
        }
        Ok(())
    }
}

/// Why the scene cannot be rendered.
#[derive(Debug, thiserror::Error)]
pub enum SyntheticError {
    /// An unknown preset or a scale out of range.
    #[error(transparent)]
    Scene(#[from] lineflow_synthetic::SynthError),
    /// The simulated JPEG could not be written or read back.
    #[error("simulating the camera's JPEG of frame {frame}: {why}")]
    Jpeg {
        /// The frame.
        frame: u64,
        /// What failed.
        why: String,
    },
}

/// A preset scene as a capture source.
pub struct SyntheticSource {
    /// The scene.
    pub scene: Synthetic,
    /// Frames to publish.
    pub total: u64,
}

impl SyntheticSource {
    /// The scene `params` describe.
    ///
    /// # Errors
    /// An unknown preset or a scale out of range.
    pub fn new(params: &SyntheticParams) -> Result<SyntheticSource, SyntheticError> {
        let mut scene = Synthetic::new(&params.preset, params.scale, params.seed)?;
        if let Some(sensor) = params.sensor {
            scene.preset.sensor = sensor;
        }
        let n = scene.poses().len() as u64;
        let total = match (params.repeat, params.frames) {
            (true, frames) => frames.unwrap_or(u64::MAX),
            (false, frames) => frames.map_or(n, |f| f.min(n)),
        };
        Ok(SyntheticSource { scene, total })
    }

    /// The survey a real project would have: control and check points, their image observations, and the
    /// approximate walls of the site.
    pub fn survey(&self) -> (Vec<ControlPoint>, Vec<Observation>, Vec<Wall>) {
        let syn = &self.scene;
        let s = syn.preset.survey_sigma_m;
        let control = syn
            .building
            .targets
            .iter()
            .map(|t| ControlPoint {
                id: fixed_str(&t.id),
                xyz: t.xyz,
                sigma_m: [s; 3],
                role: if t.control { ControlPoint::CONTROL } else { ControlPoint::CHECK },
                reserved: 0,
            })
            .collect();
        let observations = syn
            .target_observations()
            .into_iter()
            .map(|o| Observation {
                frame: o.frame as u64,
                point_id: fixed_str(&o.id),
                col: o.px[0],
                row: o.px[1],
            })
            .collect();
        let walls = syn
            .approximate_walls()
            .into_iter()
            .map(|(name, corners)| Wall::new(&name, &corners))
            .collect();
        (control, observations, walls)
    }

    /// The true poses of every frame (`gt/poses`), final.
    pub fn true_poses(&self) -> Vec<Pose> {
        self.scene
            .poses()
            .iter()
            .enumerate()
            .map(|(i, pose)| Pose::from_exterior(i as u64, 0, Pose::ORIENTED | Pose::FINAL, pose))
            .collect()
    }

    /// The building's edges that some frame sees (`gt/lines3d`), numbered from 1.
    pub fn true_lines(&self) -> Vec<Line3> {
        self.scene
            .seen_edges()
            .iter()
            .enumerate()
            .map(|(i, e)| Line3 {
                id: i as u64 + 1,
                start_m: e.edge.a,
                end_m: e.edge.b,
                n_points: 0,
                n_images: e.frames.len() as u32,
                rms_m: 0.0,
                class: lineflow_messages::LineClass::Structure.code(),
                reserved: 0,
            })
            .collect()
    }

    /// Frame `frame` as an RGB image message under `stamp`, through the simulated JPEG when the sensor has one.
    ///
    /// # Errors
    /// The JPEG simulation failed.
    pub fn frame(&self, frame: u64, stamp: Stamp) -> Result<(ImageHeader, Vec<u8>), SyntheticError> {
        let cam = self.scene.camera();
        let mut rgb = self.scene.render(frame as usize);
        let quality = self.scene.preset.sensor.jpeg_quality;
        if quality > 0 {
            let jpeg = |why: String| SyntheticError::Jpeg { frame, why };
            let bytes = lineflow_synthetic::jpeg_bytes(&rgb, cam.width, cam.height, quality).map_err(|e| jpeg(e.to_string()))?;
            rgb = image::load_from_memory(&bytes)
                .map_err(|e| jpeg(e.to_string()))?
                .into_rgb8()
                .into_raw();
        }
        let header = ImageHeader {
            stamp,
            width: cam.width,
            height: cam.height,
            step: cam.width * 3,
            encoding: Encoding::Rgb8 as u32,
            name: fixed_str(&self.scene.image_name(frame as usize)),
        };
        Ok((header, rgb))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use lineflow_runtime::StageParams;

    fn small() -> SyntheticParams {
        SyntheticParams {
            scale: 0.05,
            frames: Some(2),
            ..SyntheticParams::default()
        }
    }

    #[test]
    fn a_frame_is_an_rgb_message_of_the_cameras_size_and_the_same_on_every_call() {
        let source = SyntheticSource::new(&small()).unwrap();
        assert_eq!(source.total, 2);
        let stamp = Stamp {
            frame: 1,
            ..Stamp::default()
        };
        let (h, rgb) = source.frame(1, stamp).unwrap();
        let cam = source.scene.camera();
        assert_eq!((h.width, h.height, h.step), (cam.width, cam.height, cam.width * 3));
        assert_eq!(rgb.len(), (cam.width * cam.height * 3) as usize);
        assert_eq!(h.stamp.frame, 1);
        assert_eq!(source.frame(1, stamp).unwrap().1, rgb);
    }

    #[test]
    fn a_repeated_strip_starts_over_with_new_noise_and_runs_as_long_as_asked() {
        let p = SyntheticParams {
            repeat: true,
            frames: None,
            ..small()
        };
        let source = SyntheticSource::new(&p).unwrap();
        assert_eq!(source.total, u64::MAX, "until stopped");
        let n = source.scene.poses().len() as u64;
        let stamp = Stamp::default();
        let (first, a) = source.frame(0, stamp).unwrap();
        let (again, b) = source.frame(n, stamp).unwrap();
        assert_ne!(first.name, again.name, "a new name on the second pass");
        assert_ne!(a, b, "new sensor noise");
        let close = a.iter().zip(&b).filter(|(x, y)| x.abs_diff(**y) <= 12).count();
        assert!(close * 10 > a.len() * 9, "the same view: {close} of {} bytes close", a.len());
        let counted = SyntheticSource::new(&SyntheticParams { frames: Some(n + 5), ..p }).unwrap();
        assert_eq!(counted.total, n + 5);
    }

    #[test]
    fn the_survey_and_the_truth_come_from_the_scene() {
        let source = SyntheticSource::new(&small()).unwrap();
        let (control, observations, walls) = source.survey();
        assert!(control.iter().any(|c| c.role == ControlPoint::CONTROL));
        assert!(control.iter().any(|c| c.role == ControlPoint::CHECK));
        assert!(!observations.is_empty() && !walls.is_empty());
        assert_eq!(source.true_poses().len(), source.scene.poses().len());
        let lines = source.true_lines();
        assert_eq!(lines.first().map(|l| l.id), Some(1));
    }

    #[test]
    fn bad_parameters_are_named() {
        let fps = SyntheticParams { fps: -1.0, ..small() };
        assert_eq!(fps.validate().unwrap_err().to_string(), "fps must be >= 0, got -1");
        let unknown = SyntheticParams {
            preset: "no-such-building".into(),
            ..small()
        };
        assert!(SyntheticSource::new(&unknown).is_err());
    }
}
