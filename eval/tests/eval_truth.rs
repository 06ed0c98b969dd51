//! `eval` gives perfect scores for the ground truth itself and the analytically expected scores for known
//! perturbations.
use lineflow_eval::{evaluate, lines2d, Lines2d, Results, Truth};
use lineflow_formats::{read_lines3d, read_poses, Line2Row, Line3Row};
use lineflow_photogrammetry::Vec3;
use lineflow_synthetic::{write_project, Synthetic};

fn scene() -> (tempfile::TempDir, Truth) {
    let dir = tempfile::tempdir().unwrap();
    let syn = Synthetic::new("convergent", 0.08, 5).unwrap();
    write_project(&syn, dir.path(), &mut |_, _| {}).unwrap();
    let truth = Truth::load(dir.path()).unwrap();
    (dir, truth)
}

/// The visible parts of the true edges, written as a 2-D line detector would (measured pixel endpoints).
fn true_lines2d(truth: &Truth, offset_px: f64) -> Vec<Line2Row> {
    let cam = truth.scene.camera();
    let ps = cam.pixel_size_mm;
    let mut rows = Vec::new();
    for (frame, pose) in truth.poses.iter().enumerate() {
        for (id, s) in lines2d::visible_truth(truth, frame).iter().enumerate() {
            let d = s.dir();
            let n = [-d.y * offset_px, d.x * offset_px];
            let end = |p: Vec3| cam.ideal_to_pixel([(p.x + n[0]) * ps, (p.y + n[1]) * ps]).unwrap();
            rows.push(Line2Row {
                image: pose.image.clone(),
                id: id as u64,
                start_px: end(s.a),
                end_px: end(s.b),
                n_pixels: None,
            });
        }
    }
    rows
}

#[test]
fn the_truth_scores_perfectly_and_known_shifts_score_as_expected() {
    let (dir, truth) = scene();
    let gt = dir.path().join("gt");
    let poses = read_poses(&gt.join("poses.csv")).unwrap();
    let lines = read_lines3d(&gt.join("lines3d.csv")).unwrap();

    // The ground truth against itself.
    let perfect = evaluate(
        &truth,
        &Results {
            poses: Some(poses.clone()),
            checkpoints: None,
            lines2d: Some(Lines2d::Rows(true_lines2d(&truth, 0.0))),
            lines3d: Some(lines.clone()),
            model: Some(lineflow_eval::model::true_wireframe(&lines)),
            model_fitted: Some(lineflow_eval::model::true_wireframe(&lines)),
            model_hidden_edges: None,
            model_surface_lines: None,
            model_openings: Some(
                truth
                    .scene
                    .building
                    .openings
                    .iter()
                    .map(|o| lineflow_eval::model::ModelOpening {
                        door: o.door,
                        ring: o.corners.iter().map(|&c| c.into()).collect(),
                    })
                    .collect(),
            ),
        },
    );
    for m in [perfect.model.as_ref().unwrap(), perfect.model_fitted.as_ref().unwrap()] {
        assert_eq!((m.edge_precision, m.edge_recall, m.vertex_rmse_m), (1.0, 1.0, 0.0), "{m:?}");
        assert_eq!(m.matched_vertices, m.true_vertices);
    }
    // Every edge of the true model matches with no error; the report draws it.
    let m = perfect.model.as_ref().unwrap();
    assert!(
        m.edge_error_m.iter().all(|e| *e < 1e-12),
        "{:?}",
        m.edge_error_m.iter().max_by(|a, b| a.total_cmp(b))
    );
    let report_dir = dir.path().join("eval");
    lineflow_eval::report::write(&truth, dir.path(), &perfect, &report_dir).unwrap();
    for f in ["model_front.png", "model_top.png", "model_image.png"] {
        assert!(report_dir.join(f).is_file(), "no {f}");
    }
    // Surface lines: true edges set aside count as the class's mistakes; lines a metre off do not.
    let (v, e) = lineflow_eval::model::true_wireframe(&lines);
    let wrong = lineflow_eval::model::evaluate_surface_lines(&lines, &v, &e[..5], truth.gsd_m());
    assert_eq!((wrong.lines, wrong.true_edges), (5, 5));
    let off: Vec<Vec3> = v.iter().map(|p| p + Vec3::new(0.0, 1.0, 0.0)).collect();
    let right = lineflow_eval::model::evaluate_surface_lines(&lines, &off, &e[..5], truth.gsd_m());
    assert_eq!((right.lines, right.true_edges), (5, 0));

    let openings = perfect.openings.as_ref().unwrap();
    assert!(openings.true_openings > 0 && truth.scene.building.openings.iter().any(|o| o.door));
    assert_eq!(
        (openings.found, openings.kind_right),
        (openings.true_openings, openings.true_openings)
    );
    assert_eq!(openings.corner_rmse_m, 0.0);
    let o = perfect.orientation.as_ref().unwrap();
    assert!(o.rms_center_m < 1e-5 && o.rms_rotation_deg < 1e-5 && o.missing.is_empty());
    let l2 = perfect.lines2d.as_ref().unwrap();
    assert!(
        l2.recall > 0.99 && l2.precision > 0.99,
        "2-D: recall {} precision {}",
        l2.recall,
        l2.precision
    );
    let l3 = perfect.lines3d.as_ref().unwrap();
    assert_eq!(l3.matched.iter().filter(|m| m.is_some()).count(), lines.len());
    assert!(l3.endpoint_m.iter().all(|d| *d < 1e-5));
    // The true edges are all classed structure: the structure lines score as all lines, no texture line is there.
    let texture = l3
        .classes
        .iter()
        .find(|c| c.class == "texture lines")
        .expect("classed lines are scored by class");
    assert_eq!(texture.n_estimated, 0);
    let kinds = l3.kinds();
    // Every true edge is found under the kind the scene gave it (the file's micrometres still find their edge).
    assert!(kinds.iter().all(|k| k.kind != "other" && k.n_found == k.n_long), "{:?}", kinds);
    assert!(kinds.iter().any(|k| k.kind == "opening") && kinds.iter().any(|k| k.kind == "outline"));
    for c in l3.classes.iter().filter(|c| c.class != "texture lines") {
        assert!((c.success_rate - 1.0).abs() < 1e-12, "{}: success {}", c.class, c.success_rate);
        assert!(
            c.n_resolvable > 0 && (c.success_resolvable - 1.0).abs() < 1e-12,
            "{}: {c:?}",
            c.class
        );
        for a in &c.at {
            assert!(
                a.segment_precision == 1.0 && a.length_recall > 0.999 && a.surface_precision > 0.999,
                "{} {}",
                c.class,
                a.label
            );
        }
    }

    // Every 3-D line moved 1 cm towards the street (−Y): lines along Y keep distance 0, all others 10 mm.
    let shift = Vec3::new(0.0, -0.01, 0.0);
    let moved: Vec<Line3Row> = lines
        .iter()
        .map(|l| Line3Row {
            start: l.start + shift,
            end: l.end + shift,
            ..l.clone()
        })
        .collect();
    let expected: Vec<f64> = lines
        .iter()
        .map(|l| {
            let d = (l.end - l.start).normalize();
            (shift - d * shift.dot(&d)).norm()
        })
        .collect();
    let shifted = evaluate(
        &truth,
        &Results {
            lines3d: Some(moved),
            lines2d: Some(Lines2d::Rows(true_lines2d(&truth, 3.0))),
            ..Default::default()
        },
    );
    let l3 = shifted.lines3d.as_ref().unwrap();
    let mean = l3.endpoint_m.iter().sum::<f64>() / l3.endpoint_m.len() as f64;
    let want = expected.iter().sum::<f64>() / expected.len() as f64;
    assert!((mean - want).abs() < 1e-6, "mean endpoint distance {mean}, expected {want}");
    let all = &l3.classes[0];
    let at = |label: &str| all.at.iter().find(|a| a.label == label).unwrap();
    let share_along_y = expected.iter().filter(|d| **d < 1e-9).count() as f64 / expected.len() as f64;
    assert!(
        (at("5 mm").segment_precision - share_along_y).abs() < 1e-9,
        "P_5mm {} vs {share_along_y}",
        at("5 mm").segment_precision
    );
    assert_eq!(at("20 mm").segment_precision, 1.0);
    assert!(at("20 mm").length_recall > 0.999);
    // Moving off the façade by 1 cm keeps every point within 20 mm of the surfaces but not within 5 mm
    // (except where another surface is near).
    assert!(at("20 mm").surface_precision > 0.999);
    // 2-D segments moved 3 px sideways leave the 1.5 px tolerance; what still counts lies on another, parallel edge
    // (frame, reveal and opening edges run a pixel or two apart at this scale).
    let l2 = shifted.lines2d.as_ref().unwrap();
    assert!(
        l2.recall < 0.5 && l2.precision < 0.5,
        "shifted 2-D: recall {} precision {}",
        l2.recall,
        l2.precision
    );
    // Moved 1 px, inside the tolerance: still perfect.
    let near = evaluate(
        &truth,
        &Results {
            lines2d: Some(Lines2d::Rows(true_lines2d(&truth, 1.0))),
            ..Default::default()
        },
    );
    let l2 = near.lines2d.as_ref().unwrap();
    assert!(
        l2.recall > 0.99 && l2.precision > 0.99,
        "1 px: recall {} precision {}",
        l2.recall,
        l2.precision
    );
}

#[test]
fn a_folder_without_ground_truth_is_named() {
    let dir = tempfile::tempdir().unwrap();
    let e = Truth::load(dir.path()).err().unwrap().to_string();
    assert!(e.contains("scene.json") && e.contains("lineflow synth"), "{e}");
}

#[test]
fn frames_scored_one_by_one_report_as_the_rows_scored_at_once() {
    let (_dir, truth) = scene();
    let rows = true_lines2d(&truth, 1.0);
    let at_once = lines2d::evaluate(&truth, &rows);
    // Every frame but the last scored as its lines came; the last never came.
    let last = truth.poses.len() - 1;
    let scored: std::collections::BTreeMap<usize, lines2d::ImageScores> = (0..last)
        .map(|frame| {
            let name = &truth.poses[frame].image;
            let own: Vec<Line2Row> = rows.iter().filter(|r| &r.image == name).cloned().collect();
            (frame, lines2d::score_image(&truth, frame, &own))
        })
        .collect();
    let one_by_one = lines2d::evaluate_scored(&truth, &scored);
    assert_eq!(one_by_one.images.len(), at_once.images.len());
    for (a, b) in one_by_one.images.iter().zip(&at_once.images).take(last) {
        assert_eq!((a.lengths, a.n_estimated), (b.lengths, b.n_estimated));
    }
    assert_eq!(one_by_one.images[last].n_estimated, 0, "a frame whose lines never came has none");
    assert!(at_once.images[last].n_estimated > 0);
    assert!(one_by_one.recall < at_once.recall);
}

/// `lineflow synth --no-images`: the same project files and truth as a full write, and no images to score a live
/// run against.
#[test]
fn the_project_files_without_images_hold_the_same_truth() {
    let (full, truth) = scene();
    let bare = tempfile::tempdir().unwrap();
    let syn = Synthetic::new("convergent", 0.08, 5).unwrap();
    lineflow_synthetic::write_project_files(&syn, bare.path()).unwrap();
    assert!(!bare.path().join("images").exists());
    // Every file written is listed: the top folder's files and gt/'s, and nothing else.
    let listed = |dir: &std::path::Path| {
        std::fs::read_dir(dir)
            .unwrap()
            .filter(|e| e.as_ref().unwrap().path().is_file())
            .count()
    };
    assert_eq!(
        listed(bare.path()) + listed(&bare.path().join("gt")),
        lineflow_synthetic::PROJECT_FILES.len()
    );
    for file in lineflow_synthetic::PROJECT_FILES {
        let read = |dir: &std::path::Path| std::fs::read(dir.join(file)).unwrap();
        assert_eq!(read(full.path()), read(bare.path()), "{file}");
    }
    let again = Truth::load(bare.path()).unwrap();
    assert_eq!(again.poses.len(), truth.poses.len());
}
