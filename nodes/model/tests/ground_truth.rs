//! The model of a synthetic façade's true edges with noise added, scored against the truth as `lineflow eval`
//! scores it (targets of issue #8: vertex RMSE ≤ 1 GSD, edge precision and recall ≥ 95 %).
use lineflow_eval::{model::evaluate, Truth};
use lineflow_model::{build, export, Cameras, LooseLines, Model, ModelLine, ModelParams, SurfaceKind};
use lineflow_photogrammetry::Vec3;
use lineflow_synthetic::{rng::Rng, Synthetic};

fn noisy_lines(truth: &Truth, sigma: f64) -> Vec<ModelLine> {
    let mut rng = Rng::new(7, 3);
    let mut jitter = move || Vec3::new(rng.normal(), rng.normal(), rng.normal()) * sigma;
    truth
        .lines
        .iter()
        .map(|l| ModelLine::new(l.start + jitter(), l.end + jitter(), sigma))
        .collect()
}

fn score(truth: &Truth, model: &Model) -> lineflow_eval::model::ModelReport {
    let v: Vec<Vec3> = model.vertices.iter().map(|v| v.point).collect();
    let e: Vec<[usize; 2]> = model.visible_edges();
    evaluate(&truth.lines, &truth.every_edge(), &v, &e, truth.gsd_m())
}

/// The a55 preset's truth, and its true edges with `sigma_gsd` GSD of noise per coordinate with the parameters
/// that say so, and the camera centres.
fn a55_noisy(sigma_gsd: f64) -> (Truth, ModelParams, Vec<ModelLine>, Cameras) {
    let truth = Truth::from_scene(Synthetic::new("a55-two-strips", 1.0, 1).unwrap());
    let sigma = sigma_gsd * truth.gsd_m();
    let params = ModelParams {
        sigma_m: sigma,
        ..ModelParams::default()
    };
    let lines = noisy_lines(&truth, sigma);
    let cameras = Cameras::new(truth.poses.iter().map(|p| p.pose.center).collect());
    (truth, params, lines, cameras)
}

#[test]
fn a55_true_edges_with_half_a_gsd_of_noise_give_the_model_within_one_gsd() {
    let (truth, params, lines, cameras) = a55_noisy(0.5);
    let gsd = truth.gsd_m();
    let model = build(&lines, &params, &cameras);
    let r = score(&truth, &model);
    assert!(
        r.vertex_rmse_m < gsd,
        "vertex RMSE {} mm, GSD {} mm",
        r.vertex_rmse_m * 1e3,
        gsd * 1e3
    );
    assert!(r.edge_precision > 0.95 && r.edge_recall > 0.95, "{r:?}");
    // σ̂0 near 1: the adjustment's precision model matches the noise. Alignment moves lines onto values shared
    // by many (known far better than one line's σ), which leaves Shape less to reconcile: σ̂0 is taken without it.
    let unaligned = build(
        &lines,
        &ModelParams {
            align: false,
            ..params.clone()
        },
        &cameras,
    );
    let s0 = unaligned.diagnostics.median_sigma0.unwrap();
    assert!((0.7..1.3).contains(&s0), "median sigma0 {s0}");
    let openings = model
        .faces
        .iter()
        .filter(|f| matches!(f.kind, SurfaceKind::Window | SurfaceKind::Door))
        .count();
    // a55: two floors of windows and a door, each an opening with its frame and panes behind it.
    assert!(openings >= 10, "{openings} openings");
    // The openings themselves, by the four corners of their outlines (35 of 40 with this noise when this was
    // written; 40 with the benchmark's).
    let found: Vec<_> = model.openings().into_iter().map(lineflow_eval::model::ModelOpening::from).collect();
    let o = lineflow_eval::model::evaluate_openings(&truth.scene.building.openings, &found, gsd);
    assert!(o.found >= 32 && o.kind_right == o.found, "{o:?}");
    assert!(model.faces.iter().any(|f| f.kind == SurfaceKind::Door), "no door");

    // Same lines, same bytes.
    let again = build(&lines, &params, &cameras);
    assert_eq!(export::obj_text(&model), export::obj_text(&again));
}

#[test]
fn a55_true_edges_with_one_gsd_of_noise_regularised_give_the_targets_edges() {
    // At 1 GSD the free lines' tilts (1.4 σ / L) blur which lines meet; turned plumb and level they meet cleanly.
    // Free here means neither regularised nor aligned (alignment needs regularised lines).
    let (truth, params, lines, cameras) = a55_noisy(1.0);
    let gsd = truth.gsd_m();
    let regular = score(&truth, &build(&lines, &params, &cameras));
    let free_params = ModelParams {
        regularise: false,
        ..params.clone()
    };
    let free = score(&truth, &build(&lines, &free_params, &cameras));
    eprintln!(
        "regularised: {:.2} GSD, P/R {:.3}/{:.3}; free: {:.2} GSD, P/R {:.3}/{:.3}",
        regular.vertex_rmse_m / gsd,
        regular.edge_precision,
        regular.edge_recall,
        free.vertex_rmse_m / gsd,
        free.edge_precision,
        free.edge_recall
    );
    assert!(regular.edge_precision > 0.95 && regular.edge_recall > 0.95, "{regular:?}");
    assert!(regular.vertex_rmse_m < 0.8 * free.vertex_rmse_m, "{regular:?} against {free:?}");
    // Aligned onto the storeys' heights, the frames' depths and the columns' positions, the vertices come within
    // the target: without alignment the two-line corners sit at the limit of two independent lines (σ / √2 per
    // coordinate each).
    let unaligned_params = ModelParams {
        align: false,
        ..params.clone()
    };
    let unaligned = score(&truth, &build(&lines, &unaligned_params, &cameras));
    eprintln!("unaligned: {:.2} GSD", unaligned.vertex_rmse_m / gsd);
    assert!(
        regular.vertex_rmse_m < gsd && regular.vertex_rmse_m < 0.97 * unaligned.vertex_rmse_m,
        "{regular:?} against {unaligned:?}"
    );
}

#[test]
fn noise_free_rectangles_in_any_order_give_the_same_corners() {
    // A wall with one window: the outline and the opening, then the same lines reversed and rotated in order.
    let rect = |x0: f64, z0: f64, x1: f64, z1: f64| {
        let p = [[x0, 0.0, z0], [x1, 0.0, z0], [x1, 0.0, z1], [x0, 0.0, z1]].map(Vec3::from);
        (0..4).map(move |k| ModelLine::new(p[k], p[(k + 1) % 4], 0.003)).collect::<Vec<_>>()
    };
    let mut lines = rect(0.0, 0.0, 10.0, 6.0);
    lines.extend(rect(2.0, 1.0, 3.5, 2.5));
    let params = ModelParams::default();
    let corners = |lines: &[ModelLine]| {
        let m = build(lines, &params, &Cameras::default());
        let mut c: Vec<[i64; 3]> = m
            .vertices
            .iter()
            .map(|v| [0, 1, 2].map(|k| (v.point[k] * 1e6).round() as i64))
            .collect();
        c.sort_unstable();
        (c, m)
    };
    let (first, model) = corners(&lines);
    assert_eq!(first.len(), 8);
    let mut shuffled: Vec<ModelLine> = lines.iter().rev().cloned().collect();
    shuffled.rotate_left(3);
    assert_eq!(corners(&shuffled).0, first);
    let wall = model.faces.iter().find(|f| f.kind == SurfaceKind::Wall).expect("a wall");
    assert_eq!(wall.holes.len(), 1);
    assert_eq!(model.faces.iter().filter(|f| f.kind == SurfaceKind::Window).count(), 1);
}

#[test]
fn bad_input_gives_an_empty_or_loose_model_without_panicking() {
    let params = ModelParams::default();
    assert_eq!(build(&[], &params, &Cameras::default()), Model::default());
    let nan = Vec3::new(f64::NAN, 0.0, 0.0);
    let degenerate = vec![
        ModelLine::new(nan, Vec3::new(1.0, 0.0, 0.0), 0.01),
        ModelLine::new(Vec3::zeros(), Vec3::zeros(), 0.01),
    ];
    let m = build(&degenerate, &params, &Cameras::default());
    assert!(m.vertices.is_empty() && m.faces.is_empty());
    // Two parallel lines: no corner, no face, both kept as loose edges when asked; by default, with no opening
    // they could belong to, they go.
    let parallel = vec![
        ModelLine::new(Vec3::zeros(), Vec3::new(1.0, 0.0, 0.0), 0.01),
        ModelLine::new(Vec3::new(0.0, 0.0, 1.0), Vec3::new(1.0, 0.0, 1.0), 0.01),
    ];
    let keep = ModelParams {
        loose_lines: LooseLines::Keep,
        ..ModelParams::default()
    };
    let m = build(&parallel, &keep, &Cameras::default());
    assert_eq!((m.edges.len(), m.faces.len(), m.diagnostics.lines_used), (2, 0, 0));
    assert!(export::cityjson(&m)["CityObjects"].as_object().unwrap().is_empty());
    let m = build(&parallel, &params, &Cameras::default());
    assert_eq!((m.edges.len(), m.diagnostics.loose_dropped), (0, 2));
}

/// Every image's visible true edges as 2-D lines in measured pixels, endpoints jittered by `sigma_px`.
fn true_image_lines(truth: &Truth, sigma_px: f64) -> Vec<lineflow_model::refine::ImageLines> {
    let cam = *truth.scene.camera();
    let mut rng = Rng::new(11, 5);
    (0..truth.poses.len())
        .map(|frame| {
            let ps = cam.pixel_size_mm;
            let segments: Vec<([f64; 2], [f64; 2])> = lineflow_eval::lines2d::visible_truth(truth, frame)
                .iter()
                .filter_map(|s| {
                    let mut px = |q: &Vec3| {
                        let m = cam.ideal_to_pixel([q[0] * ps, q[1] * ps])?;
                        Some([m[0] + sigma_px * rng.normal(), m[1] + sigma_px * rng.normal()])
                    };
                    Some((px(&s.a)?, px(&s.b)?))
                })
                .collect();
            lineflow_model::refine::ImageLines::new(&cam, Some(truth.poses[frame].pose), &segments, 20.0)
        })
        .collect()
}

/// RMS per object axis of the model's corners (vertices with σ) from their nearest true vertex within 3 GSD.
fn axis_rms(truth: &Truth, model: &Model) -> Vec3 {
    let true_vertices: Vec<Vec3> = truth.lines.iter().flat_map(|l| [l.start, l.end]).collect();
    let (mut sum, mut n) = (Vec3::zeros(), 0usize);
    for v in model.vertices.iter().filter(|v| v.sigma.is_some()) {
        let nearest = true_vertices
            .iter()
            .min_by(|a, b| (*a - v.point).norm().total_cmp(&(*b - v.point).norm()));
        if let Some(t) = nearest.filter(|t| (*t - v.point).norm() < 3.0 * truth.gsd_m()) {
            sum += (v.point - t).component_mul(&(v.point - t));
            n += 1;
        }
    }
    (sum / n.max(1) as f64).map(f64::sqrt)
}

#[test]
fn refine_with_the_images_lines_pins_the_corners_where_the_images_see_sharply() {
    // 3-D lines with 1 GSD of noise per coordinate give corners 1.5 GSD off (docs/model.md); the true edges as
    // 2-D lines (0.3 px of noise) in the 26 images are intersected through their interpretation planes.
    let (truth, params, lines, cameras) = a55_noisy(1.0);
    // Without alignment, which already shares heights and positions along the wall between the lines of a storey
    // or a column: here the image lines alone should pin them.
    let params = ModelParams {
        align: false,
        refine: true,
        ..params
    };
    let shaped = build(&lines, &params, &cameras);
    let image_lines = true_image_lines(&truth, 0.3);
    let images = lineflow_model::Images {
        camera: truth.scene.camera(),
        lines: &image_lines,
        params: lineflow_model::refine::RefineParams::default(),
    };
    let refined = lineflow_model::build_with_images(&lines, &params, &cameras, Some(&images));
    let (before, after) = (score(&truth, &shaped), score(&truth, &refined));
    let (axes_before, axes_after) = (axis_rms(&truth, &shaped), axis_rms(&truth, &refined));
    eprintln!(
        "shape only: {:.1} mm (X/Y/Z {:.1?}), refined ({} edges): {:.1} mm (X/Y/Z {:.1?})",
        before.vertex_rmse_m * 1e3,
        axes_before * 1e3,
        refined.diagnostics.lines_refined,
        after.vertex_rmse_m * 1e3,
        axes_after * 1e3
    );
    assert!(
        refined.diagnostics.lines_refined > refined.diagnostics.lines_used / 2,
        "{:?}",
        refined.diagnostics
    );
    // The cameras of a street-level strip see a façade edge sharply across their viewing rays and poorly along
    // them: the image lines pin the height of horizontal edges (Z) and, less, the position of vertical ones (X);
    // the depth (Y, the wall's normal) stays with the 3-D lines.
    assert!(axes_after.z < 0.7 * axes_before.z, "{axes_before:?} -> {axes_after:?}");
    assert!(
        axes_after.x < 0.85 * axes_before.x && axes_after.y < 1.1 * axes_before.y,
        "{axes_before:?} -> {axes_after:?}"
    );
    assert!(after.vertex_rmse_m < 0.9 * before.vertex_rmse_m, "{after:?}");
    // Refine changes where the corners are, not which edges there are.
    assert!(after.edge_recall >= before.edge_recall - 0.01, "{after:?}");
}
