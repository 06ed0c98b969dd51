//! `lineflow-model`: the model stage (`impl = "csr"`). Rebuilds the wire-frame from every set of 3-D lines it
//! receives and publishes it (the live model), and at end-of-stream writes `model.obj` and `model.city.json`.
use std::collections::HashMap;

use anyhow::{bail, Context, Result};
use lineflow_formats::Line3Row;
use lineflow_messages::{kinds, FaceVertex, Line3, ModelFacesHeader, Pose, Stamp, WireEdge, WireframeHeader};
use lineflow_model::refine::{Endpoints, ImageLines};
use lineflow_model::{build_with_images, export, lines_from_rows, Cameras, Images, Model, ModelParams, SurfaceKind};
use lineflow_photogrammetry::{Camera, Vec3};
use lineflow_runtime::{Flow, NodeContext, Output};

/// The images' 2-D lines for Refine: segments as they arrive, indexed once the camera is known, each image
/// placed at its newest pose.
#[derive(Default)]
struct ImageLineStore {
    /// Measured-pixel endpoints of frames not indexed yet.
    pending: std::collections::BTreeMap<u64, Vec<Endpoints>>,
    /// Indexed frames, ascending, and their lines.
    frames: Vec<u64>,
    lines: Vec<ImageLines>,
    /// The newest pose of every oriented frame.
    poses: std::collections::BTreeMap<u64, lineflow_photogrammetry::Pose>,
}

impl ImageLineStore {
    /// Every frame's lines, at its newest pose (none while not oriented); how many are oriented.
    fn update(&mut self, camera: &Camera, min_px: f64) -> (&[ImageLines], usize) {
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
        let mut oriented = 0;
        for (frame, lines) in self.frames.iter().zip(&mut self.lines) {
            let pose = self.poses.get(frame).copied();
            oriented += usize::from(pose.is_some());
            lines.set_pose(pose);
        }
        (&self.lines, oriented)
    }
}

fn main() -> std::process::ExitCode {
    lineflow_runtime::run_node(body)
}

/// The edge's kind code of `WireEdge` (0 wall, 1 roof, 2 opening, 3 ground) from the first face it bounds.
fn wire_edges(model: &Model) -> Vec<WireEdge> {
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
                hidden: u32::from(e.completed),
            }
        })
        .collect()
}

/// The faces as rings of vertex indices, outer ring first, then the holes.
fn face_vertices(model: &Model) -> Vec<FaceVertex> {
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

fn body() -> Result<()> {
    let ctx = NodeContext::from_env()?;
    match ctx.implementation("csr") {
        "csr" => {}
        other => bail!("node '{}': unknown model impl '{other}' (available: csr)", ctx.name()),
    }
    let params: ModelParams = ctx.params()?;
    if let Err(e) = params.validate() {
        bail!("node '{}': {e}", ctx.name());
    }
    let lines_in = ctx.input::<kinds::Lines3D>("lines3d")?;
    let poses_in = ctx.optional_input::<kinds::Poses>("poses")?;
    // Refine needs the images' 2-D lines, the camera and the poses.
    let lines2d_in = ctx.optional_input::<kinds::Lines2D>("lines2d")?;
    let camera_in = ctx.optional_input::<kinds::CameraModel>("camera")?;
    let output = ctx.output::<kinds::Wireframe>("wireframe")?;
    let faces_out = ctx.optional_output::<kinds::ModelFaces>("faces")?;
    ctx.connect()?;

    let mut cameras = Cameras::default();
    let mut model = Model::default();
    let mut latest: Option<Vec<Line3Row>> = None;
    let mut published = std::collections::HashSet::new();
    let mut camera: Option<Camera> = None;
    let mut image_lines = ImageLineStore::default();
    let refining = params.refine && lines2d_in.is_some() && camera_in.is_some() && poses_in.is_some();
    if params.refine && !refining {
        tracing::warn!("refine needs the lines2d, camera and poses inputs wired: building without it");
    }
    ctx.run(|| {
        if let Some(cam) = &camera_in {
            while let Some(m) = cam.receive()? {
                camera = Some(m.user_header().camera());
            }
        }
        if let Some(poses) = &poses_in {
            while let Some(m) = poses.receive()? {
                let oriented: Vec<&Pose> = m.payload().iter().filter(|p: &&Pose| p.flags & 1 != 0).collect();
                if !oriented.is_empty() {
                    cameras = Cameras::new(oriented.iter().map(|p| Vec3::from(p.center_m)).collect());
                }
                image_lines.poses = oriented.iter().map(|p| (p.frame, p.exterior())).collect();
            }
        }
        if let Some(lines2d) = &lines2d_in {
            lines2d.for_each_segments(|h, segs, _| {
                if refining {
                    image_lines
                        .pending
                        .insert(h.stamp.frame, segs.iter().map(|s| (s.start_px, s.end_px)).collect());
                }
                Ok(())
            })?;
        }
        // Only the newest set of lines is built: each one holds every line so far. Every frame received for the
        // first time still gets its model message, in order, so that downstream sees no frame missing.
        let mut received: Vec<Stamp> = Vec::new();
        while let Some(m) = lines_in.receive()? {
            latest = Some(m.payload().iter().map(|l: &Line3| Line3Row::from(l)).collect());
            received.push(m.user_header().stamp);
        }
        if let (Some(rows), Some(&stamp)) = (latest.take(), received.last()) {
            let lines = lines_from_rows(&rows, &params);
            let images = match (&camera, refining) {
                (Some(cam), true) => match image_lines.update(cam, params.refine_min_image_line_px) {
                    (lines, oriented) if oriented >= 2 => Some(Images {
                        camera: cam,
                        lines,
                        params: params.refine_params(),
                    }),
                    _ => None,
                },
                _ => None,
            };
            model = build_with_images(&lines, &params, &cameras, images.as_ref());
            let d = &model.diagnostics;
            tracing::debug!(
                frame = stamp.frame,
                lines = d.lines_in,
                vertices = model.vertices.len(),
                faces = model.faces.len(),
                "model rebuilt"
            );
            for stamp in lineflow_runtime::frames_to_publish(&received, &mut published) {
                publish(&output, faces_out.as_ref(), stamp, &model)?;
            }
        }
        Ok(if lines_in.is_ended() { Flow::Stop } else { Flow::Continue })
    })?;
    output.end_of_stream()?;
    if let Some(f) = &faces_out {
        f.end_of_stream()?;
    }
    let dir = ctx.out_dir();
    let (obj, city) = (dir.join("model.obj"), dir.join("model.city.json"));
    export::write_obj(&obj, &model).with_context(|| format!("writing {}", obj.display()))?;
    export::write_cityjson(&city, &model).with_context(|| format!("writing {}", city.display()))?;
    let d = &model.diagnostics;
    if d.lines_in > 0 && model.faces.is_empty() {
        tracing::warn!("no closed face among {} lines: the model is a loose wire-frame", d.lines_in);
    }
    tracing::info!("model: {} -> {}", model.summary(), obj.display());
    ctx.finish();
    Ok(())
}
