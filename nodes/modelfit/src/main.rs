//! `lineflow-modelfit`: the modelfit stage (`impl = "lsmif"`). Keeps every frame's edge pixels and the newest
//! poses, fits the newest wire-frame to them as the stream goes (every `live_interval_frames` new edge maps) and
//! publishes the fitted wire-frame; at end-of-stream fits the final wire-frame with the final poses and writes
//! `model_fitted.obj`.
use std::collections::BTreeMap;

use anyhow::{bail, Context, Result};
use lineflow_messages::{kinds, parts, EdgePixel, Stamp, WireEdge, WireframeHeader};
use lineflow_modelfit::wireframe::facade_params;
use lineflow_modelfit::{fit_wireframe, write_obj, FitParams, ImageEdges, Weighting};
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
    /// Refit while streaming after this many new edge maps (0: only at the end).
    #[serde(default = "default_interval")]
    live_interval_frames: usize,
}

fn default_interval() -> usize {
    5
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
        }
    }
}

#[derive(Default)]
struct State {
    camera: Option<Camera>,
    edges: BTreeMap<u64, Vec<EdgePixel>>,
    poses: BTreeMap<u64, Pose>,
    wireframe: Option<(Stamp, Vec<Vec3>, Vec<WireEdge>)>,
    edges_since_fit: usize,
    fitted: Option<Vec<Vec3>>,
}

impl State {
    /// Fits the newest wire-frame to every frame that has both edges and a pose.
    fn fit(&mut self, params: &Params) -> Option<Vec<Vec3>> {
        let camera = self.camera?;
        let (_, vertices, edges) = self.wireframe.as_ref()?;
        let images: Vec<ImageEdges> = self
            .edges
            .iter()
            .filter_map(|(f, px)| Some(ImageEdges::new(camera, *self.poses.get(f)?, px)))
            .collect();
        if images.is_empty() || vertices.is_empty() {
            return None;
        }
        let pairs: Vec<[usize; 2]> = edges.iter().map(|e| [e.a as usize, e.b as usize]).collect();
        let fit = fit_wireframe(vertices, &pairs, &[], &images, &params.fit_params(&camera));
        tracing::info!("fitted to {} images: {}", images.len(), fit.summary(camera.pixel_size_mm));
        for why in fit.failures.iter().take(3) {
            tracing::warn!("a part of the model was left unfitted: {why}");
        }
        self.edges_since_fit = 0;
        Some(fit.vertices)
    }
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
    let output = ctx.output::<kinds::Wireframe>("wireframe_fitted")?;
    ctx.connect()?;

    let mut st = State::default();
    let mut checked = false;
    ctx.run(|| {
        while let Some(m) = camera_in.receive()? {
            let camera = m.user_header().camera();
            if !checked {
                if let Err(e) = params.fit_params(&camera).validate() {
                    bail!("node '{}': {e}", ctx.name());
                }
                checked = true;
            }
            st.camera = Some(camera);
        }
        while let Some(m) = edges_in.receive()? {
            st.edges.insert(m.user_header().stamp.frame, m.payload().to_vec());
            st.edges_since_fit += 1;
        }
        while let Some(m) = poses_in.receive()? {
            for p in m.payload().iter().filter(|p| p.flags & lineflow_messages::Pose::ORIENTED != 0) {
                st.poses.insert(p.frame, p.exterior());
            }
        }
        let mut fresh = false;
        while let Some(m) = wire_in.receive()? {
            let h = *m.user_header();
            let (v, e) = parts::split::<[f64; 3], WireEdge>(m.payload(), h.n_vertices as usize, h.n_edges as usize)
                .map_err(|e| anyhow::anyhow!("wireframe of frame {}: {e}", h.stamp.frame))?;
            let n = v.len() as u32;
            if let Some(bad) = e.iter().find(|x| x.a >= n || x.b >= n) {
                bail!("wireframe of frame {}: edge ({}, {}) names a vertex beyond {n}", h.stamp.frame, bad.a, bad.b);
            }
            st.wireframe = Some((h.stamp, v.iter().map(|&p| Vec3::from(p)).collect(), e.to_vec()));
            fresh = true;
        }
        let ended = wire_in.is_ended() && edges_in.is_ended() && poses_in.is_ended();
        let due = params.live_interval_frames > 0 && st.edges_since_fit >= params.live_interval_frames;
        if !ended && fresh && due {
            if let Some(v) = st.fit(&params) {
                let (stamp, _, edges) = st.wireframe.as_ref().expect("fit needs a wire-frame");
                publish(&output, *stamp, &v, edges)?;
                st.fitted = Some(v);
            }
        }
        Ok(if ended { Flow::Stop } else { Flow::Continue })
    })?;
    // The end: the final wire-frame against the final poses.
    if let Some(v) = st.fit(&params) {
        let (stamp, _, edges) = st.wireframe.as_ref().expect("fit needs a wire-frame");
        publish(&output, *stamp, &v, edges)?;
        st.fitted = Some(v);
    } else if st.wireframe.is_some() {
        tracing::warn!("no frame has both edges and a pose: the model was not fitted");
    }
    output.end_of_stream()?;
    if let (Some(v), Some((_, _, edges))) = (&st.fitted, &st.wireframe) {
        let path = ctx.out_dir().join("model_fitted.obj");
        let pairs: Vec<[usize; 2]> = edges.iter().map(|e| [e.a as usize, e.b as usize]).collect();
        write_obj(&path, v, &pairs).with_context(|| format!("writing {}", path.display()))?;
        tracing::info!("fitted model -> {}", path.display());
    }
    ctx.finish();
    Ok(())
}
