//! `lineflow-modelfit`: the modelfit stage's process (`impl = "lsmif"`). Feeds
//! [`lineflow_modelfit::stage::FitStage`]; at end-of-stream fits the final wire-frame with the final poses,
//! publishes it and writes `model_fitted.obj` and `model_fitted.city.json`, with the faces of the `faces` topic
//! when it is wired. With `live_interval_frames` > 0 it also fits the newest wire-frame on a worker thread every so
//! many new edge maps and publishes each fit.
use anyhow::Result;
use lineflow_messages::{kinds, parts, WireEdge, WireframeHeader};
use lineflow_modelfit::stage::{FitStage, Job, LsmifParams, Wire};
use lineflow_photogrammetry::Vec3;
use lineflow_runtime::{Flow, NodeContext, Output};

fn main() -> std::process::ExitCode {
    lineflow_runtime::run_stage("modelfit", "lsmif", &[("lsmif", run)])
}

fn publish(output: &Output<kinds::Wireframe>, wire: &Wire, vertices: &[Vec3]) -> Result<()> {
    let v: Vec<[f64; 3]> = vertices.iter().map(|p| [p.x, p.y, p.z]).collect();
    let header = WireframeHeader {
        stamp: wire.stamp,
        n_vertices: v.len() as u32,
        n_edges: wire.edges.len() as u32,
    };
    output.publish_parts(header, &v, &wire.edges)
}

fn run(ctx: NodeContext) -> Result<()> {
    let params: LsmifParams = ctx.stage_params()?;
    let wire_in = ctx.input::<kinds::Wireframe>("wireframe")?;
    let edges_in = ctx.input::<kinds::EdgeMap>("edges")?;
    let poses_in = ctx.input::<kinds::Poses>("poses")?;
    let camera_in = ctx.input::<kinds::CameraModel>("camera")?;
    let faces_in = ctx.optional_input::<kinds::ModelFaces>("faces")?;
    let output = ctx.output::<kinds::Wireframe>("wireframe_fitted")?;
    ctx.connect()?;

    let mut stage = FitStage::new(params);
    let named = |e: lineflow_modelfit::stage::FitStageError| anyhow::anyhow!("node '{}': {e}", ctx.name());
    // Live fits run on a worker so that the edge maps keep flowing in while one is under way.
    let (jobs_tx, jobs_rx) = crossbeam::channel::bounded::<Job>(1);
    let (done_tx, done_rx) = crossbeam::channel::bounded::<(Wire, Vec<Vec3>)>(1);
    let worker = std::thread::Builder::new().name("modelfit-live".into()).spawn(move || {
        for job in jobs_rx {
            let fitted = job.run();
            if done_tx.send((job.wire, fitted)).is_err() {
                break;
            }
        }
    })?;
    let mut busy = false;
    ctx.run(|| {
        while let Some(m) = camera_in.receive()? {
            stage.on_camera(m.user_header().camera()).map_err(named)?;
        }
        while let Some(m) = edges_in.receive()? {
            stage.on_edges(m.user_header().stamp.frame, m.payload());
        }
        while let Some(m) = poses_in.receive()? {
            stage.on_poses(m.payload());
        }
        if let Some(faces) = &faces_in {
            while let Some(m) = faces.receive()? {
                stage.on_faces(m.user_header().stamp, m.payload());
            }
        }
        while let Some(m) = wire_in.receive()? {
            let h = *m.user_header();
            let (v, e) = parts::split::<[f64; 3], WireEdge>(m.payload(), h.n_vertices as usize, h.n_edges as usize)
                .map_err(|e| anyhow::anyhow!("wireframe of frame {}: {e}", h.stamp.frame))?;
            stage.on_wireframe(h.stamp, v, e).map_err(named)?;
        }
        if let Ok((wire, fitted)) = done_rx.try_recv() {
            publish(&output, &wire, &fitted)?;
            busy = false;
        }
        // The faces of the last wire-frame follow it on their own topic: wait for their end too, or the fitted
        // model can be written without them.
        let faces_ended = faces_in.as_ref().is_none_or(|f| f.is_ended());
        let ended = wire_in.is_ended() && edges_in.is_ended() && poses_in.is_ended() && faces_ended;
        if !busy {
            if let Some(job) = stage.live_job(ended) {
                busy = jobs_tx.try_send(job).is_ok();
            }
        }
        Ok(if ended { Flow::Stop } else { Flow::Continue })
    })?;
    drop(jobs_tx);
    if let Ok((wire, fitted)) = done_rx.recv() {
        publish(&output, &wire, &fitted)?;
    }
    let _ = worker.join();
    // The end: the final wire-frame against the final poses.
    let fitted = match stage.final_job() {
        Ok(job) => {
            let v = job.run();
            publish(&output, &job.wire, &v)?;
            Some((job.wire, v))
        }
        Err(why) => {
            tracing::warn!("{why}");
            None
        }
    };
    output.end_of_stream()?;
    if let Some((wire, vertices)) = fitted {
        let (model, warning) = stage.fitted_model(&wire, &vertices);
        if let Some(why) = warning {
            tracing::warn!("{why}; the fitted model is written without faces");
        }
        let dir = ctx.out_dir();
        let (obj, city) = (dir.join("model_fitted.obj"), dir.join("model_fitted.city.json"));
        lineflow_model::export::write_obj(&obj, &model)?;
        lineflow_model::export::write_cityjson(&city, &model)?;
        tracing::info!("fitted model ({} faces) -> {}", model.faces.len(), obj.display());
    }
    ctx.finish();
    Ok(())
}
