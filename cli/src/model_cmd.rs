//! `lineflow model`: the wire-frame model of a lines3d.csv, as the model stage builds it.
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::time::Instant;

use anyhow::Result;
use lineflow_formats::{read_lines2d, read_lines3d, read_poses, PoseRow};
use lineflow_model::refine::{Endpoints, ImageLines};
use lineflow_model::{build, build_with_images, export, lines_from_rows, Cameras, Images, ModelParams};

/// Where Refine finds the images' 2-D lines: `lines2d.csv` and the `camera.toml` they were measured with (the
/// poses come from `--poses`).
pub struct RefineInputs<'a> {
    pub lines2d: &'a Path,
    pub camera: &'a Path,
}

/// Every posed image's 2-D lines for Refine (images of `lines2d.csv` without a pose are left out).
fn image_lines(
    inputs: &RefineInputs,
    poses: &[PoseRow],
    params: &ModelParams,
) -> Result<(lineflow_photogrammetry::Camera, Vec<ImageLines>)> {
    let camera = lineflow_formats::project::read_camera(inputs.camera)?.camera();
    let rows = read_lines2d(inputs.lines2d)?;
    let mut by_image: std::collections::HashMap<&str, Vec<Endpoints>> = Default::default();
    for r in &rows {
        by_image.entry(r.image.as_str()).or_default().push((r.start_px, r.end_px));
    }
    let lines = poses
        .iter()
        .map(|p| {
            let segments = by_image.get(p.image.as_str()).map_or(&[][..], Vec::as_slice);
            ImageLines::new(&camera, Some(p.pose), segments, params.refine_min_image_line_px)
        })
        .collect();
    Ok((camera, lines))
}

/// `lineflow model LINES3D [--poses POSES] [--lines2d LINES2D --camera CAMERA] [--out DIR] [--set PARAM=VALUE]...`
pub fn model(lines: &Path, poses: Option<&Path>, refine: Option<RefineInputs>, out: Option<PathBuf>, set: &[String]) -> Result<ExitCode> {
    let params = ModelParams::with_overrides(set)?;
    let rows = read_lines3d(lines)?;
    let poses = poses.map(read_poses).transpose()?.unwrap_or_default();
    let cameras = Cameras::new(poses.iter().map(|p| p.pose.center).collect());
    let images = match &refine {
        Some(inputs) if poses.is_empty() => {
            anyhow::bail!("refining with {} needs the images' poses: give --poses", inputs.lines2d.display())
        }
        Some(inputs) => Some(image_lines(inputs, &poses, &params)?),
        None => None,
    };
    let started = Instant::now();
    let model = match &images {
        Some((camera, lines_2d)) => {
            let images = Images {
                camera,
                lines: lines_2d,
                params: params.refine_params(),
            };
            build_with_images(&lines_from_rows(&rows, &params), &params, &cameras, Some(&images))
        }
        None => build(&lines_from_rows(&rows, &params), &params, &cameras),
    };
    let elapsed = started.elapsed().as_secs_f64();
    let out = out.unwrap_or_else(|| lines.parent().map(Path::to_path_buf).unwrap_or_default());
    export::write_obj(&out.join("model.obj"), &model)?;
    export::write_cityjson(&out.join("model.city.json"), &model)?;
    println!("{} in {:.0} ms", model.summary(), elapsed * 1000.0);
    println!("wrote {} and model.city.json", out.join("model.obj").display());
    if !rows.is_empty() && model.faces.is_empty() {
        eprintln!("warning: no closed face among the lines: the model is a loose wire-frame");
    }
    Ok(ExitCode::SUCCESS)
}

/// `lineflow classify LINES3D --out FILE [--poses POSES --camera CAMERA] [--set PARAM=VALUE]...`: the lines with
/// their `class` column as the line stages write it (docs/lines3d.md, "Structure and texture").
pub fn classify(lines: &Path, out: &Path, cameras: Option<(PathBuf, PathBuf)>, set: &[String]) -> Result<ExitCode> {
    let (n, texture) = lineflow_model::classify_file(lines, out, cameras, set)?;
    println!("{n} lines: {} structure, {texture} texture -> {}", n - texture, out.display());
    Ok(ExitCode::SUCCESS)
}
