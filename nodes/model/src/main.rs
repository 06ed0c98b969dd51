//! `lineflow-model`: the model stage's process (`impl = "csr"`). Feeds [`lineflow_model::stage::ModelStage`],
//! publishes each rebuilt wire-frame (the live model) with its faces, and at end-of-stream writes `model.obj` and
//! `model.city.json`.
use anyhow::{Context, Result};
use lineflow_messages::{kinds, ModelFacesHeader, Stamp, WireframeHeader};
use lineflow_model::stage::{face_vertices, wire_edges, ModelStage};
use lineflow_model::{export, Model, ModelParams};
use lineflow_runtime::{Flow, NodeContext, Output};

fn main() -> std::process::ExitCode {
    lineflow_runtime::run_stage("model", "csr", &[("csr", run)])
}

/// Publishes the faces (when wired) and then the wire-frame, with the same stamp: a reader that has the wire-frame
/// has its faces.
fn publish(output: &Output<kinds::Wireframe>, faces: Option<&Output<kinds::ModelFaces>>, stamp: Stamp, model: &Model) -> Result<()> {
    if let Some(faces) = faces {
        let header = ModelFacesHeader {
            stamp,
            n_faces: model.faces.len() as u32,
            reserved: 0,
        };
        faces.publish(header, &face_vertices(model))?;
    }
    let vertices: Vec<[f64; 3]> = model.vertices.iter().map(|v| v.point.into()).collect();
    let edges = wire_edges(model);
    let header = WireframeHeader {
        stamp,
        n_vertices: vertices.len() as u32,
        n_edges: edges.len() as u32,
    };
    output.publish_parts(header, &vertices, &edges)
}

fn run(ctx: NodeContext) -> Result<()> {
    let params: ModelParams = ctx.stage_params()?;
    let lines_in = ctx.input::<kinds::Lines3D>("lines3d")?;
    let poses_in = ctx.optional_input::<kinds::Poses>("poses")?;
    // Refine and the openings' evidence need the images' 2-D lines, the camera and the poses.
    let lines2d_in = ctx.optional_input::<kinds::Lines2D>("lines2d")?;
    let camera_in = ctx.optional_input::<kinds::CameraModel>("camera")?;
    let output = ctx.output::<kinds::Wireframe>("wireframe")?;
    let faces_out = ctx.optional_output::<kinds::ModelFaces>("faces")?;
    ctx.connect()?;

    let images_wired = lines2d_in.is_some() && camera_in.is_some() && poses_in.is_some();
    let mut stage = ModelStage::new(params, images_wired);
    if stage.refine_unavailable() {
        tracing::warn!("refine needs the lines2d, camera and poses inputs wired: building without it");
    }
    ctx.run(|| {
        if let Some(cam) = &camera_in {
            while let Some(m) = cam.receive()? {
                stage.on_camera(m.user_header().camera());
            }
        }
        if let Some(poses) = &poses_in {
            while let Some(m) = poses.receive()? {
                stage.on_poses(m.payload());
            }
        }
        if let Some(lines2d) = &lines2d_in {
            lines2d.for_each_segments(|h, segs, _| {
                stage.on_segments(h.stamp.frame, segs);
                Ok(())
            })?;
        }
        while let Some(m) = lines_in.receive()? {
            stage.on_lines(m.user_header().stamp, m.payload());
        }
        let stamps = stage.rebuild();
        if let Some(newest) = stamps.last() {
            let model = stage.model();
            tracing::debug!(
                frame = newest.frame,
                lines = model.diagnostics.lines_in,
                vertices = model.vertices.len(),
                faces = model.faces.len(),
                "model rebuilt"
            );
        }
        for stamp in stamps {
            publish(&output, faces_out.as_ref(), stamp, stage.model())?;
        }
        Ok(if lines_in.is_ended() { Flow::Stop } else { Flow::Continue })
    })?;
    output.end_of_stream()?;
    if let Some(f) = &faces_out {
        f.end_of_stream()?;
    }
    let model = stage.model();
    let dir = ctx.out_dir();
    let (obj, city) = (dir.join("model.obj"), dir.join("model.city.json"));
    export::write_obj(&obj, model).with_context(|| format!("writing {}", obj.display()))?;
    export::write_cityjson(&city, model).with_context(|| format!("writing {}", city.display()))?;
    let d = &model.diagnostics;
    if d.lines_in > 0 && model.faces.is_empty() {
        tracing::warn!("no closed face among {} lines: the model is a loose wire-frame", d.lines_in);
    }
    tracing::info!("model: {} -> {}", model.summary(), obj.display());
    ctx.finish();
    Ok(())
}
