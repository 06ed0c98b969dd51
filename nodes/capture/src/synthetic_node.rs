//! The `synthetic` capture: renders a preset scene frame by frame, publishes the survey data a real project
//! would have, and the ground truth on `gt/*` (which only `eval` may read).
use anyhow::{bail, Context, Result};
use lineflow_messages::{
    fixed_str, kinds, CameraModelHeader, ControlPoint, Encoding, ImageHeader, Line3, Lines3DHeader, Observation, Pose, PosesHeader,
    StampFlags, Wall,
};
use lineflow_runtime::NodeContext;
use lineflow_synthetic::{Sensor, Synthetic};
use serde::Deserialize;

use crate::source::{Pacer, Survey};

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct Params {
    /// Scene preset (d2x-strip, a55-two-strips, convergent, roof).
    #[serde(default = "default_preset")]
    preset: String,
    /// Image size relative to the preset; the field of view stays.
    #[serde(default = "default_scale")]
    scale: f64,
    /// Seed of everything random.
    #[serde(default = "default_seed")]
    seed: u64,
    /// Frames per second; 0 = as fast as the graph accepts.
    #[serde(default)]
    fps: f64,
    /// Stop after this many frames (default: all of the preset's).
    #[serde(default)]
    frames: Option<u64>,
    /// Stamp frames from the system clock instead of the fixed start.
    #[serde(default)]
    use_clock: bool,
    /// Optics and sensor (noise_dn, blur_px, vignetting, jpeg_quality, gamma).
    #[serde(default)]
    sensor: Option<Sensor>,
}

fn default_preset() -> String {
    lineflow_synthetic::DEFAULT_PRESET.into()
}
fn default_scale() -> f64 {
    lineflow_synthetic::DEFAULT_SCALE
}
fn default_seed() -> u64 {
    lineflow_synthetic::DEFAULT_SEED
}

fn survey(syn: &Synthetic) -> (Vec<ControlPoint>, Vec<Observation>, Vec<Wall>) {
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

pub fn run(ctx: &NodeContext) -> Result<()> {
    let p: Params = ctx.params()?;
    if !(p.fps >= 0.0 && p.fps.is_finite()) {
        bail!("node '{}': fps must be >= 0, got {}", ctx.name(), p.fps);
    }
    let images = ctx.output::<kinds::Image>("images")?;
    // The supervisor sizes the image edge from the preset unless the launch file does.
    if let Some(preset) = lineflow_synthetic::preset(&p.preset, p.seed) {
        let c = preset.camera.scaled(p.scale.clamp(1e-3, 2.0));
        ctx.declare_max_payload("images", c.width as u64 * c.height as u64 * 3);
    }
    let survey_out = Survey::open(ctx)?;
    let gt_poses = ctx.optional_output::<kinds::Poses>("gt/poses")?;
    let gt_lines = ctx.optional_output::<kinds::Lines3D>("gt/lines3d")?;

    let mut syn = Synthetic::new(&p.preset, p.scale, p.seed).map_err(|e| anyhow::anyhow!("node '{}': {e}", ctx.name()))?;
    if let Some(sensor) = p.sensor {
        if sensor.jpeg_quality > 100 {
            bail!(
                "node '{}': sensor.jpeg_quality must be 0-100, got {}",
                ctx.name(),
                sensor.jpeg_quality
            );
        }
        syn.preset.sensor = sensor;
    }
    let total = p.frames.map_or(syn.poses().len() as u64, |n| n.min(syn.poses().len() as u64));
    let cam = *syn.camera();
    tracing::info!(
        "{} at scale {} ({}x{}), {total} frames, seed {}",
        p.preset,
        p.scale,
        cam.width,
        cam.height,
        p.seed
    );
    let (control, observations, walls) = survey(&syn);
    ctx.connect()?;

    let pacer = Pacer::new(p.fps, p.use_clock)?;
    let once = pacer.once();
    survey_out.publish(once, CameraModelHeader::from_camera(&cam), &control, &observations, &walls)?;
    if let Some(o) = &gt_poses {
        let poses: Vec<Pose> = syn
            .poses()
            .iter()
            .enumerate()
            .map(|(i, pose)| Pose::from_exterior(i as u64, 0, Pose::ORIENTED | Pose::FINAL, pose))
            .collect();
        let mut stamp = once;
        stamp.flags |= StampFlags::FINAL;
        o.publish(
            PosesHeader {
                stamp,
                sigma0: f64::NAN,
                rms_px: f64::NAN,
            },
            &poses,
        )?;
        o.end_of_stream()?;
    }
    if let Some(o) = &gt_lines {
        let lines: Vec<Line3> = syn
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
            })
            .collect();
        o.publish(Lines3DHeader { stamp: once }, &lines)?;
        o.end_of_stream()?;
    }

    for frame in 0..total {
        if ctx.should_stop() {
            break;
        }
        let mut rgb = syn.render(frame as usize);
        if syn.preset.sensor.jpeg_quality > 0 {
            let bytes = lineflow_synthetic::jpeg_bytes(&rgb, cam.width, cam.height, syn.preset.sensor.jpeg_quality)?;
            rgb = image::load_from_memory(&bytes)
                .context("decoding the simulated JPEG")?
                .into_rgb8()
                .into_raw();
        }
        let header = ImageHeader {
            stamp: pacer.frame(frame),
            width: cam.width,
            height: cam.height,
            step: cam.width * 3,
            encoding: Encoding::Rgb8 as u32,
            name: fixed_str(&syn.image_name(frame as usize)),
        };
        images.publish(header, &rgb)?;
        tracing::debug!(frame, "rendered and published");
    }
    images.end_of_stream()?;
    tracing::info!("{total} frames published");
    ctx.finish();
    Ok(())
}
