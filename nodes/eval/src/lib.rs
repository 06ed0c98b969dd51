//! The live `eval` sink without its process: [`Collector`] keeps the newest message of every truth and result topic
//! and turns them into the rows [`lineflow_eval::evaluate`] scores. The 2-D lines, one message per frame, are
//! scored as they come once the truth is in, so the sink keeps each frame's scores, not its segments.
#![warn(missing_docs)]

use std::collections::BTreeMap;

use lineflow_eval::lines2d::{frame_of, score_image, ImageScores};
use lineflow_eval::model::ModelOpening;
use lineflow_eval::{Lines2d, Results, Truth, Wireframe};
use lineflow_formats::{CheckRow, Line2Row, Line3Row, PoseRow};
use lineflow_messages::{FaceVertex, Line3, Lines2DHeader, Pose, Segment2, WireEdge};
use lineflow_photogrammetry::Vec3;
use lineflow_synthetic::Synthetic;

/// The 2-D lines received: each frame's scores, and the segments of frames that came before the truth.
#[derive(Debug, Default)]
struct Segments {
    scored: BTreeMap<usize, ImageScores>,
    waiting: Vec<Line2Row>,
}

/// What the sink has received. The newest message of each topic is the one that counts (a later revision
/// supersedes an earlier one); 2-D segments come one message per frame and are scored as they come
/// ([`Collector::score_segments`]).
#[derive(Debug, Default)]
pub struct Collector {
    /// `gt/poses`.
    pub truth_poses: Vec<Pose>,
    /// `gt/lines3d`.
    pub truth_lines: Vec<Line3>,
    poses: Option<Vec<Pose>>,
    lines: Option<Vec<Line3>>,
    segments: Option<Segments>,
    model: Option<Wireframe>,
    model_hidden: usize,
    fitted: Option<Wireframe>,
    faces: Option<Vec<FaceVertex>>,
}

impl Collector {
    /// A collector; `segments_wired`: the `lines2d` input is connected (its absence is reported as "none").
    pub fn new(segments_wired: bool) -> Collector {
        Collector {
            segments: segments_wired.then(Segments::default),
            ..Collector::default()
        }
    }

    /// A `poses` message.
    pub fn on_poses(&mut self, poses: &[Pose]) {
        self.poses = Some(poses.to_vec());
    }

    /// A `lines3d` message.
    pub fn on_lines(&mut self, lines: &[Line3]) {
        self.lines = Some(lines.to_vec());
    }

    /// One frame's `lines2d` message, waiting for [`Collector::score_segments`].
    pub fn on_segments(&mut self, header: &Lines2DHeader, segments: &[Segment2]) {
        if let Some(received) = &mut self.segments {
            received.waiting.extend(segments.iter().map(|s| Line2Row {
                image: header.name().to_string(),
                id: s.id as u64,
                start_px: s.start_px,
                end_px: s.end_px,
                n_pixels: Some(s.chain_len),
            }));
        }
    }

    /// Scores the frames whose 2-D lines are waiting against `truth` and lets their segments go; frames the truth
    /// does not hold are left out, as the scoring of a whole run leaves them out.
    pub fn score_segments(&mut self, truth: &Truth) {
        let Some(received) = &mut self.segments else { return };
        let mut waiting = std::mem::take(&mut received.waiting);
        while let Some(first) = waiting.first() {
            let image = first.image.clone();
            let n = waiting.iter().take_while(|r| r.image == image).count();
            let frame: Vec<Line2Row> = waiting.drain(..n).collect();
            if let Some(k) = frame_of(truth, &image) {
                received.scored.insert(k, score_image(truth, k, &frame));
            }
        }
    }

    /// Whether both truth topics have arrived.
    pub fn has_truth(&self) -> bool {
        !self.truth_poses.is_empty() && !self.truth_lines.is_empty()
    }

    /// A `wireframe` (`fitted` false) or `wireframe_fitted` message's parts. Edges completed behind an occluder
    /// are not scored: the truth holds the edges seen in images.
    pub fn on_wireframe(&mut self, fitted: bool, vertices: &[[f64; 3]], edges: &[WireEdge]) {
        let wire = (
            vertices.iter().map(|p| Vec3::from(*p)).collect(),
            edges
                .iter()
                .filter(|e| e.hidden == 0)
                .map(|e| [e.a as usize, e.b as usize])
                .collect(),
        );
        if fitted {
            self.fitted = Some(wire);
        } else {
            self.model = Some(wire);
            self.model_hidden = edges.iter().filter(|e| e.hidden != 0).count();
        }
    }

    /// A `faces` message.
    pub fn on_faces(&mut self, faces: &[FaceVertex]) {
        self.faces = Some(faces.to_vec());
    }

    /// The truth of `scene` as the truth topics gave it, to score against; `dir` is where the report goes.
    pub fn truth(&self, scene: Synthetic, dir: std::path::PathBuf) -> Truth {
        Truth {
            dir,
            poses: pose_rows(&scene, &self.truth_poses),
            lines: line_rows(&self.truth_lines),
            scene,
        }
    }

    /// The results to score against `truth`, with the orientation's check points when it wrote them.
    pub fn results(mut self, truth: &Truth, checkpoints: Option<Vec<CheckRow>>) -> Results {
        self.score_segments(truth);
        let scene = &truth.scene;
        Results {
            poses: self.poses.map(|p| pose_rows(scene, &p)),
            lines3d: self.lines.map(|l| line_rows(&l)),
            lines2d: self.segments.map(|s| Lines2d::Scored(s.scored)),
            checkpoints,
            model_openings: self.model.as_ref().zip(self.faces.as_ref()).map(|((v, _), f)| openings(v, f)),
            model_hidden_edges: self.model.as_ref().map(|_| self.model_hidden),
            // The live wire-frame carries the model's edges only; the surface lines are in model.obj.
            model_surface_lines: None,
            model: self.model,
            model_fitted: self.fitted,
        }
    }
}

/// Poses as `poses.csv` rows named by the scene's images; frames beyond the scene are left out.
pub fn pose_rows(scene: &Synthetic, poses: &[Pose]) -> Vec<PoseRow> {
    poses
        .iter()
        .filter(|p| (p.frame as usize) < scene.poses().len())
        .map(|p| PoseRow {
            image: scene.image_name(p.frame as usize),
            pose: p.exterior(),
            sigma_center_m: None,
            sigma_angles_deg: None,
        })
        .collect()
}

/// Lines as `lines3d.csv` rows.
pub fn line_rows(lines: &[Line3]) -> Vec<Line3Row> {
    lines.iter().map(Line3Row::from).collect()
}

/// The window and door faces (outer rings) of a `ModelFaces` message over its wire-frame's vertices.
pub fn openings(vertices: &[Vec3], faces: &[FaceVertex]) -> Vec<ModelOpening> {
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

#[cfg(test)]
mod tests {
    use super::*;

    fn edge(a: u32, b: u32, hidden: u32) -> WireEdge {
        WireEdge {
            a,
            b,
            face: 0,
            kind: 0,
            hidden,
        }
    }

    fn vertex(face: u32, ring: u32, kind: u32, vertex: u32) -> FaceVertex {
        FaceVertex { face, ring, kind, vertex }
    }

    #[test]
    fn the_newest_wireframe_counts_and_hidden_edges_are_counted_not_scored() {
        let scene = Synthetic::new("d2x-strip", 0.05, 1).unwrap();
        let mut c = Collector::new(false);
        let truth = c.truth(scene, Default::default());
        let v = [[0.0; 3], [1.0, 0.0, 0.0], [1.0, 0.0, 1.0]];
        c.on_wireframe(false, &v[..2], &[edge(0, 1, 0)]);
        c.on_wireframe(false, &v, &[edge(0, 1, 0), edge(1, 2, 1)]);
        c.on_wireframe(true, &v[..2], &[edge(0, 1, 0)]);
        let r = c.results(&truth, None);
        let (vertices, edges) = r.model.unwrap();
        assert_eq!((vertices.len(), edges), (3, vec![[0, 1]]));
        assert_eq!(r.model_hidden_edges, Some(1));
        assert_eq!(r.model_fitted.unwrap().0.len(), 2);
        assert!(r.lines2d.is_none() && r.poses.is_none() && r.model_openings.is_none());
    }

    #[test]
    fn openings_are_the_outer_rings_of_window_and_door_faces() {
        let v: Vec<Vec3> = (0..8).map(|i| Vec3::new(i as f64, 0.0, 0.0)).collect();
        let faces = [
            vertex(0, 0, 0, 0),
            vertex(0, 1, 0, 1),
            vertex(1, 0, FaceVertex::KIND_WINDOW, 2),
            vertex(1, 0, FaceVertex::KIND_WINDOW, 3),
            vertex(2, 0, FaceVertex::KIND_DOOR, 4),
            vertex(2, 0, FaceVertex::KIND_DOOR, 99),
        ];
        let o = openings(&v, &faces);
        assert_eq!(o.len(), 2);
        assert!(!o[0].door && o[0].ring == [v[2], v[3]]);
        assert!(o[1].door && o[1].ring == [v[4]], "a vertex beyond the wire-frame is skipped");
    }

    #[test]
    fn poses_beyond_the_scene_are_left_out_and_named_by_image() {
        let scene = Synthetic::new("d2x-strip", 0.05, 1).unwrap();
        let inside = Pose::from_exterior(0, 0, Pose::ORIENTED, &scene.poses()[0]);
        let beyond = Pose { frame: 10_000, ..inside };
        let rows = pose_rows(&scene, &[inside, beyond]);
        assert_eq!(rows.len(), 1);
        assert_eq!(rows[0].image, scene.image_name(0));
    }
}
