//! The `folder` capture: publishes a project folder's camera and survey data once, then its images as a stream.
use std::path::PathBuf;
use std::time::{Duration, Instant};

use anyhow::{bail, Context, Result};
use lineflow_capture::decode_file;
use lineflow_formats::project::{self, Project};
use lineflow_messages::{fixed_str, kinds, CameraModelHeader, ImageHeader};
use lineflow_runtime::NodeContext;
use serde::Deserialize;

use crate::source::{Pacer, Survey};

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct Params {
    /// Project folder.
    folder: PathBuf,
    /// Frames per second; 0 = as fast as the graph accepts.
    #[serde(default)]
    fps: f64,
    /// Keep watching images/ for new files.
    #[serde(default)]
    watch: bool,
    /// Watch mode ends after this long without a new file (0 = never).
    #[serde(default = "default_idle")]
    idle_timeout_s: f64,
    /// Watch mode ends when this file appears in the project folder.
    #[serde(default = "default_stop_file")]
    stop_file: String,
    /// A file must keep its size this long before it is read.
    #[serde(default = "default_settle")]
    settle_ms: u64,
    /// Stamp frames from the system clock instead of the fixed start.
    #[serde(default)]
    use_clock: bool,
}

fn default_idle() -> f64 {
    30.0
}
fn default_stop_file() -> String {
    "STOP".into()
}
fn default_settle() -> u64 {
    300
}

pub fn run(ctx: &NodeContext) -> Result<()> {
    let mut p: Params = ctx.params()?;
    let base = ctx.graph().source.parent().map(std::path::Path::to_path_buf).unwrap_or_default();
    p.folder = lineflow_runtime::launch::resolve_param_path(&base, &p.folder.display().to_string());
    let valid = |v: f64| v.is_finite() && v >= 0.0;
    if !valid(p.fps) || !(valid(p.idle_timeout_s) || p.idle_timeout_s == f64::INFINITY) {
        bail!(
            "node '{}': fps and idle_timeout_s must be >= 0, got {} and {}",
            ctx.name(),
            p.fps,
            p.idle_timeout_s
        );
    }
    let images = ctx.output::<kinds::Image>("images")?;
    let survey = Survey::open(ctx)?;
    let project = Project::open(&p.folder, p.watch).map_err(|e| anyhow::anyhow!("{e}"))?;
    ctx.connect()?;

    let pacer = Pacer::new(p.fps, p.use_clock)?;
    survey.publish(
        pacer.once(),
        CameraModelHeader::from_camera(&project.camera.camera()),
        &project.control_points,
        &project.observations,
        &project.walls,
    )?;

    let mut frame = 0u64;
    let mut publish = |path: &std::path::Path| -> Result<()> {
        let img = decode_file(path).map_err(|e| anyhow::anyhow!(e))?;
        if (img.width, img.height) != (project.camera.width, project.camera.height) {
            bail!(
                "{}: image is {}x{} but camera.toml says {}x{}",
                path.display(),
                img.width,
                img.height,
                project.camera.width,
                project.camera.height
            );
        }
        let header = ImageHeader {
            stamp: pacer.frame(frame),
            width: img.width,
            height: img.height,
            step: img.width * img.encoding.bytes_per_pixel() as u32,
            encoding: img.encoding as u32,
            name: fixed_str(&project::file_name(path)),
        };
        images
            .publish(header, &img.bytes)
            .with_context(|| format!("{}: cannot publish", path.display()))?;
        tracing::debug!(frame, "published {}", path.display());
        frame += 1;
        Ok(())
    };

    for path in &project.images {
        if ctx.should_stop() {
            break;
        }
        publish(path)?;
    }
    if p.watch {
        let stop_file = p.folder.join(&p.stop_file);
        let mut watcher =
            lineflow_capture::watch::Watcher::new(&p.folder.join("images"), Duration::from_millis(p.settle_ms), project.images.clone());
        let mut last_new = Instant::now();
        tracing::info!(
            "watching {} (stop: Ctrl-C, {} or {} s idle)",
            p.folder.join("images").display(),
            stop_file.display(),
            p.idle_timeout_s
        );
        while !ctx.should_stop() && !stop_file.exists() && (p.idle_timeout_s == 0.0 || last_new.elapsed().as_secs_f64() < p.idle_timeout_s)
        {
            for path in watcher.poll() {
                publish(&path)?;
                last_new = Instant::now();
            }
            std::thread::sleep(Duration::from_millis(50));
        }
    }
    // Latched topics (camera, survey data) carry one message and no end-of-stream, so late joiners still get it.
    images.end_of_stream()?;
    tracing::info!("{frame} frames published");
    ctx.finish();
    Ok(())
}
