//! `lineflow bench modelfit`: a façade model built (CSR, from the preset's true edges with noise) and fitted to
//! the edge pixels of every frame (LSMIF, free vertices, canny + combined), against the 1 s target and
//! against one adjustment of all vertices at once (no split into components), measured in the same run.
use std::process::ExitCode;
use std::time::Instant;

use anyhow::Result;
use lineflow_messages::Encoding;
use lineflow_model::{build, Model, SurfaceKind};
use lineflow_modelfit::parametric::DepthPrior;
use lineflow_modelfit::{fit, fit_wireframe, FacePlane, FitParams, FreeVertices, ImageEdges, Weighting};
use lineflow_photogrammetry::Vec3;
use lineflow_synthetic::Synthetic;

use crate::model::noisy_input;
use crate::util::median_time;

const TARGET_S: f64 = 1.0;

/// The model's faces for self-occlusion.
pub fn face_planes(model: &Model) -> Vec<FacePlane> {
    model
        .faces
        .iter()
        .map(|f| FacePlane {
            ring: f.ring.clone(),
            normal: f.normal,
        })
        .collect()
}

/// The modelfit node's façade settings for a camera of `pixel_mm` pixels.
pub fn facade_params(pixel_mm: f64) -> FitParams {
    lineflow_modelfit::wireframe::facade_params(pixel_mm)
}

pub struct Args<'a> {
    pub preset: &'a str,
    pub sigma_gsd: f64,
    pub frames: Option<usize>,
    pub weighting: Weighting,
    pub reps: usize,
    pub reference: bool,
    pub subpixel: bool,
    pub flat_textures: bool,
}

pub fn bench_modelfit(args: Args) -> Result<ExitCode> {
    let Args {
        preset,
        sigma_gsd,
        frames,
        weighting,
        reps,
        reference,
        subpixel,
        flat_textures,
    } = args;
    let mut scene = Synthetic::new(preset, 1.0, 1)?;
    scene.set_flat_textures(flat_textures);
    let truth = lineflow_eval::Truth::from_scene(scene);
    let gsd = truth.gsd_m();
    let spec = &truth.scene.building.spec;
    let camera = *truth.scene.camera();
    let frames = truth.scene.poses().len().min(frames.unwrap_or(usize::MAX));
    println!(
        "preset {preset}: {} true edges, {} openings, {frames} frames, GSD {:.1} mm, line noise σ {sigma_gsd} GSD",
        truth.lines.len(),
        spec.floors * spec.window_columns,
        gsd * 1000.0
    );
    let t = Instant::now();
    let (w, h) = (camera.width as usize, camera.height as usize);
    let images: Vec<ImageEdges> = (0..frames)
        .map(|f| {
            let rgb = truth.scene.render(f);
            let mut gray = vec![0u8; w * h];
            lineflow_imaging::gray_into(Encoding::Rgb8, w, h, w * 3, &rgb, &mut gray)?;
            let map = lineflow_edges::canny(&gray, w, h, 40.0, 100.0);
            let pixels = lineflow_edges::pixels(&gray, w, h, &map);
            eprint!(
                "\r  frame {}/{frames} rendered and edge-detected ({:.0} s)",
                f + 1,
                t.elapsed().as_secs_f64()
            );
            let at = subpixel.then(|| lineflow_imaging::subpixel_positions(&gray, w, h, &pixels));
            Ok(ImageEdges::with_positions(camera, truth.scene.poses()[f], &pixels, at.as_deref()))
        })
        .collect::<Result<_>>()?;
    eprintln!();

    let sigma = sigma_gsd * gsd;
    let input = noisy_input(&truth, sigma, &lineflow_model::ModelParams::default());
    let mut model = Model::default();
    let t_build = median_time(reps, || model = build(&input.lines, &input.params, &input.cameras));
    let vertices: Vec<Vec3> = model.vertices.iter().map(|v| v.point).collect();
    let edges: Vec<[usize; 2]> = model.visible_edges();
    let faces = face_planes(&model);
    let params = FitParams {
        weighting,
        ..facade_params(camera.pixel_size_mm)
    };
    let mut fitted = Default::default();
    let t_fit = median_time(reps, || fitted = fit_wireframe(&vertices, &edges, &faces, &images, &params));
    let every = truth.every_edge();
    let before = lineflow_eval::model::evaluate(&truth.lines, &every, &vertices, &edges, gsd);
    let after = lineflow_eval::model::evaluate(&truth.lines, &every, &fitted.vertices, &edges, gsd);
    println!(
        "model: {} vertices, {} edges, {} openings; {}",
        vertices.len(),
        edges.len(),
        model.count(&[SurfaceKind::Window, SurfaceKind::Door]),
        fitted.summary(camera.pixel_size_mm)
    );
    let moved: Vec<f64> = vertices.iter().zip(&fitted.vertices).map(|(a, b)| (a - b).norm() / gsd).collect();
    let mut sorted = moved.clone();
    sorted.sort_by(f64::total_cmp);
    eprintln!(
        "vertex moves (GSD): median {:.2}, 90 % {:.2}, max {:.2}",
        sorted[sorted.len() / 2],
        sorted[sorted.len() * 9 / 10],
        sorted[sorted.len() - 1]
    );
    {
        let (tv, _) = lineflow_eval::model::true_wireframe(&truth.lines);
        let per_axis = |vs: &[Vec3]| {
            let mut acc = [0.0; 3];
            let mut n = 0;
            for (i, v) in vs.iter().enumerate() {
                if !fitted.fitted[i] {
                    continue;
                }
                let t = tv.iter().min_by(|a, b| (*a - v).norm().total_cmp(&(*b - v).norm())).unwrap();
                if (t - v).norm() > 5.0 * gsd {
                    continue;
                }
                for k in 0..3 {
                    acc[k] += (v[k] - t[k]).powi(2);
                }
                n += 1;
            }
            acc.map(|a| (a / n.max(1) as f64).sqrt() / gsd)
        };
        eprintln!(
            "fitted vertices, per-axis RMS (GSD) before {:?} after {:?}",
            per_axis(&vertices),
            per_axis(&fitted.vertices)
        );
    }
    println!("| | vertex RMSE (mm) | (GSD) | matched | edge precision | edge recall |");
    println!("|---|---|---|---|---|---|");
    for (name, r) in [("CSR model", &before), ("after LSMIF", &after)] {
        println!(
            "| {name} | {:.1} | {:.2} | {}/{} | {:.1} % | {:.1} % |",
            r.vertex_rmse_m * 1000.0,
            r.vertex_rmse_m / gsd,
            r.matched_vertices,
            r.true_vertices,
            100.0 * r.edge_precision,
            100.0 * r.edge_recall
        );
    }
    println!(
        "build {:.0} ms + fit {:.0} ms = {:.0} ms (median of {reps}); ratio to the {TARGET_S} s target {:.2}",
        t_build * 1e3,
        t_fit * 1e3,
        (t_build + t_fit) * 1e3,
        (t_build + t_fit) / TARGET_S
    );
    if reference {
        let axis = images.iter().map(|i| i.pose.axis()).sum::<Vec3>().normalize();
        let one = FreeVertices::new(edges.clone(), faces.clone()).with_prior(DepthPrior {
            axis,
            lateral_m: lineflow_modelfit::wireframe::DEFAULT_PRIOR_M,
            depth_m: lineflow_modelfit::wireframe::DEFAULT_DEPTH_PRIOR_M,
        });
        let start = FreeVertices::pack(&vertices);
        let p = params.clone();
        let t = Instant::now();
        let f = fit(&one, &start, &images, &p);
        let t_dense = t.elapsed().as_secs_f64();
        println!(
            "reference, all {} vertices in one adjustment (no split into components): {:.0} ms ({}); ratio {:.1}",
            vertices.len(),
            t_dense * 1e3,
            if f.ok() { "ok" } else { "failed" },
            t_dense / t_fit
        );
    }
    Ok(ExitCode::SUCCESS)
}
