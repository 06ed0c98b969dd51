//! `lineflow-modelfit`: the modelfit stage (`impl = "lsmif"`). Keeps every frame's edge pixels and the newest
//! poses; at end-of-stream fits the final wire-frame with the final poses, publishes it and writes
//! `model_fitted.obj` and `model_fitted.city.json`, with the faces of the `faces` topic when it is wired. With `live_interval_frames` > 0 it also fits the newest wire-frame on a worker thread
//! every so many new edge maps and publishes each fit.
use std::collections::BTreeMap;
use std::sync::Arc;

use anyhow::{bail, Result};
use lineflow_messages::{kinds, parts, EdgePixel, FaceVertex, Stamp, WireEdge, WireframeHeader};
use lineflow_modelfit::faces::fitted_model;
use lineflow_modelfit::wireframe::facade_params;
use lineflow_modelfit::{fit_wireframe, FitParams, ImageEdges, Weighting};
use lineflow_photogrammetry::{Camera, Pose, Vec3};
use lineflow_runtime::{Flow, NodeContext, Output};
use serde::Deserialize;

fn main() -> std::process::ExitCode {
    lineflow_runtime::run_node(body)
}

/// Launch-file parameters; what is not given comes from `wireframe::facade_params` for the actual camera
/// (docs/modelfit.md).
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct Params {
    #[serde(default)]
    weighting: Weighting,
    buffer_start_mm: Option<f64>,
    buffer_step_mm: Option<f64>,
    buffer_min_mm: Option<f64>,
    angle_gate_deg: Option<f64>,
    max_iterations: Option<usize>,
    prior_sigma_m: Option<f64>,
    prior_depth_sigma_m: Option<f64>,
    max_pixels_per_line: Option<usize>,
    freeze_at_final: Option<bool>,
    /// Refit while streaming after this many new edge maps (0: only at the end). Live fits run as the data
    /// happen to arrive, so a re-run of a recording may publish different intermediate fits; the final fit,
    /// after every input has ended, is always the same.
    #[serde(default)]
    live_interval_frames: usize,
}

impl Params {
    fn fit_params(&self, camera: &Camera) -> FitParams {
        let d = facade_params(camera.pixel_size_mm);
        FitParams {
            weighting: self.weighting,
            buffer_start_mm: self.buffer_start_mm.unwrap_or(d.buffer_start_mm),
            buffer_step_mm: self.buffer_step_mm.unwrap_or(d.buffer_step_mm),
            buffer_min_mm: self.buffer_min_mm.unwrap_or(d.buffer_min_mm),
            angle_gate_deg: self.angle_gate_deg.unwrap_or(d.angle_gate_deg),
            max_iterations: self.max_iterations.unwrap_or(d.max_iterations),
            prior_sigma: self.prior_sigma_m.unwrap_or(d.prior_sigma),
            prior_depth_sigma: self.prior_depth_sigma_m.unwrap_or(d.prior_depth_sigma),
            max_pixels_per_line: self.max_pixels_per_line.unwrap_or(d.max_pixels_per_line),
            freeze_at_final: self.freeze_at_final.unwrap_or(d.freeze_at_final),
            constraints: d.constraints,
        }
    }
}

/// A wire-frame to fit: its stamp, vertices and edges.
type Wire = (Stamp, Vec<Vec3>, Vec<WireEdge>);

#[derive(Default)]
struct State {
    camera: Option<Camera>,
    edges: BTreeMap<u64, Arc<Vec<EdgePixel>>>,
    poses: BTreeMap<u64, Pose>,
    /// Edge images built for the pose they were built with.
    images: BTreeMap<u64, (Pose, Arc<ImageEdges>)>,
    wireframe: Option<Wire>,
    /// The newest faces of the model stage, with the stamp of their wire-frame.
    faces: Option<(Stamp, Vec<FaceVertex>)>,
    edges_since_fit: usize,
}

impl State {
    /// The edge images of every frame that has both edges and a pose, rebuilt where the pose changed.
    fn images(&mut self) -> Vec<Arc<ImageEdges>> {
        let Some(camera) = self.camera else { return Vec::new() };
        let mut out = Vec::new();
        for (f, px) in &self.edges {
            let Some(pose) = self.poses.get(f) else { continue };
            let fresh = self.images.get(f).is_none_or(|(p, _)| p != pose);
            if fresh {
                self.images.insert(*f, (*pose, Arc::new(ImageEdges::new(camera, *pose, px))));
            }
            out.push(self.images[f].1.clone());
        }
        out
    }

    /// The newest wire-frame and the images to fit it to, if there is something to fit.
    fn job(&mut self) -> Option<(Wire, Vec<Arc<ImageEdges>>)> {
        let wire = self.wireframe.clone()?;
        let images = self.images();
        if images.is_empty() || wire.1.is_empty() {
            return None;
        }
        self.edges_since_fit = 0;
        Some((wire, images))
    }
}

/// Fits `wire` to `images`; the fitted vertices.
fn fit_job(wire: &Wire, images: &[Arc<ImageEdges>], params: &FitParams) -> Vec<Vec3> {
    let (_, vertices, edges) = wire;
    let fit = fit_wireframe(vertices, &pairs(edges), &[], images, params);
    let pixel_mm = images.first().map_or(1.0, |i| i.camera.pixel_size_mm);
    tracing::info!("fitted to {} images: {}", images.len(), fit.summary(pixel_mm));
    for why in fit.failures.iter().take(3) {
        tracing::warn!("a part of the model was left unfitted: {why}");
    }
    fit.vertices
}

/// The observed edges as vertex-index pairs: an edge completed behind an occluder has no edge pixels of its own
/// (those near its projection belong to the occluder).
fn pairs(edges: &[WireEdge]) -> Vec<[usize; 2]> {
    edges
        .iter()
        .filter(|e| e.hidden == 0)
        .map(|e| [e.a as usize, e.b as usize])
        .collect()
}

fn publish(output: &Output<kinds::Wireframe>, stamp: Stamp, vertices: &[Vec3], edges: &[WireEdge]) -> Result<()> {
    let v: Vec<[f64; 3]> = vertices.iter().map(|p| [p.x, p.y, p.z]).collect();
    let header = WireframeHeader {
        stamp,
        n_vertices: v.len() as u32,
        n_edges: edges.len() as u32,
    };
    output.publish_parts(header, &v, edges)
}

/// Writes `model_fitted.obj` and `model_fitted.city.json`: the fitted vertices with the faces published for the
/// same wire-frame, or as a bare wire-frame (with a warning) when there are none or they do not fit it.
fn write_model(
    ctx: &NodeContext,
    vertices: &[Vec3],
    stamp: Stamp,
    edges: &[WireEdge],
    faces: Option<&(Stamp, Vec<FaceVertex>)>,
) -> Result<()> {
    let same = |s: &Stamp| (s.frame, s.revision, s.capture_time_ns) == (stamp.frame, stamp.revision, stamp.capture_time_ns);
    let with_faces = match faces {
        Some((s, rows)) if same(s) => {
            fitted_model(vertices, edges, rows).map_err(|why| format!("the model's faces do not fit its wire-frame ({why})"))
        }
        Some(_) => Err("no faces arrived for the final wire-frame".to_owned()),
        None => Err("no faces arrived (is the model stage's `faces` topic wired to this node?)".to_owned()),
    };
    // Without faces the wire-frame cannot fail to build: every edge names a vertex (checked on arrival).
    let model = with_faces.unwrap_or_else(|why| {
        tracing::warn!("{why}; the fitted model is written without faces");
        fitted_model(vertices, edges, &[]).unwrap_or_default()
    });
    let dir = ctx.out_dir();
    let (obj, city) = (dir.join("model_fitted.obj"), dir.join("model_fitted.city.json"));
    lineflow_model::export::write_obj(&obj, &model)?;
    lineflow_model::export::write_cityjson(&city, &model)?;
    tracing::info!("fitted model ({} faces) -> {}", model.faces.len(), obj.display());
    Ok(())
}

fn body() -> Result<()> {
    let ctx = NodeContext::from_env()?;
    match ctx.implementation("lsmif") {
        "lsmif" => {}
        other => bail!("node '{}': unknown modelfit impl '{other}' (available: lsmif)", ctx.name()),
    }
    let params: Params = ctx.params()?;
    let wire_in = ctx.input::<kinds::Wireframe>("wireframe")?;
    let edges_in = ctx.input::<kinds::EdgeMap>("edges")?;
    let poses_in = ctx.input::<kinds::Poses>("poses")?;
    let camera_in = ctx.input::<kinds::CameraModel>("camera")?;
    let faces_in = ctx.optional_input::<kinds::ModelFaces>("faces")?;
    let output = ctx.output::<kinds::Wireframe>("wireframe_fitted")?;
    ctx.connect()?;

    let mut st = State::default();
    let mut fit_params: Option<FitParams> = None;
    // Live fits run on a worker so that the edge maps keep flowing in while one is under way.
    let (jobs_tx, jobs_rx) = crossbeam::channel::bounded::<(Wire, Vec<Arc<ImageEdges>>, FitParams)>(1);
    let (done_tx, done_rx) = crossbeam::channel::bounded::<(Wire, Vec<Vec3>)>(1);
    let worker = std::thread::Builder::new().name("modelfit-live".into()).spawn(move || {
        for (wire, images, params) in jobs_rx {
            let fitted = fit_job(&wire, &images, &params);
            if done_tx.send((wire, fitted)).is_err() {
                break;
            }
        }
    })?;
    let mut busy = false;
    ctx.run(|| {
        while let Some(m) = camera_in.receive()? {
            let camera = m.user_header().camera();
            let p = params.fit_params(&camera);
            if let Err(e) = p.validate() {
                bail!("node '{}': {e}", ctx.name());
            }
            fit_params = Some(p);
            st.camera = Some(camera);
        }
        while let Some(m) = edges_in.receive()? {
            st.edges.insert(m.user_header().stamp.frame, Arc::new(m.payload().to_vec()));
            st.edges_since_fit += 1;
        }
        while let Some(m) = poses_in.receive()? {
            for p in m.payload().iter().filter(|p| p.flags & lineflow_messages::Pose::ORIENTED != 0) {
                st.poses.insert(p.frame, p.exterior());
            }
        }
        if let Some(faces) = &faces_in {
            while let Some(m) = faces.receive()? {
                st.faces = Some((m.user_header().stamp, m.payload().to_vec()));
            }
        }
        while let Some(m) = wire_in.receive()? {
            let h = *m.user_header();
            let (v, e) = parts::split::<[f64; 3], WireEdge>(m.payload(), h.n_vertices as usize, h.n_edges as usize)
                .map_err(|e| anyhow::anyhow!("wireframe of frame {}: {e}", h.stamp.frame))?;
            let n = v.len() as u32;
            if let Some(bad) = e.iter().find(|x| x.a >= n || x.b >= n) {
                bail!(
                    "wireframe of frame {}: edge ({}, {}) names a vertex beyond {n}",
                    h.stamp.frame,
                    bad.a,
                    bad.b
                );
            }
            st.wireframe = Some((h.stamp, v.iter().map(|&p| Vec3::from(p)).collect(), e.to_vec()));
        }
        if let Ok(((stamp, _, edges), fitted)) = done_rx.try_recv() {
            publish(&output, stamp, &fitted, &edges)?;
            busy = false;
        }
        let ended = wire_in.is_ended() && edges_in.is_ended() && poses_in.is_ended();
        let due = params.live_interval_frames > 0 && st.edges_since_fit >= params.live_interval_frames;
        if !ended && due && !busy {
            if let (Some(p), Some((wire, images))) = (fit_params.clone(), st.job()) {
                busy = jobs_tx.try_send((wire, images, p)).is_ok();
            }
        }
        Ok(if ended { Flow::Stop } else { Flow::Continue })
    })?;
    drop(jobs_tx);
    if let Ok(((stamp, _, edges), fitted)) = done_rx.recv() {
        publish(&output, stamp, &fitted, &edges)?;
    }
    let _ = worker.join();
    // The end: the final wire-frame against the final poses.
    let mut fitted = None;
    match (fit_params, st.job()) {
        (Some(p), Some((wire, images))) => {
            let v = fit_job(&wire, &images, &p);
            publish(&output, wire.0, &v, &wire.2)?;
            fitted = Some((v, wire.0, wire.2));
        }
        _ if st.wireframe.is_none() => tracing::warn!("no wire-frame arrived: nothing to fit"),
        _ if st.camera.is_none() => tracing::warn!("no camera model arrived: the model was not fitted"),
        _ if st.wireframe.as_ref().is_some_and(|w| w.1.is_empty()) => tracing::warn!("the wire-frame is empty"),
        _ => tracing::warn!("no frame has both edges and a pose: the model was not fitted"),
    }
    output.end_of_stream()?;
    if let Some((v, stamp, edges)) = fitted {
        write_model(&ctx, &v, stamp, &edges, st.faces.as_ref())?;
    }
    ctx.finish();
    Ok(())
}
