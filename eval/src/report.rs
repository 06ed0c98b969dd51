//! The Markdown report: tables first, pictures beside them.
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use anyhow::{Context, Result};

use crate::geometry::stats;
use crate::{plot, Evaluation, Truth};

fn pct(x: f64) -> String {
    if x.is_finite() {
        format!("{:.1} %", 100.0 * x)
    } else {
        "–".into()
    }
}

fn mm(x: f64) -> String {
    if x.is_finite() {
        format!("{:.1}", 1000.0 * x)
    } else {
        "–".into()
    }
}

/// Writes `report.md`, its pictures and `metrics.json` (`summary::summary`) into `out`; returns the report's path.
pub fn write(truth: &Truth, results: &Path, eval: &Evaluation, out: &Path) -> Result<PathBuf> {
    std::fs::create_dir_all(out).with_context(|| format!("cannot create {}", out.display()))?;
    let mut md = String::new();
    let cam = truth.scene.camera();
    let _ = writeln!(md, "# lineflow evaluation\n");
    let _ = writeln!(
        md,
        "Results `{}` against the ground truth `{}` (preset `{}`, scale {}, seed {}, {}×{} px, {} images, GSD {:.1} mm).\n",
        results.display(),
        truth.dir.display(),
        truth.scene.preset.name,
        truth.scene.scale,
        truth.scene.seed,
        cam.width,
        cam.height,
        truth.poses.len(),
        truth.gsd_m() * 1000.0
    );

    orientation_section(&mut md, eval);
    lines2d_section(&mut md, eval);
    lines3d_section(&mut md, eval, out)?;
    model_section(&mut md, truth, eval, out)?;
    let metrics = out.join("metrics.json");
    let json = serde_json::to_string_pretty(&crate::summary::summary(eval))?;
    std::fs::write(&metrics, json + "\n").with_context(|| format!("cannot write {}", metrics.display()))?;
    let path = out.join("report.md");
    std::fs::write(&path, md).with_context(|| format!("cannot write {}", path.display()))?;
    Ok(path)
}

/// Poses against the truth, and the check points.
fn orientation_section(md: &mut String, eval: &Evaluation) {
    let _ = writeln!(md, "## Orientation\n");
    match &eval.orientation {
        None => {
            let _ = writeln!(md, "No `poses.csv` in the results.\n");
        }
        Some(o) => {
            let _ = writeln!(
                md,
                "| images | missing | centre RMS (mm) | centre max (mm) | rotation RMS (°) | rotation max (°) |\n|---|---|---|---|---|---|\n| {} | {} | {} | {} | {:.4} | {:.4} |\n",
                o.images.len(),
                o.missing.len(),
                mm(o.rms_center_m),
                mm(o.max_center_m),
                o.rms_rotation_deg,
                o.max_rotation_deg
            );
            match o.checkpoints {
                Some((r, n)) => {
                    let _ = writeln!(
                        md,
                        "Check points ({n}): RMSE X {} mm, Y {} mm, Z {} mm.\n",
                        mm(r[0]),
                        mm(r[1]),
                        mm(r[2])
                    );
                }
                None => {
                    let _ = writeln!(md, "No `checkpoints.csv` in the results.\n");
                }
            }
            let _ = writeln!(md, "σ0 is not part of the result files; the orientation stage's log reports it.\n");
        }
    }
}

/// The 2-D segments per image.
fn lines2d_section(md: &mut String, eval: &Evaluation) {
    let _ = writeln!(md, "## 2-D lines (tolerance 1.5 px and 5°, corrected coordinates)\n");
    match &eval.lines2d {
        None => {
            let _ = writeln!(md, "No `lines2d.csv` in the results.\n");
        }
        Some(l) => {
            let _ = writeln!(
                md,
                "Length recall {}, length precision {} over all images.\n",
                pct(l.recall),
                pct(l.precision)
            );
            let _ = writeln!(
                md,
                "| image | true segments | estimated | recall | precision |\n|---|---|---|---|---|"
            );
            for i in &l.images {
                let _ = writeln!(
                    md,
                    "| {} | {} | {} | {} | {} |",
                    i.image,
                    i.n_true,
                    i.n_estimated,
                    pct(i.recall),
                    pct(i.precision)
                );
            }
            md.push('\n');
        }
    }
}

/// The 3-D lines: the thesis's tables, each class's figures, and the plots written beside the report.
/// The true edges of at least 0.5 m no line recovered, with what they belong to, for finding where lines go missing.
fn write_missed(l: &crate::lines3d::Lines3dReport, path: &Path) -> Result<()> {
    let mut csv =
        String::from("X1,Y1,Z1,X2,Y2,Z2,length_m,kind,class,resolvable,partner_found,nearest_dX,nearest_dY,nearest_dZ,nearest_coverage\n");
    for (g, e) in l.truth.iter().zip(&l.true_edges).filter(|(_, e)| e.found == Some(false)) {
        let _ = writeln!(
            csv,
            "{:.6},{:.6},{:.6},{:.6},{:.6},{:.6},{:.3},{},{},{},{},{}",
            g.a.x,
            g.a.y,
            g.a.z,
            g.b.x,
            g.b.y,
            g.b.z,
            g.length(),
            e.kind,
            format!("{:?}", e.class).to_lowercase(),
            e.resolvable,
            e.partner_found,
            e.nearest.map_or(",,,".to_owned(), |n| format!(
                "{:.4},{:.4},{:.4},{:.3}",
                n.offset.x, n.offset.y, n.offset.z, n.coverage
            ))
        );
    }
    std::fs::write(path, csv).with_context(|| format!("writing {}", path.display()))
}

fn lines3d_section(md: &mut String, eval: &Evaluation, out: &Path) -> Result<()> {
    let _ = writeln!(md, "## 3-D lines\n");
    match &eval.lines3d {
        None => {
            let _ = writeln!(md, "No `lines3d.csv` in the results.\n");
        }
        Some(l) => {
            let matched = l.matched.iter().filter(|m| m.is_some()).count();
            let (em, es, ex) = stats(&l.endpoint_m);
            let (am, as_, ax) = stats(&l.angle_deg);
            let (lm, ls, lx) = stats(&l.angle_long_deg);
            let _ = writeln!(
                md,
                "{} estimated segments, {} matched to a true edge (within 10° and 5 GSD); {} true edges.\n",
                l.estimated.len(),
                matched,
                l.truth.len()
            );
            let _ = writeln!(
                md,
                "The thesis's tables (Tables 4-6, 4-8):\n\n| | mean | std | max |\n|---|---|---|---|\n| endpoint perpendicular distance (mm) | {} | {} | {} |\n| angle (°) | {:.3} | {:.3} | {:.3} |\n| angle, edges ≥ 1 m (°) | {:.3} | {:.3} | {:.3} |\n",
                mm(em),
                mm(es),
                mm(ex),
                am,
                as_,
                ax,
                lm,
                ls,
                lx
            );
            for c in &l.classes {
                let _ = writeln!(
                    md,
                    "### {} ({} true, {} estimated); success rate {}\n\nOver the {} edges of at least 0.5 m that at least {} images show {} px or more from every parallel true edge beside them: {}. At most (the images): {}, where of two edges more than 4 GSD apart that no two images show apart only one counts.\n\n| τ | P_τ (segments) | precision (length) | recall (length) | precision vs surfaces |\n|---|---|---|---|---|",
                    if c.class.ends_with("lines") {
                        c.class.to_string()
                    } else {
                        format!("{} edges", c.class)
                    },
                    c.n_true,
                    c.n_estimated,
                    pct(c.success_rate),
                    c.n_resolvable,
                    crate::resolvable::RESOLVE_VIEWS,
                    crate::resolvable::RESOLVE_PX,
                    pct(c.success_resolvable),
                    pct(c.success_ceiling)
                );
                for a in &c.at {
                    let _ = writeln!(
                        md,
                        "| {} ({:.1} mm) | {} | {} | {} | {} |",
                        a.label,
                        a.tau_m * 1000.0,
                        pct(a.segment_precision),
                        pct(a.length_precision),
                        pct(a.length_recall),
                        pct(a.surface_precision)
                    );
                }
                md.push('\n');
            }
            let kinds = l.kinds();
            if !kinds.is_empty() {
                md.push_str("### Success by part of the building\n\nTrue edges of at least 0.5 m, by what they belong to in the synthetic scene; resolvable as above.\n\n| part | edges | found | success | resolvable | found of those |\n|---|---|---|---|---|---|\n");
                for k in &kinds {
                    let share = |n: usize, of: usize| if of == 0 { f64::NAN } else { n as f64 / of as f64 };
                    let _ = writeln!(
                        md,
                        "| {} | {} | {} | {} | {} | {} |",
                        k.kind,
                        k.n_long,
                        k.n_found,
                        pct(share(k.n_found, k.n_long)),
                        k.n_resolvable,
                        k.n_found_resolvable
                    );
                }
                md.push('\n');
                write_missed(l, &out.join("lines3d_missed.csv"))?;
                md.push_str("The true edges of at least 0.5 m that were not found: `lines3d_missed.csv`.\n\n");
            }
            let max_error = (5.0 * l.gsd_m).max(0.01);
            plot::histogram(&l.endpoint_m, max_error, 25, &out.join("lines3d_endpoint_hist.png"))?;
            plot::view(
                &l.truth,
                &l.estimated,
                &l.error_m,
                max_error,
                (0, 2),
                &out.join("lines3d_front.png"),
            )?;
            plot::view(&l.truth, &l.estimated, &l.error_m, max_error, (0, 1), &out.join("lines3d_top.png"))?;
            let _ = writeln!(
                md,
                "Endpoint distances, 0 to {:.0} mm in 25 bars (the last collects the rest):\n\n![histogram](lines3d_endpoint_hist.png)\n\nFront view (X right, Z up) and top view (X right, Y up): true edges grey, estimates coloured by mean endpoint distance from green (0) to red ({:.0} mm and more), magenta where unmatched.\n\n![front](lines3d_front.png)\n\n![top](lines3d_top.png)\n",
                max_error * 1000.0,
                max_error * 1000.0
            );
        }
    }
    Ok(())
}

/// The models' vertices and edges, hidden edges and openings.
fn model_section(md: &mut String, truth: &Truth, eval: &Evaluation, out: &Path) -> Result<()> {
    let _ = writeln!(md, "## Model\n");
    let models = [
        ("CSR (`model.obj`)", &eval.model),
        ("fitted to the images (`model_fitted.obj`)", &eval.model_fitted),
    ];
    if models.iter().all(|(_, m)| m.is_none()) {
        let _ = writeln!(md, "No `model.obj` in the results.\n");
    }
    for (i, m) in models.iter().filter_map(|(name, m)| m.as_ref().map(|m| (name, m))).enumerate() {
        let (name, m) = m;
        if i == 0 {
            let _ = writeln!(
                md,
                "| model | true vertices | model vertices | matched (≤ {} mm) | vertex RMSE (mm) | vertex RMSE (GSD) | true edges | model edges | edge precision | edge recall (ends ≤ {} mm) |\n|---|---|---|---|---|---|---|---|---|---|",
                mm(m.vertex_reach_m),
                mm(m.edge_tolerance_m)
            );
        }
        let _ = writeln!(
            md,
            "| {name} | {} | {} | {} | {} | {:.2} | {} | {} | {} | {} |",
            m.true_vertices,
            m.model_vertices,
            m.matched_vertices,
            mm(m.vertex_rmse_m),
            m.vertex_rmse_m / m.gsd_m,
            m.true_edges,
            m.model_edges,
            pct(m.edge_precision),
            pct(m.edge_recall)
        );
    }
    let _ = writeln!(md);
    if let Some(n) = eval.model.as_ref().map(|m| m.unseen_edges).filter(|&n| n > 0) {
        let _ = writeln!(
            md,
            "{n} edges of the model lie on edges of the building that fewer than two images see; they are left out of the precision (`docs/eval.md`).\n"
        );
    }
    if let Some(n) = eval.hidden_edges.filter(|&n| n > 0) {
        let _ = writeln!(
            md,
            "{n} edges of the CSR model were completed behind an occluder (`docs/model.md`); they are not scored, as the truth holds the edges seen in two images.\n"
        );
    }
    if let Some(s) = eval.surface_lines.filter(|s| s.lines > 0) {
        let _ = writeln!(
            md,
            "{} lines lying inside a wall's surface (mortar, tile and panel joints) were set aside from the model's edges (`surface_lines`, `docs/model.md`); {} of them are true edges after all.\n",
            s.lines, s.true_edges
        );
    }
    if let Some(o) = &eval.openings {
        let _ = writeln!(
            md,
            "Openings of the CSR model: {} of {} true windows and doors found (a model window or door face with a vertex within {} mm of each of the four corners of the opening's outline), {} of them of the right kind, corner RMSE {} mm; {} window and door faces in the model (frames and panes behind an opening included). Reveals: {} of the found openings have a frame or door face behind their outline (without one the model's opening is flush); {} of the found openings have their reveal depth within {} mm of the truth, depth RMSE {} mm.\n",
            o.found,
            o.true_openings,
            mm(o.reach_m),
            o.kind_right,
            mm(o.corner_rmse_m),
            o.model_openings,
            o.reveals_measured,
            o.reveals_right,
            mm(o.reveal_tolerance_m),
            mm(o.reveal_rmse_m)
        );
    }
    if let Some(m) = &eval.model {
        let max_error = m.edge_tolerance_m;
        for (axes, file) in [((0, 2), "model_front.png"), ((0, 1), "model_top.png")] {
            plot::view(
                &m.true_segments,
                &m.edge_segments,
                &m.edge_error_m,
                max_error,
                axes,
                &out.join(file),
            )?;
        }
        let _ = writeln!(
            md,
            "The CSR model's edges in a front view (X right, Z up) and a top view (X right, Y up): true edges grey, model edges that match one coloured by the mean distance of their ends from green (0) to red ({} mm), magenta where they match none.\n\n![model front](model_front.png)\n\n![model top](model_top.png)\n",
            mm(max_error)
        );
        if let Some(frame) = model_over_image(truth, m, &out.join("model_image.png"))? {
            let _ = writeln!(
                md,
                "The same edges over {} (the true pose), coloured alike:\n\n![model over an image](model_image.png)\n",
                truth.scene.image_name(frame)
            );
        }
    }
    Ok(())
}

/// Draws the model's edges over the middle image of the scene, projected with its true pose; returns the frame, or
/// `None` when the scene has no images.
fn model_over_image(truth: &Truth, m: &crate::model::ModelReport, path: &Path) -> Result<Option<usize>> {
    let poses = truth.scene.poses();
    if poses.is_empty() {
        return Ok(None);
    }
    let frame = poses.len() / 2;
    let camera = truth.scene.camera();
    let Some(img) = image::RgbImage::from_raw(camera.width, camera.height, truth.scene.render(frame)) else {
        return Ok(None);
    };
    // Sampled along the edge so that a straight edge bends with the lens's distortion as in the photograph.
    let pieces: Vec<(Vec<(f64, f64)>, f64)> = m
        .edge_segments
        .iter()
        .zip(&m.edge_error_m)
        .map(|(s, &e)| {
            let points = (0..=16)
                .filter_map(|k| poses[frame].project(camera, &(s.a + (s.b - s.a) * (k as f64 / 16.0))))
                .map(|p| (p[0], p[1]))
                .collect();
            (points, e)
        })
        .collect();
    plot::over_image(img, &pieces, m.edge_tolerance_m, path)?;
    Ok(Some(frame))
}
