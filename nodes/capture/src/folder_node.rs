//! The `folder` capture: publishes a project folder's camera and survey data once, then its images as a stream.
use std::time::{Duration, Instant};

use anyhow::{bail, Context, Result};
use lineflow_capture::decode_file_for;
use lineflow_capture::folder_params::FolderParams;
use lineflow_capture::pacer::Pacer;
use lineflow_formats::project::{self, Project};
use lineflow_messages::{fixed_str, kinds, CameraModelHeader, ImageHeader};
use lineflow_runtime::NodeContext;

use crate::source::{sent, Survey};

pub fn run(ctx: NodeContext) -> Result<()> {
    let mut p: FolderParams = ctx.stage_params()?;
    let base = ctx.graph().source.parent().map(std::path::Path::to_path_buf).unwrap_or_default();
    p.folder = lineflow_runtime::launch::resolve_param_path(&base, &p.folder.display().to_string());
    let images = ctx.output::<kinds::Image>("images")?;
    let survey = Survey::open(&ctx)?;
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
    // Whether the frame went out (not when the run is stopped while it waits for a subscriber).
    let mut publish = |path: &std::path::Path| -> Result<bool> {
        let img = decode_file_for(path, (project.camera.width, project.camera.height))?;
        if (img.width, img.height) != (project.camera.width, project.camera.height) {
            bail!(
                "{}: image is {}x{} but camera.toml says {}x{} (one camera per project, its images neither cropped nor \
                 scaled; a photo turned by its EXIF orientation is taken as stored where that fits)",
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
        let result = images
            .publish(header, &img.bytes)
            .with_context(|| format!("{}: cannot publish", path.display()));
        if !sent(&ctx, frame, result)? {
            return Ok(false);
        }
        tracing::debug!(frame, "published {}", path.display());
        frame += 1;
        Ok(true)
    };

    for path in &project.images {
        if ctx.should_stop() || !publish(path)? {
            break;
        }
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
                if !publish(&path)? {
                    break;
                }
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
