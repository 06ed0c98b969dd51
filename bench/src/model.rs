//! `lineflow bench model`: the model stage on the ground truth of a preset with noise added, accuracy and time.
use std::path::Path;
use std::process::ExitCode;

use anyhow::Result;
use lineflow_formats::Line3Row;
use lineflow_model::{build, export, junction, lines_from_rows, Cameras, Model, ModelLine, ModelParams, SurfaceKind};
use lineflow_photogrammetry::Vec3;
use lineflow_synthetic::{rng::Rng, Synthetic};

use crate::util::median_time;

/// The speed target: a façade with 40 openings built in at most this many seconds.
const TARGET_S: f64 = 1.0;

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
    let base = ModelParams::with_overrides(set)?;
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
    println!("| noise σ (GSD) | vertex RMSE (mm) | (GSD) | vertices matched | edge precision | edge recall | openings found (right kind) | corner RMSE (mm) | reveals right / measured (depth RMSE, mm) | window/door faces (with frames, glass) | hidden edges completed | build (ms) | all-pairs junctions alone (ms) | ratio to the 1 s target |");
    println!("|---|---|---|---|---|---|---|---|---|---|---|---|---|---|");
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
        let edges: Vec<[usize; 2]> = model.visible_edges();
        let r = lineflow_eval::model::evaluate(&truth.lines, &truth.every_edge(), &vertices, &edges, gsd);
        let found: Vec<_> = model.openings().into_iter().map(lineflow_eval::model::ModelOpening::from).collect();
        let o = lineflow_eval::model::evaluate_openings(&truth.scene.building.openings, &found, gsd);
        println!(
            "| {k} | {:.1} | {:.2} | {}/{} | {:.1} % | {:.1} % | {}/{} ({}) | {:.1} | {}/{} ({:.1}) | {} | {} | {:.0} | {:.0} | {:.2} |",
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
            o.reveals_right,
            o.reveals_measured,
            o.reveal_rmse_m * 1000.0,
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
