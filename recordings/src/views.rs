//! Viewer channels: Foxglove renderings of recorded messages, so that a recording opens in Foxglove with images,
//! 2-D segments drawn over them, and cameras and 3-D lines in the 3-D panel.
//!
//! Images become `foxglove_msgs/msg/RawImage` previews (ros2msg + CDR), box-filtered down to at most
//! `preview_max_px` on the long side so that previews do not double the recording; 2-D segments and keypoints
//! become `foxglove.ImageAnnotations` in the preview's pixel grid; poses, 3-D lines and wire-frame models become
//! `foxglove.SceneUpdate` entities (JSON) in the object frame `world`. Each preview is in the frame `camera/<frame>`,
//! with a `foxglove.CameraCalibration` of the preview's pixel grid beside it, and each pose places that frame in
//! `world` (`foxglove.FrameTransforms`), so that Foxglove's image panel can draw the 3-D lines and the model over
//! the images.
use lineflow_messages::schema::{decode_view, read_elements, read_pod, Decoded};
use lineflow_messages::{
    parts, CameraModelHeader, Encoding, ImageHeader, Keypoint, KeypointsHeader, Line3, LineClass, Lines2DHeader, MessageKind, Pose,
    Segment2, Stamp, WireEdge, WireframeHeader,
};
use serde_json::{json, Value};

/// The schema of a viewer channel.
#[derive(Debug)]
pub struct ViewSchema {
    /// Schema name Foxglove recognises.
    pub name: &'static str,
    /// Schema encoding.
    pub schema_encoding: &'static str,
    /// Schema text.
    pub data: &'static str,
    /// Message encoding.
    pub message_encoding: &'static str,
}

/// `foxglove_msgs/msg/RawImage`.
pub const RAW_IMAGE: ViewSchema = ViewSchema {
    name: "foxglove_msgs/msg/RawImage",
    schema_encoding: "ros2msg",
    data: "builtin_interfaces/Time timestamp\nstring frame_id\nuint32 width\nuint32 height\nstring encoding\nuint32 step\n\
           uint8[] data\n================================================================================\n\
           MSG: builtin_interfaces/Time\nint32 sec\nuint32 nanosec\n",
    message_encoding: "cdr",
};

/// `foxglove_msgs/msg/CompressedImage`: the previews of a recording whose images are compressed
/// (`[record] images`), as JPEG, so that previews stay small beside the images.
pub const COMPRESSED_PREVIEW: ViewSchema = ViewSchema {
    name: "foxglove_msgs/msg/CompressedImage",
    schema_encoding: "ros2msg",
    data: "builtin_interfaces/Time timestamp\nstring frame_id\nuint8[] data\nstring format\n\
           ================================================================================\n\
           MSG: builtin_interfaces/Time\nint32 sec\nuint32 nanosec\n",
    message_encoding: "cdr",
};

/// JPEG quality of the compressed previews: viewing only.
const PREVIEW_JPEG_QUALITY: u8 = 80;

/// `foxglove.ImageAnnotations` (JSON).
pub const IMAGE_ANNOTATIONS: ViewSchema = ViewSchema {
    name: "foxglove.ImageAnnotations",
    schema_encoding: "jsonschema",
    data: r#"{"title":"foxglove.ImageAnnotations","type":"object","properties":{"circles":{"type":"array"},"points":{"type":"array","items":{"type":"object","properties":{"timestamp":{"type":"object"},"type":{"type":"integer"},"points":{"type":"array"},"outline_color":{"type":"object"},"thickness":{"type":"number"}}}},"texts":{"type":"array"}}}"#,
    message_encoding: "json",
};

/// `foxglove.SceneUpdate` (JSON).
pub const SCENE_UPDATE: ViewSchema = ViewSchema {
    name: "foxglove.SceneUpdate",
    schema_encoding: "jsonschema",
    data: r#"{"title":"foxglove.SceneUpdate","type":"object","properties":{"deletions":{"type":"array"},"entities":{"type":"array","items":{"type":"object","properties":{"timestamp":{"type":"object"},"frame_id":{"type":"string"},"id":{"type":"string"},"lines":{"type":"array"}}}}}}"#,
    message_encoding: "json",
};

/// `foxglove.CameraCalibration` (JSON).
pub const CAMERA_CALIBRATION: ViewSchema = ViewSchema {
    name: "foxglove.CameraCalibration",
    schema_encoding: "jsonschema",
    data: r#"{"title":"foxglove.CameraCalibration","type":"object","properties":{"timestamp":{"type":"object"},"frame_id":{"type":"string"},"width":{"type":"integer"},"height":{"type":"integer"},"distortion_model":{"type":"string"},"D":{"type":"array"},"K":{"type":"array"},"R":{"type":"array"},"P":{"type":"array"}}}"#,
    message_encoding: "json",
};

/// `foxglove.FrameTransforms` (JSON).
pub const FRAME_TRANSFORMS: ViewSchema = ViewSchema {
    name: "foxglove.FrameTransforms",
    schema_encoding: "jsonschema",
    data: r#"{"title":"foxglove.FrameTransforms","type":"object","properties":{"transforms":{"type":"array","items":{"type":"object","properties":{"timestamp":{"type":"object"},"parent_frame_id":{"type":"string"},"child_frame_id":{"type":"string"},"translation":{"type":"object"},"rotation":{"type":"object"}}}}}}"#,
    message_encoding: "json",
};

/// The viewer channels a kind can have: (channel suffix, schema).
fn views_of(kind: MessageKind) -> &'static [(&'static str, &'static ViewSchema)] {
    match kind {
        MessageKind::Image => &[("preview", &RAW_IMAGE), ("calibration", &CAMERA_CALIBRATION)],
        MessageKind::Lines2D | MessageKind::Keypoints => &[("annotations", &IMAGE_ANNOTATIONS)],
        MessageKind::Poses => &[("scene", &SCENE_UPDATE), ("transforms", &FRAME_TRANSFORMS)],
        MessageKind::Lines3D | MessageKind::Wireframe => &[("scene", &SCENE_UPDATE)],
        _ => &[],
    }
}

/// The frame of an image's preview and calibration, placed in `world` by its pose.
fn camera_frame(frame: u64) -> String {
    format!("camera/{frame}")
}

/// Renders viewer messages of one topic; remembers the preview scale so annotations match the previews.
#[derive(Debug)]
pub struct ViewRenderer {
    /// Longest preview side in pixels (0 = no previews).
    pub preview_max_px: u32,
    /// Preview pixels per image pixel of the latest image.
    scale: f64,
    /// Previews as JPEG `CompressedImage` instead of `RawImage`.
    compressed_previews: bool,
    /// Pixels averaged per side of each preview pixel's box (`None`: the whole box).
    preview_samples: Option<usize>,
    /// The camera of the images, once its message has come: the previews' calibration.
    camera: Option<CameraModelHeader>,
    /// Capture time of every frame rendered: a pose's transform is stamped with its image's time, since Foxglove
    /// draws an image only with a transform at or before the image's own stamp.
    frame_times: std::collections::BTreeMap<u64, u64>,
    /// Decoding buffers reused from message to message.
    scratch: Decoded,
}

impl ViewRenderer {
    /// A renderer with the given preview size.
    pub fn new(preview_max_px: u32) -> Self {
        Self {
            preview_max_px,
            scale: 1.0,
            compressed_previews: false,
            preview_samples: None,
            camera: None,
            frame_times: Default::default(),
            scratch: Decoded::default(),
        }
    }

    /// Previews as JPEG `foxglove_msgs/msg/CompressedImage` (for a recording whose images are compressed).
    pub fn with_compressed_previews(mut self, on: bool) -> Self {
        self.compressed_previews = on;
        self
    }

    /// Previews that average `n` × `n` pixels spread over each box instead of all of it (at least 1): a live view's
    /// preview of a 12 MP frame then reads a few rows in each box, not all 36 MB, at the price of some aliasing.
    pub fn with_sampled_previews(mut self, n: usize) -> Self {
        self.preview_samples = Some(n.max(1));
        self
    }

    /// The viewer channels this renderer fills for a topic of `kind` (channel suffix, schema): the recorder adds
    /// exactly these, [`render`](Self::render) writes no other.
    pub fn views(&self, kind: MessageKind) -> impl Iterator<Item = (&'static str, &'static ViewSchema)> + '_ {
        views_of(kind)
            .iter()
            .copied()
            .filter(move |(suffix, _)| self.preview_max_px > 0 || !matches!(*suffix, "preview" | "calibration"))
            .map(move |(suffix, schema)| match (suffix, self.compressed_previews) {
                ("preview", true) => (suffix, &COMPRESSED_PREVIEW),
                _ => (suffix, schema),
            })
    }

    /// The viewer messages of one recorded message: `(channel suffix, bytes)`.
    pub fn render(&mut self, kind: MessageKind, cdr: &[u8]) -> Vec<(&'static str, Vec<u8>)> {
        if kind == MessageKind::CameraModel {
            if let Ok((header, _)) = decode_view(kind, cdr, &mut self.scratch) {
                self.camera = Some(read_pod(header));
            }
            return Vec::new();
        }
        // Most messages (edge maps, tie points) have no view: do not decode them at all.
        if self.views(kind).next().is_none() {
            return Vec::new();
        }
        // An image's pixels are read in place from the recorded bytes, not copied out first.
        let Ok((header, payload)) = decode_view(kind, cdr, &mut self.scratch) else {
            return Vec::new();
        };
        let stamp: Stamp = read_pod(header);
        match kind {
            MessageKind::Image => {
                let h: ImageHeader = read_pod(header);
                self.frame_times.insert(stamp.frame, stamp.capture_time_ns);
                let factor = h.width.max(h.height).div_ceil(self.preview_max_px).max(1);
                self.scale = 1.0 / factor as f64;
                let samples = self.preview_samples.map_or(factor as usize, |n| n.min(factor as usize));
                let Some(p) = preview(&h, payload, factor, samples, self.compressed_previews) else {
                    return Vec::new();
                };
                let calibration = self
                    .camera
                    .filter(|c| (c.width, c.height) == (h.width, h.height))
                    .map(|c| ("calibration", calibration(&c, &stamp, factor)));
                std::iter::once(("preview", p)).chain(calibration).collect()
            }
            MessageKind::Lines2D => {
                let h: Lines2DHeader = read_pod(header);
                let segs: Vec<Segment2> = read_elements(&payload[..(h.n_segments as usize * size_of::<Segment2>()).min(payload.len())]);
                vec![("annotations", annotations(&stamp, &segs, self.scale))]
            }
            MessageKind::Keypoints => {
                let h: KeypointsHeader = read_pod(header);
                let kps: Vec<Keypoint> = read_elements(&payload[..(h.count as usize * size_of::<Keypoint>()).min(payload.len())]);
                let pts = kps.iter().map(|k| [k.col as f64, k.row as f64]);
                vec![("annotations", image_points(&stamp, pts, 1, self.scale))]
            }
            MessageKind::Wireframe => {
                let h: WireframeHeader = read_pod(header);
                let nv = h.n_vertices as usize;
                let split = parts::align8(nv * 24).min(payload.len());
                let vertices: Vec<[f64; 3]> = read_elements(&payload[..(nv * 24).min(split)]);
                let edges: Vec<WireEdge> = read_elements(&payload[split..]);
                let pts = |hidden: bool| -> Vec<Value> {
                    edges
                        .iter()
                        .filter(|e| (e.hidden != 0) == hidden)
                        .filter(|e| (e.a as usize) < vertices.len() && (e.b as usize) < vertices.len())
                        .flat_map(|e| [point(vertices[e.a as usize]), point(vertices[e.b as usize])])
                        .collect()
                };
                let mut entities = vec![entity(
                    &stamp,
                    "model".into(),
                    pts(false),
                    json!({ "r": 0.9, "g": 0.9, "b": 0.9, "a": 1.0 }),
                    3.0,
                )];
                // Edges completed behind an occluder: drawn apart, dimmer, so that a viewer can tell them.
                let hidden = pts(true);
                if !hidden.is_empty() {
                    entities.push(entity(
                        &stamp,
                        "model/hidden".into(),
                        hidden,
                        json!({ "r": 0.5, "g": 0.6, "b": 1.0, "a": 0.6 }),
                        2.0,
                    ));
                }
                vec![(
                    "scene",
                    serde_json::to_vec(&json!({ "deletions": [], "entities": entities })).unwrap_or_default(),
                )]
            }
            MessageKind::Poses => {
                let poses = read_elements::<Pose>(payload);
                vec![
                    ("scene", scene_poses(&stamp, &poses)),
                    ("transforms", transforms(&poses, &self.frame_times)),
                ]
            }
            MessageKind::Lines3D => vec![("scene", scene_lines(&stamp, &read_elements::<Line3>(payload)))],
            _ => Vec::new(),
        }
    }
}

fn time(ns: u64) -> Value {
    json!({ "sec": ns / 1_000_000_000, "nsec": ns % 1_000_000_000 })
}

/// A preview of a mono8 or rgb8 image `factor` times smaller, CDR-encoded as `foxglove_msgs/msg/RawImage`, or as
/// a JPEG `foxglove_msgs/msg/CompressedImage` when `jpeg`: each pixel the mean of `samples` × `samples` pixels
/// spread evenly over its box (all of them, a box filter, when `samples` is `factor`).
fn preview(h: &ImageHeader, pixels: &[u8], factor: u32, samples: usize, jpeg: bool) -> Option<Vec<u8>> {
    let enc = h.encoding()?;
    let channels = match enc {
        Encoding::Mono8 => 1,
        Encoding::Rgb8 => 3,
        _ => return None,
    };
    let (f, step) = (factor as usize, h.step as usize);
    let (w, ht) = (h.width as usize / f, h.height as usize / f);
    if w == 0 || ht == 0 || samples == 0 || pixels.len() < step * h.height as usize {
        return None;
    }
    // Offsets of the sampled rows and columns within a box: the centres of `samples` equal parts of it.
    let offsets: Vec<usize> = (0..samples).map(|k| (2 * k + 1) * f / (2 * samples)).collect();
    let mut out = vec![0u8; w * ht * channels];
    let mut sums = vec![0u32; w * channels];
    for (y, row_out) in out.chunks_exact_mut(w * channels).enumerate() {
        sums.fill(0);
        for &dy in &offsets {
            let row = &pixels[(y * f + dy) * step..][..w * f * channels];
            for (s, block) in sums.chunks_exact_mut(channels).zip(row.chunks_exact(f * channels)) {
                if samples == f && channels == 1 {
                    s[0] += block.iter().map(|&v| v as u32).sum::<u32>();
                    continue;
                }
                for &dx in &offsets {
                    for (s, &v) in s.iter_mut().zip(&block[dx * channels..(dx + 1) * channels]) {
                        *s += v as u32;
                    }
                }
            }
        }
        let n = (samples * samples) as u32;
        for (o, s) in row_out.iter_mut().zip(&sums) {
            *o = ((s + n / 2) / n) as u8;
        }
    }
    let mut cdr = Cdr::new();
    let ns = h.stamp.capture_time_ns;
    cdr.u32((ns / 1_000_000_000) as u32);
    cdr.u32((ns % 1_000_000_000) as u32);
    cdr.string(&camera_frame(h.stamp.frame));
    if jpeg {
        let color = if channels == 1 {
            image::ExtendedColorType::L8
        } else {
            image::ExtendedColorType::Rgb8
        };
        let mut file = Vec::new();
        image::ImageEncoder::write_image(
            image::codecs::jpeg::JpegEncoder::new_with_quality(&mut file, PREVIEW_JPEG_QUALITY),
            &out,
            w as u32,
            ht as u32,
            color,
        )
        .ok()?;
        cdr.u32(file.len() as u32);
        cdr.0.extend_from_slice(&file);
        cdr.string("jpeg");
        return Some(cdr.0);
    }
    cdr.u32(w as u32);
    cdr.u32(ht as u32);
    cdr.string(enc.name());
    cdr.u32((w * channels) as u32);
    cdr.u32(out.len() as u32);
    cdr.0.extend_from_slice(&out);
    Some(cdr.0)
}

/// The camera as Foxglove's pinhole model of the preview's pixel grid (`factor` image pixels a preview pixel), in
/// the optical frame (x right, y down, z along the view; `conventions.md` has y up and looks along −z). The lens
/// correction becomes `plumb_bob` to first order: the correction model is not OpenCV's, and the inverse of a
/// correction is its negative only while it is small (a drawing aid, not a measurement).
fn calibration(c: &CameraModelHeader, stamp: &Stamp, factor: u32) -> Vec<u8> {
    let f = factor as f64;
    let focal_px = c.focal_mm / c.pixel_size_mm;
    let cx = (c.width as f64 - 1.0) / 2.0 + c.principal_point_mm[0] / c.pixel_size_mm;
    let cy = (c.height as f64 - 1.0) / 2.0 - c.principal_point_mm[1] / c.pixel_size_mm;
    let (fp, cxp, cyp) = (focal_px / f, (cx + 0.5) / f - 0.5, (cy + 0.5) / f - 0.5);
    let fm = c.focal_mm;
    let [k1, k2, k3] = c.radial;
    let [p1, p2] = c.decentering;
    let msg = json!({
        "timestamp": time(stamp.capture_time_ns),
        "frame_id": camera_frame(stamp.frame),
        "width": c.width / factor,
        "height": c.height / factor,
        "distortion_model": "plumb_bob",
        "D": [-k1 * fm.powi(2), -k2 * fm.powi(4), p2 * fm, -p1 * fm, -k3 * fm.powi(6)],
        "K": [fp, 0.0, cxp, 0.0, fp, cyp, 0.0, 0.0, 1.0],
        "R": [1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0],
        "P": [fp, 0.0, cxp, 0.0, 0.0, fp, cyp, 0.0, 0.0, 0.0, 1.0, 0.0],
    });
    serde_json::to_vec(&msg).unwrap_or_default()
}

/// Each pose as the transform from `world` to the image's optical frame: the frame's origin at the perspective
/// centre, its axes the rows of diag(1, −1, −1)·M; stamped with its image's capture time, or 0 (valid from the
/// start) when the image was not seen.
fn transforms(poses: &[Pose], frame_times: &std::collections::BTreeMap<u64, u64>) -> Vec<u8> {
    let transforms: Vec<Value> = poses
        .iter()
        .map(|p| {
            let m = nalgebra::Matrix3::from_row_slice(&p.rotation);
            let optical = nalgebra::Matrix3::from_diagonal(&nalgebra::Vector3::new(1.0, -1.0, -1.0)) * m;
            let to_world = nalgebra::Rotation3::from_matrix(&optical.transpose());
            let q = nalgebra::UnitQuaternion::from_rotation_matrix(&to_world);
            json!({
                "timestamp": time(frame_times.get(&p.frame).copied().unwrap_or(0)),
                "parent_frame_id": "world",
                "child_frame_id": camera_frame(p.frame),
                "translation": point(p.center_m),
                "rotation": { "x": q.i, "y": q.j, "z": q.k, "w": q.w },
            })
        })
        .collect();
    serde_json::to_vec(&json!({ "transforms": transforms })).unwrap_or_default()
}

struct Cdr(Vec<u8>);

impl Cdr {
    fn new() -> Self {
        Self(vec![0, 1, 0, 0])
    }
    fn u32(&mut self, v: u32) {
        while !(self.0.len() - 4).is_multiple_of(4) {
            self.0.push(0);
        }
        self.0.extend_from_slice(&v.to_le_bytes());
    }
    fn string(&mut self, s: &str) {
        self.u32(s.len() as u32 + 1);
        self.0.extend_from_slice(s.as_bytes());
        self.0.push(0);
    }
}

fn annotations(stamp: &Stamp, segs: &[Segment2], scale: f64) -> Vec<u8> {
    image_points(stamp, segs.iter().flat_map(|s| [s.start_px, s.end_px]), 4, scale)
}

/// One `PointsAnnotation` of `kind` (1 points, 4 line list) in the preview's pixel grid. Written out directly, not
/// built as a `serde_json::Value` first: a 12 MP frame's 20,000 segments made 40,000 maps, most of the live view's
/// time on a frame's lines.
fn image_points(stamp: &Stamp, px: impl Iterator<Item = [f64; 2]>, kind: u32, scale: f64) -> Vec<u8> {
    fn put(out: &mut Vec<u8>, v: &impl serde::Serialize) {
        // Writing a number or a small value into a Vec cannot fail.
        let _ = serde_json::to_writer(&mut *out, v);
    }
    let mut out = Vec::with_capacity(256 + 48 * px.size_hint().0);
    out.extend_from_slice(b"{\"circles\":[],\"points\":[{\"fill_color\":");
    put(&mut out, &json!({ "r": 0.0, "g": 0.0, "b": 0.0, "a": 0.0 }));
    out.extend_from_slice(b",\"outline_color\":");
    put(&mut out, &json!({ "r": 1.0, "g": 0.2, "b": 0.1, "a": 1.0 }));
    out.extend_from_slice(b",\"outline_colors\":[],\"points\":[");
    for (i, p) in px.enumerate() {
        if i > 0 {
            out.push(b',');
        }
        out.extend_from_slice(b"{\"x\":");
        put(&mut out, &((p[0] + 0.5) * scale - 0.5));
        out.extend_from_slice(b",\"y\":");
        put(&mut out, &((p[1] + 0.5) * scale - 0.5));
        out.push(b'}');
    }
    out.extend_from_slice(b"],\"thickness\":2.0,\"timestamp\":");
    put(&mut out, &time(stamp.capture_time_ns));
    out.extend_from_slice(b",\"type\":");
    put(&mut out, &kind);
    out.extend_from_slice(b"}],\"texts\":[]}");
    out
}

fn entity(stamp: &Stamp, id: String, points: Vec<Value>, color: Value, thickness: f64) -> Value {
    json!({
        "timestamp": time(stamp.capture_time_ns),
        "frame_id": "world",
        "id": id,
        "lifetime": { "sec": 0, "nsec": 0 },
        "frame_locked": false,
        "metadata": [],
        "arrows": [], "cubes": [], "spheres": [], "cylinders": [], "triangles": [], "texts": [], "models": [],
        "lines": [{
            "type": 2, // LINE_LIST
            "pose": { "position": { "x": 0.0, "y": 0.0, "z": 0.0 }, "orientation": { "x": 0.0, "y": 0.0, "z": 0.0, "w": 1.0 } },
            "thickness": thickness,
            "scale_invariant": true,
            "points": points,
            "color": color,
            "colors": [],
            "indices": [],
        }],
    })
}

fn point(p: [f64; 3]) -> Value {
    json!({ "x": p[0], "y": p[1], "z": p[2] })
}

/// Each camera as a frustum 1 m deep: viewing rays Mᵀ(x, y, −1) through the frame corners (`conventions.md`).
fn scene_poses(stamp: &Stamp, poses: &[Pose]) -> Vec<u8> {
    let entities: Vec<Value> = poses
        .iter()
        .map(|p| {
            let m = &p.rotation;
            let ray = |x: f64, y: f64| -> [f64; 3] {
                let v = [x, y, -1.0];
                std::array::from_fn(|j| p.center_m[j] + (0..3).map(|i| m[3 * i + j] * v[i]).sum::<f64>())
            };
            let corners = [ray(-0.5, -0.35), ray(0.5, -0.35), ray(0.5, 0.35), ray(-0.5, 0.35)];
            let mut pts = Vec::new();
            for k in 0..4 {
                pts.extend([point(p.center_m), point(corners[k]), point(corners[k]), point(corners[(k + 1) % 4])]);
            }
            entity(
                stamp,
                format!("camera/{}", p.frame),
                pts,
                json!({ "r": 0.1, "g": 0.6, "b": 1.0, "a": 1.0 }),
                2.0,
            )
        })
        .collect();
    serde_json::to_vec(&json!({ "deletions": [], "entities": entities })).unwrap_or_default()
}

/// The 3-D lines as one entity per class, so that a viewer can show or hide each: structure amber, texture (lines
/// inside a surface) thin and grey, unclassed lines amber as before the classes.
fn scene_lines(stamp: &Stamp, lines: &[Line3]) -> Vec<u8> {
    let styles = [
        (
            LineClass::Structure,
            "lines3d/structure",
            json!({ "r": 1.0, "g": 0.8, "b": 0.0, "a": 1.0 }),
            2.0,
        ),
        (
            LineClass::Texture,
            "lines3d/texture",
            json!({ "r": 0.6, "g": 0.6, "b": 0.6, "a": 0.5 }),
            1.0,
        ),
        (
            LineClass::Unknown,
            "lines3d",
            json!({ "r": 1.0, "g": 0.8, "b": 0.0, "a": 1.0 }),
            2.0,
        ),
    ];
    let entities: Vec<Value> = styles
        .into_iter()
        .filter_map(|(class, name, color, thickness)| {
            let pts: Vec<Value> = lines
                .iter()
                .filter(|l| LineClass::from_code(l.class) == class)
                .flat_map(|l| [point(l.start_m), point(l.end_m)])
                .collect();
            (!pts.is_empty()).then(|| entity(stamp, format!("{name}/{}", stamp.frame), pts, color, thickness))
        })
        .collect();
    serde_json::to_vec(&json!({ "deletions": [], "entities": entities })).unwrap_or_default()
}

#[cfg(test)]
mod tests {
    use super::*;
    use lineflow_messages::schema::{bytes_of, encode};

    #[test]
    fn image_annotations_are_the_json_foxglove_reads() {
        let stamp = Stamp {
            capture_time_ns: 3_000_000_007,
            ..Default::default()
        };
        let px = [[10.0, 20.0], [30.5, 40.25], [0.0, -1.0], [1e-7, 4288.0]];
        let got: Value = serde_json::from_slice(&image_points(&stamp, px.iter().copied(), 4, 0.25)).unwrap();
        let points: Vec<Value> = px
            .iter()
            .map(|p| json!({ "x": (p[0] + 0.5) * 0.25 - 0.5, "y": (p[1] + 0.5) * 0.25 - 0.5 }))
            .collect();
        let want = json!({
            "circles": [],
            "points": [{
                "timestamp": { "sec": 3, "nsec": 7 },
                "type": 4,
                "points": points,
                "outline_color": { "r": 1.0, "g": 0.2, "b": 0.1, "a": 1.0 },
                "outline_colors": [],
                "fill_color": { "r": 0.0, "g": 0.0, "b": 0.0, "a": 0.0 },
                "thickness": 2.0,
            }],
            "texts": [],
        });
        // Both read back by one parser (serde_json's default number parsing does not round-trip every f64).
        let want: Value = serde_json::from_slice(&serde_json::to_vec(&want).unwrap()).unwrap();
        assert_eq!(got, want);
        let none: Value = serde_json::from_slice(&image_points(&stamp, std::iter::empty(), 1, 1.0)).unwrap();
        assert_eq!(none["points"][0]["points"], json!([]));
    }

    #[test]
    fn sampled_preview_averages_pixels_spread_over_each_box() {
        // One 4x4 box of an RGB image: 2 samples per side read rows and columns 1 and 3.
        let header = ImageHeader {
            width: 4,
            height: 4,
            step: 12,
            encoding: lineflow_messages::Encoding::Rgb8 as u32,
            ..Default::default()
        };
        let pixels: Vec<u8> = (0..48u8).collect();
        let want = |c: usize| {
            let v: Vec<u32> = [(1, 1), (1, 3), (3, 1), (3, 3)]
                .iter()
                .map(|&(y, x)| pixels[y * 12 + x * 3 + c] as u32)
                .collect();
            ((v.iter().sum::<u32>() + 2) / 4) as u8
        };
        let p = preview(&header, &pixels, 4, 2, false).unwrap();
        assert_eq!(&p[p.len() - 3..], &[want(0), want(1), want(2)]);
        // All samples: the box mean.
        let full = preview(&header, &pixels, 4, 4, false).unwrap();
        let mean = |c: usize| ((0..16).map(|i| pixels[i * 3 + c] as u32).sum::<u32>() + 8) / 16;
        assert_eq!(&full[full.len() - 3..], &[mean(0) as u8, mean(1) as u8, mean(2) as u8]);
    }

    #[test]
    fn preview_is_box_filtered_and_valid_cdr() {
        let header = ImageHeader {
            width: 4,
            height: 2,
            step: 4,
            ..Default::default()
        };
        let pixels = [0u8, 2, 10, 20, 4, 6, 30, 40];
        let mut cdr = Vec::new();
        encode(MessageKind::Image, bytes_of(&header), &pixels, &mut cdr);
        let mut r = ViewRenderer::new(2);
        let out = r.render(MessageKind::Image, &cdr);
        assert_eq!(out.len(), 1);
        let p = &out[0].1;
        // ... width 2, height 1, "mono8", step 2, then 2 bytes: means of the 2x2 boxes.
        assert_eq!(&p[p.len() - 2..], &[3, 25]);
        assert_eq!(r.scale, 0.5);
    }

    /// Where Foxglove's image panel draws a world point: the pose's transform into the optical frame, then the
    /// calibration's K and plumb_bob distortion in the preview's grid.
    fn foxglove_pixel(transform: &Value, calibration: &Value, x: [f64; 3]) -> [f64; 2] {
        let t = &transform["translation"];
        let r = &transform["rotation"];
        let q = nalgebra::UnitQuaternion::from_quaternion(nalgebra::Quaternion::new(
            r["w"].as_f64().unwrap(),
            r["x"].as_f64().unwrap(),
            r["y"].as_f64().unwrap(),
            r["z"].as_f64().unwrap(),
        ));
        let origin = nalgebra::Vector3::new(t["x"].as_f64().unwrap(), t["y"].as_f64().unwrap(), t["z"].as_f64().unwrap());
        let o = q.inverse() * (nalgebra::Vector3::from(x) - origin);
        let (xn, yn) = (o.x / o.z, o.y / o.z);
        let d: Vec<f64> = calibration["D"].as_array().unwrap().iter().map(|v| v.as_f64().unwrap()).collect();
        let k: Vec<f64> = calibration["K"].as_array().unwrap().iter().map(|v| v.as_f64().unwrap()).collect();
        let r2 = xn * xn + yn * yn;
        let radial = 1.0 + d[0] * r2 + d[1] * r2 * r2 + d[4] * r2 * r2 * r2;
        let xd = xn * radial + 2.0 * d[2] * xn * yn + d[3] * (r2 + 2.0 * xn * xn);
        let yd = yn * radial + d[2] * (r2 + 2.0 * yn * yn) + 2.0 * d[3] * xn * yn;
        [k[0] * xd + k[2], k[4] * yd + k[5]]
    }

    #[test]
    fn foxglove_projects_the_world_into_a_preview_where_the_collinearity_does() {
        use lineflow_photogrammetry::{rotation_from_opk, Camera, Pose as Eo, Vec3};
        let camera = Camera {
            width: 4000,
            height: 3000,
            pixel_size_mm: 0.006,
            focal_mm: 24.0,
            principal_point_mm: [0.05, -0.03],
            radial: [-2e-5, 1e-8, 0.0],
            decentering: [3e-6, -2e-6],
        };
        let eo = Eo {
            center: Vec3::new(102.0, -15.0, 6.0),
            rotation: rotation_from_opk(1.45, 0.2, -0.1),
        };
        let stamp = Stamp {
            frame: 7,
            capture_time_ns: 5,
            ..Default::default()
        };
        let pose = Pose {
            frame: 7,
            center_m: eo.center.into(),
            rotation: std::array::from_fn(|k| eo.rotation[(k / 3, k % 3)]),
            ..Default::default()
        };
        let factor = 4;
        let calib: Value = serde_json::from_slice(&calibration(&CameraModelHeader::from_camera(&camera), &stamp, factor)).unwrap();
        let tf: Value = serde_json::from_slice(&transforms(&[pose], &[(7, 5)].into())).unwrap();
        let tf = &tf["transforms"][0];
        assert_eq!(
            (tf["child_frame_id"].as_str(), calib["frame_id"].as_str()),
            (Some("camera/7"), Some("camera/7"))
        );
        assert_eq!((calib["width"].as_u64(), calib["height"].as_u64()), (Some(1000), Some(750)));
        assert_eq!(
            (tf["timestamp"]["nsec"].as_u64(), calib["timestamp"]["nsec"].as_u64()),
            (Some(5), Some(5))
        );
        let mut worst = 0.0f64;
        for (dx, dz) in [(0.0, 0.0), (8.0, 4.0), (-9.0, -5.0), (5.0, -3.0)] {
            // Points on a wall 20 m in front of the camera, spread over the frame.
            let x = eo.center + eo.rotation.transpose() * Vec3::new(dx, dz, -20.0);
            let px = eo.project(&camera, &x).unwrap();
            let expected = [(px[0] + 0.5) / factor as f64 - 0.5, (px[1] + 0.5) / factor as f64 - 0.5];
            let got = foxglove_pixel(tf, &calib, x.into());
            worst = worst.max((got[0] - expected[0]).hypot(got[1] - expected[1]));
        }
        // First order in the lens correction: a tenth of a preview pixel at the corners.
        assert!(worst < 0.1, "{worst} preview px");
    }

    #[test]
    fn the_3d_lines_become_one_scene_entity_per_class() {
        let line = |x: f64, class: LineClass| Line3 {
            start_m: [x, 0.0, 0.0],
            end_m: [x, 0.0, 1.0],
            class: class.code(),
            ..Default::default()
        };
        let stamp = Stamp {
            frame: 4,
            ..Default::default()
        };
        let lines = [
            line(0.0, LineClass::Structure),
            line(1.0, LineClass::Texture),
            line(2.0, LineClass::Texture),
        ];
        let v: Value = serde_json::from_slice(&scene_lines(&stamp, &lines)).unwrap();
        let entities = v["entities"].as_array().unwrap();
        let ids: Vec<&str> = entities.iter().map(|e| e["id"].as_str().unwrap()).collect();
        assert_eq!(ids, ["lines3d/structure/4", "lines3d/texture/4"]);
        let points = |k: usize| entities[k]["lines"][0]["points"].as_array().unwrap().len();
        assert_eq!((points(0), points(1)), (2, 4));
        // Lines of a stage that does not class them keep the entity of before.
        let v: Value = serde_json::from_slice(&scene_lines(&stamp, &[line(0.0, LineClass::Unknown)])).unwrap();
        assert_eq!(v["entities"][0]["id"], "lines3d/4");
    }

    #[test]
    fn a_wireframe_becomes_one_scene_entity_with_a_line_per_edge() {
        let header = WireframeHeader {
            n_vertices: 3,
            n_edges: 2,
            ..Default::default()
        };
        let vertices = [[0.0f64, 0.0, 0.0], [1.0, 0.0, 0.0], [1.0, 0.0, 2.0]];
        let edges = [
            WireEdge {
                a: 0,
                b: 1,
                face: 0,
                kind: 0,
                hidden: 0,
            },
            WireEdge {
                a: 1,
                b: 2,
                face: 0,
                kind: 0,
                hidden: 0,
            },
        ];
        let mut payload = vec![0u8; parts::two_part_len::<[f64; 3], WireEdge>(3, 2)];
        let mut aligned = vec![0u64; payload.len().div_ceil(8)];
        let buf: &mut [u8] = unsafe { std::slice::from_raw_parts_mut(aligned.as_mut_ptr().cast(), payload.len()) };
        parts::write(buf, &vertices, &edges);
        payload.copy_from_slice(buf);
        let mut cdr = Vec::new();
        encode(MessageKind::Wireframe, bytes_of(&header), &payload, &mut cdr);
        let out = ViewRenderer::new(0).render(MessageKind::Wireframe, &cdr);
        let v: Value = serde_json::from_slice(&out[0].1).unwrap();
        let pts = &v["entities"][0]["lines"][0]["points"];
        assert_eq!(pts.as_array().unwrap().len(), 4);
        assert_eq!(pts[3]["z"], 2.0);
        assert_eq!(v["entities"].as_array().unwrap().len(), 1, "no hidden edges, no second entity");

        // The second edge hidden: drawn as its own entity.
        let hidden = [edges[0], WireEdge { hidden: 1, ..edges[1] }];
        let mut buf = vec![0u64; payload.len().div_ceil(8)];
        let bytes: &mut [u8] = unsafe { std::slice::from_raw_parts_mut(buf.as_mut_ptr().cast(), payload.len()) };
        parts::write(bytes, &vertices, &hidden);
        let mut cdr = Vec::new();
        encode(MessageKind::Wireframe, bytes_of(&header), bytes, &mut cdr);
        let out = ViewRenderer::new(0).render(MessageKind::Wireframe, &cdr);
        let v: Value = serde_json::from_slice(&out[0].1).unwrap();
        assert_eq!(v["entities"][0]["lines"][0]["points"].as_array().unwrap().len(), 2);
        assert_eq!(v["entities"][1]["id"], "model/hidden");
        assert_eq!(v["entities"][1]["lines"][0]["points"][1]["z"], 2.0);
    }
}
