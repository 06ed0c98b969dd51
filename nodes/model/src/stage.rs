//! The model stage between messages, as a state machine the process shell feeds: it latches the camera, keeps the
//! newest poses and every frame's 2-D segments (for Refine and the openings' evidence), and rebuilds the model from the newest set of 3-D lines
//! only (each set holds every line so far), naming the stamps to publish it under. The wire-frame and face
//! messages are laid out here too ([`wire_edges`], [`face_vertices`]).
use std::collections::{BTreeMap, HashMap, HashSet};

use lineflow_formats::Line3Row;
use lineflow_messages::{FaceVertex, Line3, Pose as PoseMessage, Segment2, Stamp, WireEdge};
use lineflow_photogrammetry::{Camera, Pose, Vec3};

use crate::refine::{Endpoints, ImageLines};
use crate::{build_with_images, lines_from_rows, Cameras, EdgeOrigin, Images, Model, ModelParams, SurfaceKind};

/// The images' 2-D lines for Refine and the openings' evidence: segments as they arrive, indexed once the camera is known, each image
/// placed at its newest pose.
#[derive(Default)]
struct ImageLineStore {
    /// Measured-pixel endpoints of frames not indexed yet.
    pending: BTreeMap<u64, Vec<Endpoints>>,
    /// Indexed frames, ascending, and their lines.
    frames: Vec<u64>,
    lines: Vec<ImageLines>,
    /// The newest pose of every oriented frame.
    poses: BTreeMap<u64, Pose>,
}

impl ImageLineStore {
    /// The lines of the newest `keep` frames (every frame for 0), at their newest pose (none while not oriented);
    /// how many are oriented.
    fn update(&mut self, camera: &Camera, min_px: f64, keep: usize) -> (&[ImageLines], usize) {
        for (frame, segments) in std::mem::take(&mut self.pending) {
            let at = self.frames.partition_point(|&f| f < frame);
            let lines = ImageLines::new(camera, None, &segments, min_px);
            if self.frames.get(at) == Some(&frame) {
                self.lines[at] = lines;
            } else {
                self.frames.insert(at, frame);
                self.lines.insert(at, lines);
            }
        }
        if keep > 0 && self.frames.len() > keep {
            let old = self.frames.len() - keep;
            self.frames.drain(..old);
            self.lines.drain(..old);
        }
        let mut oriented = 0;
        for (frame, lines) in self.frames.iter().zip(&mut self.lines) {
            let pose = self.poses.get(frame).copied();
            oriented += usize::from(pose.is_some());
            lines.set_pose(pose);
        }
        (&self.lines, oriented)
    }
}

/// The `csr` implementation between messages.
pub struct ModelStage {
    params: ModelParams,
    /// The images' 2-D lines are used (Refine or the openings' evidence asked for, and the 2-D lines, camera and
    /// poses wired).
    using_images: bool,
    cameras: Cameras,
    camera: Option<Camera>,
    image_lines: ImageLineStore,
    /// The newest set of 3-D lines not built yet, and the stamps received since the last build.
    latest: Option<Vec<Line3Row>>,
    received: Vec<Stamp>,
    /// Frames already published.
    published: HashSet<u64>,
    model: Model,
}

impl ModelStage {
    /// A stage with `params`; `images_wired`: the lines2d, camera and poses inputs are all connected.
    pub fn new(params: ModelParams, images_wired: bool) -> ModelStage {
        ModelStage {
            using_images: (params.refine || params.verify_openings || params.settle_openings) && images_wired,
            params,
            cameras: Cameras::default(),
            camera: None,
            image_lines: ImageLineStore::default(),
            latest: None,
            received: Vec::new(),
            published: HashSet::new(),
            model: Model::default(),
        }
    }

    /// Refine was asked for but cannot run (its inputs are not wired).
    pub fn refine_unavailable(&self) -> bool {
        self.params.refine && !self.using_images
    }

    /// The camera model (latched; the newest wins).
    pub fn on_camera(&mut self, camera: Camera) {
        self.camera = Some(camera);
    }

    /// A Poses message: the oriented frames' centres (for the side the walls face) and poses (for Refine).
    pub fn on_poses(&mut self, poses: &[PoseMessage]) {
        let oriented: Vec<&PoseMessage> = poses.iter().filter(|p| p.flags & PoseMessage::ORIENTED != 0).collect();
        if !oriented.is_empty() {
            self.cameras = Cameras::new(oriented.iter().map(|p| Vec3::from(p.center_m)).collect());
        }
        self.image_lines.poses = oriented.iter().map(|p| (p.frame, p.exterior())).collect();
    }

    /// One frame's 2-D segments (kept only when the images are used).
    pub fn on_segments(&mut self, frame: u64, segments: &[Segment2]) {
        if self.using_images {
            let endpoints = segments.iter().map(|s| (s.start_px, s.end_px)).collect();
            self.image_lines.pending.insert(frame, endpoints);
        }
    }

    /// A set of 3-D lines: it replaces any set not built yet.
    pub fn on_lines(&mut self, stamp: Stamp, lines: &[Line3]) {
        self.latest = Some(lines.iter().map(Line3Row::from).collect());
        self.received.push(stamp);
    }

    /// Builds the model from the newest set of lines, if one arrived since the last build; the stamps to publish
    /// it under (every frame received for the first time, in order, so that downstream sees no frame missing).
    pub fn rebuild(&mut self) -> Vec<Stamp> {
        let Some(rows) = self.latest.take() else { return Vec::new() };
        let received = std::mem::take(&mut self.received);
        let lines = lines_from_rows(&rows, &self.params);
        let images = match (&self.camera, self.using_images) {
            (Some(camera), true) => match self
                .image_lines
                .update(camera, self.params.refine_min_image_line_px, self.params.keep_frames)
            {
                (lines, oriented) if oriented >= 2 => Some(Images {
                    camera,
                    lines,
                    params: self.params.refine_params(),
                }),
                _ => None,
            },
            _ => None,
        };
        self.model = build_with_images(&lines, &self.params, &self.cameras, images.as_ref());
        lineflow_runtime::frames_to_publish(&received, &mut self.published)
    }

    /// The newest model.
    pub fn model(&self) -> &Model {
        &self.model
    }
}

/// The model's edges as `WireEdge`s, with the kind code (0 wall, 1 roof, 2 opening, 3 ground) of the first face
/// each bounds.
pub fn wire_edges(model: &Model) -> Vec<WireEdge> {
    // The first face bounding each vertex pair, from one pass over the rings.
    let mut face_of: HashMap<(usize, usize), usize> = HashMap::new();
    for (f, face) in model.faces.iter().enumerate() {
        let n = face.ring.len();
        for i in 0..n {
            let (p, q) = (face.ring[i], face.ring[(i + 1) % n]);
            face_of.entry((p.min(q), p.max(q))).or_insert(f);
        }
    }
    model
        .edges
        .iter()
        .map(|e| {
            let face = face_of.get(&(e.a.min(e.b), e.a.max(e.b))).copied();
            let kind = face.map_or(0, |f| match model.faces[f].kind {
                SurfaceKind::Wall => 0,
                SurfaceKind::Roof => 1,
                SurfaceKind::Window | SurfaceKind::Door => 2,
                SurfaceKind::Ground | SurfaceKind::Floor => 3,
            });
            WireEdge {
                a: e.a as u32,
                b: e.b as u32,
                face: face.map_or(u32::MAX, |f| f as u32),
                kind,
                hidden: u32::from(e.origin == EdgeOrigin::Hidden),
            }
        })
        .collect()
}

/// The faces as rings of vertex indices, outer ring first, then the holes.
pub fn face_vertices(model: &Model) -> Vec<FaceVertex> {
    let mut out = Vec::new();
    for (f, face) in model.faces.iter().enumerate() {
        for (ring, vertices) in std::iter::once(&face.ring).chain(&face.holes).enumerate() {
            out.extend(vertices.iter().map(|&v| FaceVertex {
                face: f as u32,
                ring: ring as u32,
                kind: face.kind.code(),
                vertex: v as u32,
            }));
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_image_lines_of_the_newest_keep_frames_are_kept() {
        let camera = Camera::pinhole(2000, 1500, 0.005, 8.0);
        let mut store = ImageLineStore::default();
        let segment = vec![([10.0, 10.0], [500.0, 10.0])];
        for frame in [3, 1, 2] {
            store.pending.insert(frame, segment.clone());
            store.update(&camera, 20.0, 2);
        }
        assert_eq!(store.frames, [2, 3]);
        assert_eq!(store.lines.len(), 2);
        // 0 keeps every frame.
        store.pending.insert(0, segment.clone());
        store.update(&camera, 20.0, 0);
        assert_eq!(store.frames, [0, 2, 3]);
    }

    /// A flat roof outline over [0, 10] × [0, 6] at 5 m, as Lines3D elements.
    fn roof() -> Vec<Line3> {
        let c = [[0.0, 0.0, 5.0], [10.0, 0.0, 5.0], [10.0, 6.0, 5.0], [0.0, 6.0, 5.0]];
        (0..4)
            .map(|k| Line3 {
                id: k as u64,
                start_m: c[k],
                end_m: c[(k + 1) % 4],
                n_points: 40,
                n_images: 3,
                rms_m: 0.01,
                ..Line3::default()
            })
            .collect()
    }

    fn stamp(frame: u64, revision: u32) -> Stamp {
        Stamp {
            frame,
            revision,
            ..Stamp::default()
        }
    }

    fn camera_above() -> PoseMessage {
        PoseMessage {
            frame: 0,
            flags: PoseMessage::ORIENTED,
            center_m: [5.0, -20.0, 40.0],
            ..PoseMessage::default()
        }
    }

    #[test]
    fn only_the_newest_set_is_built_and_every_new_frame_gets_a_message() {
        let mut stage = ModelStage::new(ModelParams::default(), false);
        stage.on_poses(&[camera_above()]);
        let mut partial = roof();
        partial.truncate(2);
        stage.on_lines(stamp(0, 0), &partial);
        stage.on_lines(stamp(1, 0), &roof());
        assert_eq!(stage.rebuild(), [stamp(0, 0), stamp(1, 0)]);
        let model = stage.model();
        assert_eq!(model.diagnostics.lines_in, 4, "the newest set: {}", model.summary());
        assert_eq!(model.faces.len(), 1, "{}", model.summary());
        assert!(stage.rebuild().is_empty(), "nothing new, nothing to publish");
        // A revision of a frame already out shares the newest message.
        stage.on_lines(stamp(1, 1), &roof());
        assert_eq!(stage.rebuild(), [stamp(1, 1)]);
    }

    #[test]
    fn the_messages_name_every_edge_with_its_face_and_every_ring_vertex() {
        let mut stage = ModelStage::new(ModelParams::default(), false);
        stage.on_poses(&[camera_above()]);
        stage.on_lines(stamp(0, 0), &roof());
        stage.rebuild();
        let model = stage.model();
        let edges = wire_edges(model);
        assert_eq!(edges.len(), model.edges.len());
        let kind = match model.faces[0].kind {
            SurfaceKind::Roof => 1,
            SurfaceKind::Ground | SurfaceKind::Floor => 3,
            other => panic!("a horizontal outline became a {other:?}"),
        };
        assert!(edges.iter().all(|e| e.face == 0 && e.kind == kind && e.hidden == 0), "{edges:?}");
        let ring = face_vertices(model);
        assert_eq!(ring.len(), model.faces[0].ring.len());
        assert!(ring.iter().all(|v| (v.face, v.ring) == (0, 0)));
    }

    #[test]
    fn refine_without_its_inputs_is_reported_and_segments_are_not_kept() {
        let params = ModelParams {
            refine: true,
            ..ModelParams::default()
        };
        let mut stage = ModelStage::new(params, false);
        assert!(stage.refine_unavailable());
        stage.on_segments(0, &[Segment2::default()]);
        assert!(stage.image_lines.pending.is_empty());
    }
}
