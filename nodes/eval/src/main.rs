//! `lineflow-eval`: the live evaluation sink. Collects the ground truth (`gt/poses`, `gt/lines3d`) and whatever
//! results the graph produces (`poses`, `lines2d`, `lines3d`, `wireframe`, `faces`), and at end-of-stream writes `eval/report.md` into the run's
//! output folder. The scene is regenerated from the parameters of the graph's `synthetic` capture node.
use anyhow::{bail, Context, Result};
use lineflow_eval::{evaluate, model::ModelOpening, report, Results, Truth, Wireframe};
use lineflow_formats::{Line2Row, Line3Row, PoseRow};
use lineflow_messages::{kinds, parts, FaceVertex, WireEdge};
use lineflow_photogrammetry::Vec3;
use lineflow_runtime::{Flow, NodeContext};
use lineflow_synthetic::Synthetic;

fn main() -> std::process::ExitCode {
    lineflow_runtime::run_node(body)
}

/// The synthetic capture node's scene: preset, scale, seed as the launch file sets them (or their defaults).
fn scene_of_graph(ctx: &NodeContext) -> Result<Synthetic> {
    let graph = ctx.graph();
    // In a replay the player stands in for the capture node; its parameters travel with the graph.
    let Some(node) = graph
        .nodes
        .iter()
        .chain(&graph.replaced)
        .find(|n| n.stage.as_deref() == Some("capture") && n.implementation.as_deref().unwrap_or("synthetic") == "synthetic")
    else {
        bail!(
            "node '{}': eval needs a `synthetic` capture node in the graph (for folders, use `lineflow eval`)",
            ctx.name()
        );
    };
    let p = &node.params;
    let preset = p
        .get("preset")
        .and_then(|v| v.as_str())
        .unwrap_or(lineflow_synthetic::DEFAULT_PRESET);
    let scale = p.get("scale").and_then(|v| v.as_f64()).unwrap_or(lineflow_synthetic::DEFAULT_SCALE);
    let seed = p.get("seed").and_then(|v| v.as_u64()).unwrap_or(lineflow_synthetic::DEFAULT_SEED);
    Synthetic::new(preset, scale, seed).map_err(|e| anyhow::anyhow!("node '{}': {e}", ctx.name()))
}

fn pose_rows(syn: &Synthetic, poses: &[lineflow_messages::Pose]) -> Vec<PoseRow> {
    poses
        .iter()
        .filter(|p| (p.frame as usize) < syn.poses().len())
        .map(|p| PoseRow {
            image: syn.image_name(p.frame as usize),
            pose: p.exterior(),
            sigma_center_m: None,
            sigma_angles_deg: None,
        })
        .collect()
}

fn line_rows(lines: &[lineflow_messages::Line3]) -> Vec<Line3Row> {
    lines.iter().map(Line3Row::from).collect()
}

fn body() -> Result<()> {
    let ctx = NodeContext::from_env()?;
    let gt_poses = ctx.input::<kinds::Poses>("gt/poses")?;
    let gt_lines = ctx.input::<kinds::Lines3D>("gt/lines3d")?;
    let poses = ctx.optional_input::<kinds::Poses>("poses")?;
    let lines = ctx.optional_input::<kinds::Lines3D>("lines3d")?;
    let segments = ctx.optional_input::<kinds::Lines2D>("lines2d")?;
    let wireframe = ctx.optional_input::<kinds::Wireframe>("wireframe")?;
    let fitted = ctx.optional_input::<kinds::Wireframe>("wireframe_fitted")?;
    let faces = ctx.optional_input::<kinds::ModelFaces>("faces")?;
    let syn = scene_of_graph(&ctx)?;
    ctx.connect()?;

    // The newest message of each topic is the one that counts (a later revision supersedes an earlier one).
    let (mut truth_poses, mut truth_lines, mut est_poses, mut est_lines) = (Vec::new(), Vec::new(), None, None);
    let mut est_segments: Option<Vec<Line2Row>> = segments.as_ref().map(|_| Vec::new());
    let (mut est_model, mut est_fitted): (Option<Wireframe>, Option<Wireframe>) = (None, None);
    let mut est_faces: Option<Vec<FaceVertex>> = None;
    let mut model_hidden = 0usize;
    ctx.run(|| {
        while let Some(m) = gt_poses.receive()? {
            truth_poses = m.payload().to_vec();
        }
        while let Some(m) = gt_lines.receive()? {
            truth_lines = m.payload().to_vec();
        }
        if let Some(i) = &poses {
            while let Some(m) = i.receive()? {
                est_poses = Some(m.payload().to_vec());
            }
        }
        if let Some(i) = &lines {
            while let Some(m) = i.receive()? {
                est_lines = Some(m.payload().to_vec());
            }
        }
        if let (Some(i), Some(rows)) = (&segments, &mut est_segments) {
            i.for_each_segments(|h, segs, _| {
                rows.extend(segs.iter().map(|s| Line2Row {
                    image: h.name().to_string(),
                    id: s.id as u64,
                    start_px: s.start_px,
                    end_px: s.end_px,
                    n_pixels: Some(s.chain_len),
                }));
                Ok(())
            })?;
        }
        for (input, slot, mut hidden) in [
            (&wireframe, &mut est_model, Some(&mut model_hidden)),
            (&fitted, &mut est_fitted, None),
        ] {
            if let Some(i) = input {
                while let Some(m) = i.receive()? {
                    let h = m.user_header();
                    let (v, e) = parts::split::<[f64; 3], WireEdge>(m.payload(), h.n_vertices as usize, h.n_edges as usize)
                        .map_err(|e| anyhow::anyhow!("wireframe of frame {}: {e}", h.stamp.frame))?;
                    // Edges completed behind an occluder are not scored: the truth holds the edges seen in images.
                    *slot = Some((
                        v.iter().map(|p| Vec3::from(*p)).collect(),
                        e.iter().filter(|e| e.hidden == 0).map(|e| [e.a as usize, e.b as usize]).collect(),
                    ));
                    if let Some(n) = hidden.as_deref_mut() {
                        *n = e.iter().filter(|e| e.hidden != 0).count();
                    }
                }
            }
        }
        if let Some(i) = &faces {
            while let Some(m) = i.receive()? {
                est_faces = Some(m.payload().to_vec());
            }
        }
        let done = segments.as_ref().is_none_or(|i| i.is_ended())
            && faces.as_ref().is_none_or(|i| i.is_ended())
            && wireframe.as_ref().is_none_or(|i| i.is_ended())
            && fitted.as_ref().is_none_or(|i| i.is_ended())
            && gt_poses.is_ended()
            && gt_lines.is_ended()
            && poses.as_ref().is_none_or(|i| i.is_ended())
            && lines.as_ref().is_none_or(|i| i.is_ended());
        Ok(if done { Flow::Stop } else { Flow::Continue })
    })?;

    let out = ctx.out_dir();
    let truth = Truth {
        dir: out.clone(),
        poses: pose_rows(&syn, &truth_poses),
        lines: line_rows(&truth_lines),
        scene: syn,
    };
    let results = Results {
        poses: est_poses.map(|p| pose_rows(&truth.scene, &p)),
        lines3d: est_lines.map(|l| line_rows(&l)),
        lines2d: est_segments,
        // Written by the orientation stage before it ended its `poses`, so complete by now.
        checkpoints: match out.join("checkpoints.csv") {
            p if p.exists() => Some(lineflow_formats::read_checkpoints(&p).context("reading checkpoints.csv")?),
            _ => None,
        },
        model_openings: est_model.as_ref().zip(est_faces.as_ref()).map(|((v, _), f)| openings(v, f)),
        model_hidden_edges: est_model.as_ref().map(|_| model_hidden),
        model: est_model,
        model_fitted: est_fitted,
    };
    let evaluation = evaluate(&truth, &results);
    let path = report::write(&truth, &out, &evaluation, &out.join("eval")).context("writing the evaluation report")?;
    tracing::info!(
        "{} true poses, {} true edges; results: poses {}, lines2d {}, lines3d {} -> {}",
        truth.poses.len(),
        truth.lines.len(),
        if results.poses.is_some() { "yes" } else { "none" },
        if results.lines2d.is_some() { "yes" } else { "none" },
        if results.lines3d.is_some() { "yes" } else { "none" },
        path.display()
    );
    ctx.finish();
    Ok(())
}

/// The window and door faces (outer rings) of a `ModelFaces` message over its wire-frame's vertices.
fn openings(vertices: &[Vec3], faces: &[FaceVertex]) -> Vec<ModelOpening> {
    let (window, door) = (FaceVertex::KIND_WINDOW, FaceVertex::KIND_DOOR);
    let mut out: Vec<(u32, ModelOpening)> = Vec::new();
    for f in faces.iter().filter(|f| f.ring == 0 && (f.kind == window || f.kind == door)) {
        let Some(&p) = vertices.get(f.vertex as usize) else { continue };
        match out.last_mut() {
            Some((face, o)) if *face == f.face => o.ring.push(p),
            _ => out.push((
                f.face,
                ModelOpening {
                    door: f.kind == door,
                    ring: vec![p],
                },
            )),
        }
    }
    out.into_iter().map(|(_, o)| o).collect()
}
