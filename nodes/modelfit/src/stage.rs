//! The modelfit stage between messages, as a state machine the process shell feeds: it keeps every frame's edge
//! pixels, the newest poses, faces and wire-frame, builds each frame's edge image once per pose, and says when a
//! live fit is due and what the final fit fits, or why there is nothing to fit. The fits themselves run where
//! the shell puts them (a worker thread for live fits).
use std::collections::BTreeMap;
use std::sync::Arc;

use lineflow_messages::{EdgePixel, FaceVertex, Pose as PoseMessage, Stamp, WireEdge};
use lineflow_model::Model;
use lineflow_photogrammetry::{Camera, Pose, Vec3};
use lineflow_runtime::{ParamError, StageParams};
use serde::Deserialize;

use crate::faces::fitted_model;
use crate::wireframe::facade_params;
use crate::{fit_wireframe, FitParams, ImageEdges, Weighting};

/// The `lsmif` implementation's launch-file parameters; what is not given comes from
/// [`facade_params`] for the actual camera (docs/modelfit.md).
#[derive(Debug, Clone, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct LsmifParams {
    /// How edge pixels in a line's buffer are weighted.
    #[serde(default)]
    pub weighting: Weighting,
    /// Buffer half-width of the first iteration, image millimetres.
    pub buffer_start_mm: Option<f64>,
    /// Its decrease per iteration.
    pub buffer_step_mm: Option<f64>,
    /// The narrowest buffer.
    pub buffer_min_mm: Option<f64>,
    /// Largest angle between an edge pixel's direction and the projected line, degrees.
    pub angle_gate_deg: Option<f64>,
    /// Iterations at most.
    pub max_iterations: Option<usize>,
    /// σ of the prior on every vertex, metres.
    pub prior_sigma_m: Option<f64>,
    /// σ of the prior along the wall normal, metres.
    pub prior_depth_sigma_m: Option<f64>,
    /// Edge pixels used per line and image at most.
    pub max_pixels_per_line: Option<usize>,
    /// Keep the final buffer's observations fixed once it is reached.
    pub freeze_at_final: Option<bool>,
    /// Refit while streaming after this many new edge maps (0: only at the end). Live fits run as the data
    /// happen to arrive, so a re-run of a recording may publish different intermediate fits; the final fit,
    /// after every input has ended, is always the same.
    #[serde(default)]
    pub live_interval_frames: usize,
}

impl LsmifParams {
    /// The fit's settings for `camera`, checked.
    ///
    /// # Errors
    /// A value out of range (given, or derived from the camera's pixel size).
    pub fn fit_params(&self, camera: &Camera) -> Result<FitParams, ParamError> {
        let d = facade_params(camera.pixel_size_mm);
        let p = FitParams {
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
        };
        p.validate()?;
        Ok(p)
    }
}

/// A wire-frame to fit.
#[derive(Debug, Clone, PartialEq)]
pub struct Wire {
    /// The stamp it was published under.
    pub stamp: Stamp,
    /// Its vertices.
    pub vertices: Vec<Vec3>,
    /// Its edges.
    pub edges: Vec<WireEdge>,
}

/// One fit to run: the wire-frame, the edge images of every frame with edges and a pose, and the settings.
#[derive(Clone)]
pub struct Job {
    /// The wire-frame.
    pub wire: Wire,
    /// The images.
    pub images: Vec<Arc<ImageEdges>>,
    /// The settings for this camera.
    pub params: FitParams,
}

impl Job {
    /// Fits the wire-frame to the images: the fitted vertices, in the wire-frame's order.
    pub fn run(&self) -> Vec<Vec3> {
        let fit = fit_wireframe(
            &self.wire.vertices,
            &observed_pairs(&self.wire.edges),
            &[],
            &self.images,
            &self.params,
        );
        let pixel_mm = self.images.first().map_or(1.0, |i| i.camera.pixel_size_mm);
        tracing::info!("fitted to {} images: {}", self.images.len(), fit.summary(pixel_mm));
        for why in fit.failures.iter().take(3) {
            tracing::warn!("a part of the model was left unfitted: {why}");
        }
        fit.vertices
    }
}

/// Why the stage cannot go on.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum FitStageError {
    /// A wire-frame message that does not split into its parts or names a vertex it lacks.
    #[error("wireframe of frame {frame}: {why}")]
    BadWireframe {
        /// The frame.
        frame: u64,
        /// What is wrong.
        why: String,
    },
    /// Settings out of range for the camera that arrived.
    #[error(transparent)]
    Params(#[from] ParamError),
}

/// Why the final fit does not run (each a warning: the stage ends without a fitted model).
#[derive(Debug, Clone, Copy, PartialEq, Eq, thiserror::Error)]
pub enum NothingToFit {
    /// No wire-frame arrived.
    #[error("no wire-frame arrived: nothing to fit")]
    NoWireframe,
    /// No camera model arrived.
    #[error("no camera model arrived: the model was not fitted")]
    NoCamera,
    /// The wire-frame has no vertices.
    #[error("the wire-frame is empty")]
    EmptyWireframe,
    /// No frame has both an edge map and a pose.
    #[error("no frame has both edges and a pose: the model was not fitted")]
    NoImages,
}

/// The `lsmif` implementation between messages.
pub struct FitStage {
    params: LsmifParams,
    fit_params: Option<FitParams>,
    camera: Option<Camera>,
    edges: BTreeMap<u64, Arc<Vec<EdgePixel>>>,
    poses: BTreeMap<u64, Pose>,
    /// Edge images with the pose they were built for.
    images: BTreeMap<u64, (Pose, Arc<ImageEdges>)>,
    wireframe: Option<Wire>,
    /// The newest faces of the model stage, with the stamp of their wire-frame.
    faces: Option<(Stamp, Vec<FaceVertex>)>,
    edges_since_fit: usize,
}

impl FitStage {
    /// A stage with these launch-file parameters.
    pub fn new(params: LsmifParams) -> FitStage {
        FitStage {
            params,
            fit_params: None,
            camera: None,
            edges: BTreeMap::new(),
            poses: BTreeMap::new(),
            images: BTreeMap::new(),
            wireframe: None,
            faces: None,
            edges_since_fit: 0,
        }
    }

    /// The camera model (latched; the newest wins).
    ///
    /// # Errors
    /// The settings derived for it are out of range.
    pub fn on_camera(&mut self, camera: Camera) -> Result<(), FitStageError> {
        self.fit_params = Some(self.params.fit_params(&camera)?);
        self.camera = Some(camera);
        Ok(())
    }

    /// One frame's edge pixels.
    pub fn on_edges(&mut self, frame: u64, pixels: &[EdgePixel]) {
        self.edges.insert(frame, Arc::new(pixels.to_vec()));
        self.edges_since_fit += 1;
    }

    /// A Poses message: the oriented frames' newest poses.
    pub fn on_poses(&mut self, poses: &[PoseMessage]) {
        for p in poses.iter().filter(|p| p.flags & PoseMessage::ORIENTED != 0) {
            self.poses.insert(p.frame, p.exterior());
        }
    }

    /// The model stage's faces for the wire-frame of `stamp`.
    pub fn on_faces(&mut self, stamp: Stamp, faces: &[FaceVertex]) {
        self.faces = Some((stamp, faces.to_vec()));
    }

    /// A wire-frame (its message's stamp and two parts); it replaces the one kept.
    ///
    /// # Errors
    /// An edge naming a missing vertex.
    pub fn on_wireframe(&mut self, stamp: Stamp, vertices: &[[f64; 3]], edges: &[WireEdge]) -> Result<(), FitStageError> {
        let n = vertices.len() as u32;
        if let Some(x) = edges.iter().find(|x| x.a >= n || x.b >= n) {
            return Err(FitStageError::BadWireframe {
                frame: stamp.frame,
                why: format!("edge ({}, {}) names a vertex beyond {n}", x.a, x.b),
            });
        }
        self.wireframe = Some(Wire {
            stamp,
            vertices: vertices.iter().map(|&p| Vec3::from(p)).collect(),
            edges: edges.to_vec(),
        });
        Ok(())
    }

    /// A live fit, when one is due (live fits on, enough new edge maps since the last, inputs not ended) and there
    /// is something to fit.
    pub fn live_job(&mut self, ended: bool) -> Option<Job> {
        let every = self.params.live_interval_frames;
        if ended || every == 0 || self.edges_since_fit < every {
            return None;
        }
        self.job().ok()
    }

    /// The final fit: the newest wire-frame against the newest poses.
    ///
    /// # Errors
    /// Why there is nothing to fit.
    pub fn final_job(&mut self) -> Result<Job, NothingToFit> {
        self.job()
    }

    fn job(&mut self) -> Result<Job, NothingToFit> {
        let wire = self.wireframe.clone().ok_or(NothingToFit::NoWireframe)?;
        let params = self.fit_params.clone().ok_or(NothingToFit::NoCamera)?;
        if wire.vertices.is_empty() {
            return Err(NothingToFit::EmptyWireframe);
        }
        let images = self.edge_images();
        if images.is_empty() {
            return Err(NothingToFit::NoImages);
        }
        self.edges_since_fit = 0;
        Ok(Job { wire, images, params })
    }

    /// The edge images of every frame that has both edges and a pose, rebuilt where the pose changed.
    fn edge_images(&mut self) -> Vec<Arc<ImageEdges>> {
        let Some(camera) = self.camera else { return Vec::new() };
        let mut out = Vec::new();
        for (f, px) in &self.edges {
            let Some(pose) = self.poses.get(f) else { continue };
            if self.images.get(f).is_none_or(|(p, _)| p != pose) {
                self.images.insert(*f, (*pose, Arc::new(ImageEdges::new(camera, *pose, px))));
            }
            out.push(self.images[f].1.clone());
        }
        out
    }

    /// The fitted model to write: the fitted `vertices` of `wire` with the faces published for the same
    /// wire-frame, or a bare wire-frame and the reason when there are none or they do not fit it.
    pub fn fitted_model(&self, wire: &Wire, vertices: &[Vec3]) -> (Model, Option<String>) {
        let same =
            |s: &Stamp| (s.frame, s.revision, s.capture_time_ns) == (wire.stamp.frame, wire.stamp.revision, wire.stamp.capture_time_ns);
        let with_faces = match &self.faces {
            Some((s, rows)) if same(s) => {
                fitted_model(vertices, &wire.edges, rows).map_err(|why| format!("the model's faces do not fit its wire-frame ({why})"))
            }
            Some(_) => Err("no faces arrived for the final wire-frame".to_owned()),
            None => Err("no faces arrived (is the model stage's `faces` topic wired to this node?)".to_owned()),
        };
        match with_faces {
            Ok(model) => (model, None),
            // Without faces the wire-frame cannot fail to build: every edge names a vertex (checked on arrival).
            Err(why) => (fitted_model(vertices, &wire.edges, &[]).unwrap_or_default(), Some(why)),
        }
    }
}

impl StageParams for LsmifParams {
    /// Values are checked once the camera is known ([`LsmifParams::fit_params`]): the defaults depend on it.
    fn validate(&self) -> Result<(), ParamError> {
        Ok(())
    }
}

/// The observed edges as vertex-index pairs: an edge completed behind an occluder has no edge pixels of its own
/// (those near its projection belong to the occluder).
pub fn observed_pairs(edges: &[WireEdge]) -> Vec<[usize; 2]> {
    edges
        .iter()
        .filter(|e| e.hidden == 0)
        .map(|e| [e.a as usize, e.b as usize])
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn camera() -> Camera {
        Camera::pinhole(400, 300, 0.01, 8.0)
    }

    fn stamp() -> Stamp {
        Stamp {
            frame: 4,
            ..Stamp::default()
        }
    }

    fn edge(a: u32, b: u32) -> WireEdge {
        WireEdge {
            a,
            b,
            face: 0,
            kind: 0,
            hidden: 0,
        }
    }

    fn oriented(frame: u64) -> PoseMessage {
        PoseMessage {
            frame,
            flags: PoseMessage::ORIENTED,
            center_m: [0.0, -10.0, 1.5],
            ..PoseMessage::default()
        }
    }

    #[test]
    fn a_wireframe_naming_a_missing_vertex_is_refused_with_its_frame() {
        let mut stage = FitStage::new(LsmifParams::default());
        let e = stage
            .on_wireframe(stamp(), &[[0.0; 3], [1.0, 0.0, 0.0]], &[edge(0, 2)])
            .unwrap_err();
        assert_eq!(e.to_string(), "wireframe of frame 4: edge (0, 2) names a vertex beyond 2");
    }

    #[test]
    fn the_final_fit_says_what_is_missing_in_order() {
        let mut stage = FitStage::new(LsmifParams::default());
        assert_eq!(stage.final_job().err(), Some(NothingToFit::NoWireframe));
        stage.on_wireframe(stamp(), &[], &[]).unwrap();
        assert_eq!(stage.final_job().err(), Some(NothingToFit::NoCamera));
        stage.on_camera(camera()).unwrap();
        assert_eq!(stage.final_job().err(), Some(NothingToFit::EmptyWireframe));
        stage.on_wireframe(stamp(), &[[0.0; 3], [1.0, 0.0, 0.0]], &[edge(0, 1)]).unwrap();
        stage.on_edges(0, &[]);
        assert_eq!(stage.final_job().err(), Some(NothingToFit::NoImages), "edges without a pose");
        stage.on_poses(&[oriented(0)]);
        let job = stage.final_job().unwrap();
        assert_eq!((job.images.len(), job.wire.edges.len()), (1, 1));
    }

    #[test]
    fn live_fits_come_every_so_many_edge_maps_and_reuse_edge_images_of_unchanged_poses() {
        let params = LsmifParams {
            live_interval_frames: 2,
            ..LsmifParams::default()
        };
        let mut stage = FitStage::new(params);
        stage.on_camera(camera()).unwrap();
        stage.on_wireframe(stamp(), &[[0.0; 3], [1.0, 0.0, 0.0]], &[edge(0, 1)]).unwrap();
        stage.on_poses(&[oriented(0), oriented(1)]);
        stage.on_edges(0, &[]);
        assert!(stage.live_job(false).is_none(), "one edge map of two");
        stage.on_edges(1, &[]);
        assert!(stage.live_job(true).is_none(), "never once the inputs ended");
        let first = stage.live_job(false).unwrap();
        assert!(stage.live_job(false).is_none(), "the count starts again");
        stage.on_edges(2, &[]);
        stage.on_edges(3, &[]);
        let second = stage.live_job(false).unwrap();
        assert!(Arc::ptr_eq(&first.images[0], &second.images[0]), "same pose, same edge image");
    }

    #[test]
    fn settings_out_of_range_for_the_camera_are_refused() {
        let params = LsmifParams {
            buffer_min_mm: Some(0.0),
            ..LsmifParams::default()
        };
        let e = FitStage::new(params).on_camera(camera()).unwrap_err();
        assert_eq!(e.to_string(), "buffer_min_mm must be > 0, got 0");
    }

    #[test]
    fn completed_edges_are_not_observed() {
        let hidden = WireEdge { hidden: 1, ..edge(1, 2) };
        assert_eq!(observed_pairs(&[edge(0, 1), hidden]), [[0, 1]]);
    }
}
