//! `lineflow model` (a wire-frame from a lines3d.csv) and `lineflow bench model` (the model stage on the ground
//! truth of a preset with noise added: accuracy and time).
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::time::Instant;

use anyhow::{Context, Result};
use lineflow_capture::synth::{rng::Rng, Synthetic};
use lineflow_formats::{read_lines2d, read_lines3d, read_poses, Line3Row, PoseRow};
use lineflow_model::refine::{Endpoints, ImageLines};
use lineflow_model::{
    build, build_with_images, export, junction, lines_from_rows, Cameras, Images, Model, ModelLine, ModelParams, SurfaceKind,
};
use lineflow_photogrammetry::Vec3;

use crate::bench_util::median_time;

/// The speed target: a façade with 40 openings built in at most this many seconds.
const TARGET_S: f64 = 1.0;

/// Applies `PARAM=VALUE` overrides (VALUE as TOML) to the model parameters.
fn params_with(set: &[String]) -> Result<ModelParams> {
    let mut table = toml::Table::new();
    for item in set {
        let (k, v) = item
            .split_once('=')
            .with_context(|| format!("--set {item}: expected PARAM=VALUE"))?;
        table.insert(k.trim().to_string(), lineflow_runtime::launch::override_value(v));
    }
    let params: ModelParams = toml::Value::Table(table).try_into().context("model parameters")?;
    params.validate().map_err(anyhow::Error::msg)?;
    Ok(params)
}

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
    let camera = lineflow_capture::project::read_camera(inputs.camera)?.camera();
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
    let params = params_with(set)?;
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

/// The model stage's input from a preset's true edges with noise σ (seed 1): the noisy rows, the lines and
/// parameters built from them, and the camera centres.
pub struct NoisyInput {
    pub rows: Vec<Line3Row>,
    pub lines: Vec<ModelLine>,
    pub params: ModelParams,
    pub cameras: Cameras,
}

pub fn noisy_input(truth: &lineflow_eval::Truth, sigma_m: f64, base: &ModelParams) -> NoisyInput {
    let rows = noisy(&truth.lines, sigma_m, 1);
    let params = ModelParams {
        sigma_m: sigma_m.max(1e-4),
        ..base.clone()
    };
    let lines = lines_from_rows(&rows, &params);
    let cameras = Cameras::new(truth.poses.iter().map(|p| p.pose.center).collect());
    NoisyInput {
        rows,
        lines,
        params,
        cameras,
    }
}

/// The true edges with every endpoint coordinate perturbed by N(0, σ²), deterministic in `seed`.
pub fn noisy(lines: &[Line3Row], sigma_m: f64, seed: u64) -> Vec<Line3Row> {
    let mut rng = Rng::new(seed, 77);
    lines
        .iter()
        .map(|l| {
            let mut jitter = || Vec3::new(rng.normal(), rng.normal(), rng.normal()) * sigma_m;
            Line3Row {
                start: l.start + jitter(),
                end: l.end + jitter(),
                ..l.clone()
            }
        })
        .collect()
}

/// `lineflow bench model`: for each noise level, the model of the preset's true edges with noise, scored against
/// the truth, and its time beside the seed's all-pairs junction search measured on the same lines. `set` overrides
/// model parameters as `--set` does for `lineflow model`.
pub fn bench_model(preset: &str, sigmas_gsd: &[f64], reps: usize, set: &[String], out: Option<&Path>) -> Result<ExitCode> {
    let base = params_with(set)?;
    let truth = lineflow_eval::Truth::from_scene(Synthetic::new(preset, 1.0, 1)?);
    let gsd = truth.gsd_m();
    let true_openings = truth.scene.building.openings.len();
    println!(
        "preset {preset}: {} true edges, {} openings, GSD {:.1} mm, {} reps",
        truth.lines.len(),
        true_openings,
        gsd * 1000.0,
        reps.max(1)
    );
    println!("| noise σ (GSD) | vertex RMSE (mm) | (GSD) | vertices matched | edge precision | edge recall | openings found (right kind) | corner RMSE (mm) | window/door faces (with frames, glass) | hidden edges completed | build (ms) | all-pairs junctions alone (ms) | ratio to the 1 s target |");
    println!("|---|---|---|---|---|---|---|---|---|---|---|---|---|");
    for &k in sigmas_gsd {
        let sigma = k * gsd;
        let NoisyInput {
            rows,
            lines,
            params,
            cameras,
        } = noisy_input(&truth, sigma, &base);
        let mut model = Model::default();
        let t_build = median_time(reps, || model = build(&lines, &params, &cameras));
        let t_pairs = median_time(reps, || {
            std::hint::black_box(junction::candidates_all_pairs(&lines, &params));
        });
        let vertices: Vec<Vec3> = model.vertices.iter().map(|v| v.point).collect();
        let edges: Vec<[usize; 2]> = model.observed_edges();
        let r = lineflow_eval::model::evaluate(&truth.lines, &vertices, &edges, gsd);
        let found: Vec<_> = model.openings().into_iter().map(lineflow_eval::model::ModelOpening::from).collect();
        let o = lineflow_eval::model::evaluate_openings(&truth.scene.building.openings, &found, gsd);
        println!(
            "| {k} | {:.1} | {:.2} | {}/{} | {:.1} % | {:.1} % | {}/{} ({}) | {:.1} | {} | {} | {:.0} | {:.0} | {:.2} |",
            r.vertex_rmse_m * 1000.0,
            r.vertex_rmse_m / gsd,
            r.matched_vertices,
            r.true_vertices,
            100.0 * r.edge_precision,
            100.0 * r.edge_recall,
            o.found,
            o.true_openings,
            o.kind_right,
            o.corner_rmse_m * 1000.0,
            model.count(&[SurfaceKind::Window, SurfaceKind::Door]),
            model.edges.len() - edges.len(),
            t_build * 1000.0,
            t_pairs * 1000.0,
            t_build / TARGET_S
        );
        eprintln!("  σ {k} GSD: {}", model.summary());
        if let Some(dir) = out {
            let dir = dir.join(format!("sigma{k}"));
            lineflow_formats::write_lines3d(&dir.join("lines3d.csv"), &rows)?;
            lineflow_formats::write_lines3d(&dir.join("truth.csv"), &truth.lines)?;
            export::write_obj(&dir.join("model.obj"), &model)?;
            export::write_cityjson(&dir.join("model.city.json"), &model)?;
        }
    }
    Ok(ExitCode::SUCCESS)
}
