//! `lineflow-eval`: the live evaluation sink. Collects the ground truth (`gt/poses`, `gt/lines3d`) and whatever
//! results the graph produces (`poses`, `lines2d`, `lines3d`, `wireframe`, `faces`), and at end-of-stream writes `eval/report.md` into the run's
//! output folder. The scene is regenerated from the parameters of the graph's `synthetic` capture node.
use anyhow::{bail, Context, Result};
use lineflow_eval::{evaluate, report, Truth};
use lineflow_eval_node::Collector;
use lineflow_messages::{kinds, parts, WireEdge};
use lineflow_runtime::{Flow, NodeContext};
use lineflow_synthetic::Synthetic;

fn main() -> std::process::ExitCode {
    lineflow_runtime::run_stage("eval", "report", &[("report", run)])
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

fn run(ctx: NodeContext) -> Result<()> {
    let gt_poses = ctx.input::<kinds::Poses>("gt/poses")?;
    let gt_lines = ctx.input::<kinds::Lines3D>("gt/lines3d")?;
    let poses = ctx.optional_input::<kinds::Poses>("poses")?;
    let lines = ctx.optional_input::<kinds::Lines3D>("lines3d")?;
    let segments = ctx.optional_input::<kinds::Lines2D>("lines2d")?;
    let wireframe = ctx.optional_input::<kinds::Wireframe>("wireframe")?;
    let fitted = ctx.optional_input::<kinds::Wireframe>("wireframe_fitted")?;
    let faces = ctx.optional_input::<kinds::ModelFaces>("faces")?;
    let mut syn = Some(scene_of_graph(&ctx)?);
    ctx.connect()?;

    let out = ctx.out_dir();
    let mut collected = Collector::new(segments.is_some());
    // Built once both truth topics are in (the capture node sends them before its first frame).
    let mut truth: Option<Truth> = None;
    ctx.run(|| {
        while let Some(m) = gt_poses.receive()? {
            collected.truth_poses = m.payload().to_vec();
        }
        while let Some(m) = gt_lines.receive()? {
            collected.truth_lines = m.payload().to_vec();
        }
        if let Some(i) = &poses {
            while let Some(m) = i.receive()? {
                collected.on_poses(m.payload());
            }
        }
        if let Some(i) = &lines {
            while let Some(m) = i.receive()? {
                collected.on_lines(m.payload());
            }
        }
        if let Some(i) = &segments {
            i.for_each_segments(|h, segs, _| {
                collected.on_segments(h, segs);
                Ok(())
            })?;
        }
        if truth.is_none() && collected.has_truth() {
            if let Some(scene) = syn.take() {
                truth = Some(collected.truth(scene, out.clone()));
            }
        }
        if let Some(t) = &truth {
            collected.score_segments(t);
        }
        for (input, is_fitted) in [(&wireframe, false), (&fitted, true)] {
            if let Some(i) = input {
                while let Some(m) = i.receive()? {
                    let h = m.user_header();
                    let (v, e) = parts::split::<[f64; 3], WireEdge>(m.payload(), h.n_vertices as usize, h.n_edges as usize)
                        .map_err(|e| anyhow::anyhow!("wireframe of frame {}: {e}", h.stamp.frame))?;
                    collected.on_wireframe(is_fitted, v, e);
                }
            }
        }
        if let Some(i) = &faces {
            while let Some(m) = i.receive()? {
                collected.on_faces(m.payload());
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

    // Written by the orientation stage before it ended its `poses`, so complete by now.
    let checkpoints = match out.join("checkpoints.csv") {
        p if p.exists() => Some(lineflow_formats::read_checkpoints(&p).context("reading checkpoints.csv")?),
        _ => None,
    };
    let truth = match truth {
        Some(truth) => truth,
        None => collected.truth(syn.take().context("the scene went into a truth that was not kept")?, out.clone()),
    };
    let results = collected.results(&truth, checkpoints);
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
