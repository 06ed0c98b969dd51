//! The recorded form of every message: a field table per `#[repr(C)]` type, from which the ros2msg definition
//! (the MCAP schema), the CDR encoder and the CDR decoder are all derived, so that the three cannot disagree.
//!
//! CDR here is what ROS 2 writes (XCDR1, little-endian, encapsulation `00 01 00 00`): primitives aligned to their
//! size relative to the start of the data, strings and sequences as a `u32` count followed by the elements.
//! Fixed-size NUL-padded text fields become `string`s; nested arrays are flattened (`float64[48] corners_m`).
//! A decoded message is the same header and payload bytes a publisher sends, so a recording can be replayed into a
//! graph: decoding is exact except for bytes after a text field's first NUL, which publishers write as zero.
use std::mem::offset_of;

use crate::*;

/// A primitive field type.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Scalar {
    /// `uint8`
    U8,
    /// `uint16`
    U16,
    /// `uint32`
    U32,
    /// `uint64`
    U64,
    /// `int32`
    I32,
    /// `float32`
    F32,
    /// `float64`
    F64,
}

impl Scalar {
    /// Bytes per value.
    pub const fn size(self) -> usize {
        match self {
            Scalar::U8 => 1,
            Scalar::U16 => 2,
            Scalar::U32 | Scalar::I32 | Scalar::F32 => 4,
            Scalar::U64 | Scalar::F64 => 8,
        }
    }
    /// The ros2msg type name.
    pub const fn ros_name(self) -> &'static str {
        match self {
            Scalar::U8 => "uint8",
            Scalar::U16 => "uint16",
            Scalar::U32 => "uint32",
            Scalar::U64 => "uint64",
            Scalar::I32 => "int32",
            Scalar::F32 => "float32",
            Scalar::F64 => "float64",
        }
    }
}

/// The type of a field.
#[derive(Debug, Clone, Copy)]
pub enum FieldType {
    /// One value.
    Scalar(Scalar),
    /// A fixed array of values (nested arrays flattened, row-major).
    Array(Scalar, usize),
    /// A NUL-padded UTF-8 byte array of this length, recorded as `string`.
    Text(usize),
    /// A nested struct.
    Struct(&'static Layout),
}

impl FieldType {
    /// Bytes the field takes in its struct.
    pub fn size(self) -> usize {
        match self {
            FieldType::Scalar(s) => s.size(),
            FieldType::Array(s, n) => s.size() * n,
            FieldType::Text(n) => n,
            FieldType::Struct(l) => l.size,
        }
    }
}

/// A named field at a byte offset of its struct.
#[derive(Debug, Clone, Copy)]
pub struct Field {
    /// Field name (ros2msg: lower-case snake case).
    pub name: &'static str,
    /// Byte offset in the `#[repr(C)]` struct.
    pub offset: usize,
    /// Its type.
    pub ty: FieldType,
}

/// The field table of a `#[repr(C)]` struct.
#[derive(Debug)]
pub struct Layout {
    /// Type name inside the `lineflow_msgs` package.
    pub name: &'static str,
    /// `size_of` the struct.
    pub size: usize,
    /// Fields in declaration order.
    pub fields: &'static [Field],
}

/// Element type of a payload part.
#[derive(Debug, Clone, Copy)]
pub enum Elem {
    /// Raw bytes (`uint8[]`).
    Byte,
    /// Structs.
    Struct(&'static Layout),
}

impl Elem {
    fn size(self) -> usize {
        match self {
            Elem::Byte => 1,
            Elem::Struct(l) => l.size,
        }
    }
}

/// A payload part: a named sequence.
#[derive(Debug, Clone, Copy)]
pub struct Part {
    /// Field name of the sequence.
    pub name: &'static str,
    /// Its elements.
    pub elem: Elem,
}

/// How a message's payload is laid out (see [`crate::parts`] for two-part payloads).
#[derive(Debug, Clone, Copy)]
pub enum Payload {
    /// No payload.
    Empty,
    /// One sequence of elements.
    One(Part),
    /// Two sequences; the header field `count` holds the length of the first, the second fills the rest.
    Two {
        /// Header field (`uint32`) with the element count of `a`.
        count: &'static str,
        /// First part.
        a: Part,
        /// Second part, starting at the next multiple of 8 bytes.
        b: Part,
    },
}

/// The recorded form of a message kind.
#[derive(Debug)]
pub struct MessageSchema {
    /// The kind.
    pub kind: MessageKind,
    /// The header's fields (the top level of the ros2msg message).
    pub header: &'static Layout,
    /// The payload.
    pub payload: Payload,
}

/// Package of every schema.
pub const PACKAGE: &str = "lineflow_msgs";
/// MCAP schema encoding of [`MessageSchema::ros2msg`].
pub const SCHEMA_ENCODING: &str = "ros2msg";
/// MCAP message encoding of [`encode`].
pub const MESSAGE_ENCODING: &str = "cdr";

macro_rules! layout {
    ($ty:ty, $name:literal { $($field:ident : $fty:expr),* $(,)? }) => {
        Layout {
            name: $name,
            size: size_of::<$ty>(),
            fields: &[$(Field { name: stringify!($field), offset: offset_of!($ty, $field), ty: $fty }),*],
        }
    };
}

use FieldType::{Array, Scalar as S, Struct, Text};
use Scalar::*;

static STAMP: Layout = layout!(Stamp, "Stamp" { frame: S(U64), capture_time_ns: S(U64), seq: S(U64), flags: S(U32), revision: S(U32) });
static IMAGE: Layout = layout!(ImageHeader, "Image" {
    stamp: Struct(&STAMP), width: S(U32), height: S(U32), step: S(U32), encoding: S(U32), name: Text(64),
});
static CAMERA: Layout = layout!(CameraModelHeader, "CameraModel" {
    stamp: Struct(&STAMP), width: S(U32), height: S(U32), pixel_size_mm: S(F64), focal_mm: S(F64),
    principal_point_mm: Array(F64, 2), radial: Array(F64, 3), decentering: Array(F64, 2),
});
static CONTROL_POINTS: Layout = layout!(ControlPointsHeader, "ControlPoints" { stamp: Struct(&STAMP) });
static CONTROL_POINT: Layout = layout!(ControlPoint, "ControlPoint" {
    id: Text(16), xyz: Array(F64, 3), sigma_m: Array(F64, 3), role: S(U32), reserved: S(U32),
});
static OBSERVATIONS: Layout = layout!(ObservationsHeader, "Observations" { stamp: Struct(&STAMP) });
static OBSERVATION: Layout = layout!(Observation, "Observation" { frame: S(U64), point_id: Text(16), col: S(F64), row: S(F64) });
static SITE: Layout = layout!(SiteHeader, "Site" { stamp: Struct(&STAMP) });
static WALL: Layout = layout!(Wall, "Wall" {
    name: Text(32), n_corners: S(U32), reserved: S(U32), corners: Array(F64, 3 * Wall::MAX_CORNERS),
});
static KEYPOINTS: Layout = layout!(KeypointsHeader, "Keypoints" {
    stamp: Struct(&STAMP), count: S(U32), descriptor_len: S(U32), descriptor_kind: S(U32), detector: Text(12),
});
static KEYPOINT: Layout = layout!(Keypoint, "Keypoint" {
    col: S(F32), row: S(F32), scale_px: S(F32), orientation_rad: S(F32), response: S(F32), laplacian_sign: S(I32),
});
static TIE_POINTS: Layout = layout!(TiePointsHeader, "TiePoints" { stamp: Struct(&STAMP) });
static TIE_POINT: Layout = layout!(TiePoint, "TiePoint" { track: S(U64), frame: S(U64), col: S(F64), row: S(F64) });
static POSES: Layout = layout!(PosesHeader, "Poses" { stamp: Struct(&STAMP), sigma0: S(F64), rms_px: S(F64) });
static POSE: Layout = layout!(Pose, "Pose" {
    frame: S(U64), revision: S(U32), flags: S(U32), center_m: Array(F64, 3), rotation: Array(F64, 9),
    sigma_center_m: Array(F64, 3), sigma_angles_rad: Array(F64, 3),
});
static EDGE_MAP: Layout = layout!(EdgeMapHeader, "EdgeMap" {
    stamp: Struct(&STAMP), width: S(U32), height: S(U32), detector: Text(16), name: Text(64),
});
static EDGE_PIXEL: Layout = layout!(EdgePixel, "EdgePixel" { col: S(U16), row: S(U16), magnitude: S(F32), direction_rad: S(F32) });
static LINES2D: Layout = layout!(Lines2DHeader, "Lines2D" { stamp: Struct(&STAMP), n_segments: S(U32), n_chain: S(U32), name: Text(64) });
static SEGMENT2: Layout = layout!(Segment2, "Segment2" {
    id: S(U32), chain_start: S(U32), chain_len: S(U32), reserved: S(U32), start_px: Array(F64, 2), end_px: Array(F64, 2),
});
/// A chain pixel, `[u16; 2]` = (column, row).
static PIXEL: Layout = Layout {
    name: "Pixel",
    size: 4,
    fields: &[
        Field {
            name: "col",
            offset: 0,
            ty: S(U16),
        },
        Field {
            name: "row",
            offset: 2,
            ty: S(U16),
        },
    ],
};
static POINTS3D: Layout = layout!(Points3DHeader, "Points3D" { stamp: Struct(&STAMP), n_groups: S(U32), n_points: S(U32) });
static POINT_GROUP: Layout = layout!(PointGroup, "PointGroup" { segment_id: S(U32), start: S(U32), len: S(U32), n_views: S(U32) });
static POINT3: Layout = layout!(Point3, "Point3" { xyz: Array(F64, 3), sncc: S(F64) });
static LINES3D: Layout = layout!(Lines3DHeader, "Lines3D" { stamp: Struct(&STAMP) });
static LINE3: Layout = layout!(Line3, "Line3" {
    id: S(U64), start_m: Array(F64, 3), end_m: Array(F64, 3), n_points: S(U32), n_images: S(U32), rms_m: S(F64),
    class: S(U32), reserved: S(U32),
});
static WIREFRAME: Layout = layout!(WireframeHeader, "Wireframe" { stamp: Struct(&STAMP), n_vertices: S(U32), n_edges: S(U32) });
/// A model vertex, `[f64; 3]` in metres.
static VERTEX: Layout = Layout {
    name: "Vertex",
    size: 24,
    fields: &[Field {
        name: "xyz_m",
        offset: 0,
        ty: Array(F64, 3),
    }],
};
static WIRE_EDGE: Layout = layout!(WireEdge, "WireEdge" { a: S(U32), b: S(U32), face: S(U32), kind: S(U32), hidden: S(U32) });
static MODEL_FACES: Layout = layout!(ModelFacesHeader, "ModelFaces" { stamp: Struct(&STAMP), n_faces: S(U32), reserved: S(U32) });
static FACE_VERTEX: Layout = layout!(FaceVertex, "FaceVertex" { face: S(U32), ring: S(U32), kind: S(U32), vertex: S(U32) });

const fn one(name: &'static str, layout: &'static Layout) -> Payload {
    Payload::One(Part {
        name,
        elem: Elem::Struct(layout),
    })
}
const fn part(name: &'static str, layout: &'static Layout) -> Part {
    Part {
        name,
        elem: Elem::Struct(layout),
    }
}

static SCHEMAS: &[MessageSchema] = &[
    MessageSchema {
        kind: MessageKind::Image,
        header: &IMAGE,
        payload: Payload::One(Part {
            name: "data",
            elem: Elem::Byte,
        }),
    },
    MessageSchema {
        kind: MessageKind::CameraModel,
        header: &CAMERA,
        payload: Payload::Empty,
    },
    MessageSchema {
        kind: MessageKind::ControlPoints,
        header: &CONTROL_POINTS,
        payload: one("points", &CONTROL_POINT),
    },
    MessageSchema {
        kind: MessageKind::Observations,
        header: &OBSERVATIONS,
        payload: one("observations", &OBSERVATION),
    },
    MessageSchema {
        kind: MessageKind::Site,
        header: &SITE,
        payload: one("walls", &WALL),
    },
    MessageSchema {
        kind: MessageKind::Keypoints,
        header: &KEYPOINTS,
        payload: Payload::Two {
            count: "count",
            a: part("keypoints", &KEYPOINT),
            b: Part {
                name: "descriptors",
                elem: Elem::Byte,
            },
        },
    },
    MessageSchema {
        kind: MessageKind::TiePoints,
        header: &TIE_POINTS,
        payload: one("tie_points", &TIE_POINT),
    },
    MessageSchema {
        kind: MessageKind::Poses,
        header: &POSES,
        payload: one("poses", &POSE),
    },
    MessageSchema {
        kind: MessageKind::EdgeMap,
        header: &EDGE_MAP,
        payload: one("pixels", &EDGE_PIXEL),
    },
    MessageSchema {
        kind: MessageKind::Lines2D,
        header: &LINES2D,
        payload: Payload::Two {
            count: "n_segments",
            a: part("segments", &SEGMENT2),
            b: part("chain", &PIXEL),
        },
    },
    MessageSchema {
        kind: MessageKind::Points3D,
        header: &POINTS3D,
        payload: Payload::Two {
            count: "n_groups",
            a: part("groups", &POINT_GROUP),
            b: part("points", &POINT3),
        },
    },
    MessageSchema {
        kind: MessageKind::Lines3D,
        header: &LINES3D,
        payload: one("lines", &LINE3),
    },
    MessageSchema {
        kind: MessageKind::Wireframe,
        header: &WIREFRAME,
        payload: Payload::Two {
            count: "n_vertices",
            a: part("vertices", &VERTEX),
            b: part("edges", &WIRE_EDGE),
        },
    },
    MessageSchema {
        kind: MessageKind::ModelFaces,
        header: &MODEL_FACES,
        payload: one("vertices", &FACE_VERTEX),
    },
];

/// What is wrong with a recorded message.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct DecodeError(pub String);

impl std::fmt::Display for DecodeError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&self.0)
    }
}
impl std::error::Error for DecodeError {}

fn err<T>(msg: impl Into<String>) -> Result<T, DecodeError> {
    Err(DecodeError(msg.into()))
}

impl MessageKind {
    /// The recorded form of this kind.
    pub fn schema(self) -> &'static MessageSchema {
        SCHEMAS.iter().find(|s| s.kind == self).expect("every kind has a schema (test)")
    }
}

impl MessageSchema {
    /// The MCAP schema name, e.g. `lineflow_msgs/msg/Image`.
    pub fn name(&self) -> String {
        format!("{PACKAGE}/msg/{}", self.kind.name())
    }

    /// Looks a kind up by its MCAP schema name.
    pub fn by_name(name: &str) -> Option<&'static MessageSchema> {
        let short = name.strip_prefix(PACKAGE)?.strip_prefix("/msg/")?;
        SCHEMAS.iter().find(|s| s.kind.name() == short)
    }

    /// The ros2msg definition with every nested type, as ROS 2 writes it into MCAP files.
    pub fn ros2msg(&self) -> String {
        let mut main = String::new();
        let mut nested: Vec<&'static Layout> = Vec::new();
        fields_text(self.header, &mut main, &mut nested);
        let mut sequence = |p: &Part, out: &mut String| match p.elem {
            Elem::Byte => out.push_str(&format!("uint8[] {}\n", p.name)),
            Elem::Struct(l) => {
                out.push_str(&format!("{PACKAGE}/{}[] {}\n", l.name, p.name));
                push_nested(l, &mut nested);
            }
        };
        match &self.payload {
            Payload::Empty => {}
            Payload::One(p) => sequence(p, &mut main),
            Payload::Two { a, b, .. } => {
                sequence(a, &mut main);
                sequence(b, &mut main);
            }
        }
        let mut i = 0;
        while i < nested.len() {
            let l = nested[i];
            main.push_str(&format!("{}\nMSG: {PACKAGE}/{}\n", "=".repeat(80), l.name));
            fields_text(l, &mut main, &mut nested);
            i += 1;
        }
        main
    }

    fn count_of(&self, header: &[u8]) -> Option<usize> {
        let Payload::Two { count, .. } = self.payload else {
            return None;
        };
        let f = self
            .header
            .fields
            .iter()
            .find(|f| f.name == count)
            .expect("count field exists (test)");
        Some(u32::from_ne_bytes(header[f.offset..f.offset + 4].try_into().unwrap()) as usize)
    }
}

fn push_nested(l: &'static Layout, nested: &mut Vec<&'static Layout>) {
    if !nested.iter().any(|n| std::ptr::eq(*n, l)) {
        nested.push(l);
    }
}

fn fields_text(layout: &'static Layout, out: &mut String, nested: &mut Vec<&'static Layout>) {
    for f in layout.fields {
        let ty = match f.ty {
            FieldType::Scalar(s) => s.ros_name().to_owned(),
            FieldType::Array(s, n) => format!("{}[{n}]", s.ros_name()),
            FieldType::Text(_) => "string".to_owned(),
            FieldType::Struct(l) => {
                push_nested(l, nested);
                format!("{PACKAGE}/{}", l.name)
            }
        };
        out.push_str(&format!("{ty} {}\n", f.name));
    }
}

/// CDR of a message: `header` and `payload` are the bytes of the header struct and of the payload slice.
///
/// # Panics
/// When `header` is shorter than the kind's header (a caller bug, not bad input).
pub fn encode(kind: MessageKind, header: &[u8], payload: &[u8], out: &mut Vec<u8>) {
    let schema = kind.schema();
    assert!(
        header.len() >= schema.header.size,
        "header of {} is {} bytes",
        kind.name(),
        header.len()
    );
    out.clear();
    out.reserve(64 + header.len() + payload.len() + payload.len() / 2);
    out.extend_from_slice(&[0, 1, 0, 0]);
    let mut w = CdrWriter { out };
    w.layout(schema.header, header);
    match schema.payload {
        Payload::Empty => {}
        Payload::One(p) => w.sequence(p.elem, payload),
        Payload::Two { a, b, .. } => {
            let count = schema.count_of(header).unwrap_or(0);
            let split = parts::align8(count * a.elem.size()).min(payload.len());
            w.sequence(a.elem, &payload[..(count * a.elem.size()).min(payload.len())]);
            w.sequence(b.elem, &payload[split..]);
        }
    }
}

/// A decoded message: header bytes (`size_of` the header) and payload bytes (whole elements).
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct Decoded {
    /// Header struct bytes.
    pub header: Vec<u8>,
    /// Payload bytes.
    pub payload: Vec<u8>,
}

impl Decoded {
    /// The stamp at the start of the header.
    pub fn stamp(&self) -> Stamp {
        // Every header starts with its Stamp (repr(C)).
        read_pod(&self.header)
    }
}

/// Decodes the CDR of a message of `kind`.
///
/// # Errors
/// A [`DecodeError`] naming what is wrong (truncated data, a count that disagrees with the header, not CDR).
pub fn decode(kind: MessageKind, cdr: &[u8]) -> Result<Decoded, DecodeError> {
    let mut d = Decoded::default();
    decode_into(kind, cdr, &mut d)?;
    Ok(d)
}

/// [`decode`] into buffers that keep their capacity from message to message (a player replaying large images
/// would otherwise fault in fresh pages for every one).
///
/// # Errors
/// As [`decode`].
pub fn decode_into(kind: MessageKind, cdr: &[u8], out: &mut Decoded) -> Result<(), DecodeError> {
    let mut r = read_header(kind, cdr, &mut out.header)?;
    out.payload.clear();
    read_payload(kind, &mut r, &out.header, &mut out.payload)
}

/// The header bytes (decoded into `scratch.header`) and the payload of a message, borrowed from `cdr` itself when
/// the payload is raw bytes (an image: no copy of its pixels), else decoded into `scratch.payload`.
///
/// # Errors
/// As [`decode`].
pub fn decode_view<'a>(kind: MessageKind, cdr: &'a [u8], scratch: &'a mut Decoded) -> Result<(&'a [u8], &'a [u8]), DecodeError> {
    let mut r = read_header(kind, cdr, &mut scratch.header)?;
    if let Payload::One(Part { elem: Elem::Byte, .. }) = kind.schema().payload {
        let n = r.u32()?;
        return Ok((&scratch.header, r.take(1, n)?));
    }
    scratch.payload.clear();
    read_payload(kind, &mut r, &scratch.header, &mut scratch.payload)?;
    Ok((&scratch.header, &scratch.payload))
}

/// Checks the encapsulation, decodes the header into `header` and returns the reader positioned after it.
fn read_header<'c>(kind: MessageKind, cdr: &'c [u8], header: &mut Vec<u8>) -> Result<CdrReader<'c>, DecodeError> {
    if cdr.len() < 4 || cdr[..2] != [0, 1] {
        return err(format!(
            "{}: not little-endian CDR (encapsulation {:02x?})",
            kind.name(),
            &cdr[..cdr.len().min(4)]
        ));
    }
    let layout = kind.schema().header;
    let mut r = CdrReader { data: &cdr[4..], pos: 0 };
    header.clear();
    header.resize(layout.size, 0);
    r.layout(layout, header)?;
    Ok(r)
}

fn read_payload(kind: MessageKind, r: &mut CdrReader<'_>, header: &[u8], out: &mut Vec<u8>) -> Result<(), DecodeError> {
    let schema = kind.schema();
    match schema.payload {
        Payload::Empty => {}
        Payload::One(p) => r.sequence(p.elem, out)?,
        Payload::Two { a, b, .. } => {
            let count = schema.count_of(header).unwrap_or(0);
            r.sequence(a.elem, out)?;
            if out.len() != count * a.elem.size() {
                return err(format!(
                    "{}: header says {count} elements in '{}' but {} were recorded",
                    kind.name(),
                    a.name,
                    out.len() / a.elem.size()
                ));
            }
            out.resize(parts::align8(out.len()), 0);
            r.sequence(b.elem, out)?;
        }
    }
    Ok(())
}

struct CdrWriter<'a> {
    out: &'a mut Vec<u8>,
}

impl CdrWriter<'_> {
    fn align(&mut self, n: usize) {
        while !(self.out.len() - 4).is_multiple_of(n) {
            self.out.push(0);
        }
    }

    fn scalars(&mut self, s: Scalar, bytes: &[u8]) {
        self.align(s.size());
        // Structs hold native-endian values; CDR here is little-endian.
        if cfg!(target_endian = "little") || s.size() == 1 {
            self.out.extend_from_slice(bytes);
        } else {
            for v in bytes.chunks_exact(s.size()) {
                self.out.extend(v.iter().rev());
            }
        }
    }

    fn layout(&mut self, layout: &Layout, bytes: &[u8]) {
        for f in layout.fields {
            let at = &bytes[f.offset..];
            match f.ty {
                FieldType::Scalar(s) => self.scalars(s, &at[..s.size()]),
                FieldType::Array(s, n) => self.scalars(s, &at[..s.size() * n]),
                FieldType::Text(n) => {
                    let text = &at[..n];
                    let len = text.iter().position(|&b| b == 0).unwrap_or(n);
                    self.scalars(Scalar::U32, &(len as u32 + 1).to_ne_bytes());
                    self.out.extend_from_slice(&text[..len]);
                    self.out.push(0);
                }
                FieldType::Struct(l) => self.layout(l, &at[..l.size]),
            }
        }
    }

    fn sequence(&mut self, elem: Elem, bytes: &[u8]) {
        let n = bytes.len() / elem.size();
        self.scalars(Scalar::U32, &(n as u32).to_ne_bytes());
        match elem {
            Elem::Byte => self.out.extend_from_slice(bytes),
            Elem::Struct(l) => {
                for e in bytes.chunks_exact(l.size) {
                    self.layout(l, e);
                }
            }
        }
    }
}

struct CdrReader<'a> {
    data: &'a [u8],
    pos: usize,
}

impl<'a> CdrReader<'a> {
    fn take(&mut self, align: usize, n: usize) -> Result<&'a [u8], DecodeError> {
        let start = self.pos.next_multiple_of(align);
        let end = start.checked_add(n).filter(|&e| e <= self.data.len());
        let Some(end) = end else {
            return err(format!("truncated: need {n} bytes at offset {start}, have {}", self.data.len()));
        };
        self.pos = end;
        Ok(&self.data[start..end])
    }

    fn scalars(&mut self, s: Scalar, out: &mut [u8]) -> Result<(), DecodeError> {
        let src = self.take(s.size(), out.len())?;
        if cfg!(target_endian = "little") || s.size() == 1 {
            out.copy_from_slice(src);
        } else {
            for (o, v) in out.chunks_exact_mut(s.size()).zip(src.chunks_exact(s.size())) {
                o.copy_from_slice(v);
                o.reverse();
            }
        }
        Ok(())
    }

    fn u32(&mut self) -> Result<usize, DecodeError> {
        let mut b = [0u8; 4];
        self.scalars(Scalar::U32, &mut b)?;
        Ok(u32::from_ne_bytes(b) as usize)
    }

    fn layout(&mut self, layout: &Layout, out: &mut [u8]) -> Result<(), DecodeError> {
        for f in layout.fields {
            let at = &mut out[f.offset..];
            match f.ty {
                FieldType::Scalar(s) => self.scalars(s, &mut at[..s.size()])?,
                FieldType::Array(s, n) => self.scalars(s, &mut at[..s.size() * n])?,
                FieldType::Text(n) => {
                    let len = self.u32()?;
                    let text = self.take(1, len)?;
                    let text = text.strip_suffix(&[0]).unwrap_or(text);
                    if text.len() > n {
                        return err(format!("{}.{}: string of {} bytes exceeds {n}", layout.name, f.name, text.len()));
                    }
                    at[..text.len()].copy_from_slice(text);
                    at[text.len()..n].fill(0);
                }
                FieldType::Struct(l) => self.layout(l, &mut at[..l.size])?,
            }
        }
        Ok(())
    }

    /// Appends the elements of a sequence to `out`.
    fn sequence(&mut self, elem: Elem, out: &mut Vec<u8>) -> Result<(), DecodeError> {
        let n = self.u32()?;
        match elem {
            Elem::Byte => out.extend_from_slice(self.take(1, n)?),
            Elem::Struct(l) => {
                // Each element takes at least one byte of CDR: a count beyond the data is corrupt, not a reason to
                // allocate gigabytes.
                if n > self.data.len() - self.pos.min(self.data.len()) {
                    return err(format!("{}[]: count {n} exceeds the message", l.name));
                }
                let start = out.len();
                out.resize(start + n * l.size, 0);
                for e in out[start..].chunks_exact_mut(l.size) {
                    self.layout(l, e)?;
                }
            }
        }
        Ok(())
    }
}

/// The bytes of a plain-old-data value (a message header or element).
pub fn bytes_of<T: Copy>(value: &T) -> &[u8] {
    // SAFETY: message structs are repr(C) plain old data without pointers; reading their bytes is defined for the
    // initialised fields. Padding bytes are never encoded (encoders read fields at their offsets).
    unsafe { std::slice::from_raw_parts((value as *const T).cast::<u8>(), size_of::<T>()) }
}

/// A plain-old-data value (a header, its leading `Stamp`, an element) read from the start of `bytes`.
///
/// # Panics
/// When `bytes` is shorter than `T` (a caller bug: decoded headers have their full size).
pub fn read_pod<T: Copy>(bytes: &[u8]) -> T {
    assert!(
        bytes.len() >= size_of::<T>(),
        "{} bytes for a {}-byte value",
        bytes.len(),
        size_of::<T>()
    );
    // SAFETY: length checked; message structs are repr(C) plain old data, valid for any bits a publisher wrote.
    unsafe { std::ptr::read_unaligned(bytes.as_ptr().cast::<T>()) }
}

/// The whole elements in `bytes`.
pub fn read_elements<T: Copy>(bytes: &[u8]) -> Vec<T> {
    bytes.chunks_exact(size_of::<T>()).map(read_pod).collect()
}

/// The bytes of a slice of plain-old-data values.
pub fn slice_bytes<T: Copy>(values: &[T]) -> &[u8] {
    // SAFETY: as in `bytes_of`.
    unsafe { std::slice::from_raw_parts(values.as_ptr().cast::<u8>(), std::mem::size_of_val(values)) }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn check_offsets(l: &Layout) {
        let mut end = 0;
        for f in l.fields {
            if let FieldType::Struct(n) = f.ty {
                check_offsets(n);
            }
            let size = f.ty.size();
            assert!(f.offset >= end, "{}.{} overlaps", l.name, f.name);
            end = f.offset + size;
        }
        assert!(
            end <= l.size && l.size - end < 8,
            "{}: fields cover {end} of {} bytes",
            l.name,
            l.size
        );
    }

    #[test]
    fn every_kind_has_a_schema_whose_fields_cover_its_structs() {
        for &kind in MessageKind::ALL {
            let s = kind.schema();
            assert_eq!(s.header.size, kind.header_size(), "{}", kind.name());
            check_offsets(s.header);
            assert!(s.ros2msg().starts_with(&format!("{PACKAGE}/Stamp stamp\n")));
            assert_eq!(MessageSchema::by_name(&s.name()).map(|s| s.kind), Some(kind));
            if let Payload::One(Part { elem: Elem::Struct(l), .. }) = s.payload {
                assert_eq!(l.size, kind.element_size(), "{}", kind.name());
                check_offsets(l);
            }
        }
    }

    #[test]
    fn ros2msg_lists_nested_types_once() {
        let text = MessageKind::Lines2D.schema().ros2msg();
        assert_eq!(text.matches("MSG: lineflow_msgs/Stamp").count(), 1);
        assert!(text.contains("lineflow_msgs/Segment2[] segments\nlineflow_msgs/Pixel[] chain\n"));
        assert!(text.contains("string name\n"));
        assert!(MessageKind::Site.schema().ros2msg().contains("float64[48] corners\n"));
    }

    #[test]
    fn lines2d_round_trips_through_cdr() {
        let segs = [Segment2 {
            id: 3,
            chain_start: 0,
            chain_len: 3,
            reserved: 0,
            start_px: [1.5, 2.0],
            end_px: [9.0, -4.25],
        }];
        let chain = [[1u16, 2], [3, 4], [5, 6]];
        let mut payload = vec![0u8; parts::two_part_len::<Segment2, [u16; 2]>(1, 3)];
        let mut aligned = vec![0u64; payload.len().div_ceil(8)];
        let buf: &mut [u8] = unsafe { std::slice::from_raw_parts_mut(aligned.as_mut_ptr().cast(), payload.len()) };
        parts::write(buf, &segs, &chain);
        payload.copy_from_slice(buf);
        let header = Lines2DHeader {
            stamp: Stamp {
                frame: 4,
                capture_time_ns: 99,
                seq: 4,
                flags: 0,
                revision: 1,
            },
            n_segments: 1,
            n_chain: 3,
            name: fixed_str("IMG_0004.JPG"),
        };
        let mut cdr = Vec::new();
        encode(MessageKind::Lines2D, bytes_of(&header), &payload, &mut cdr);
        let d = decode(MessageKind::Lines2D, &cdr).unwrap();
        assert_eq!(d.payload, payload);
        assert_eq!(d.header.len(), size_of::<Lines2DHeader>());
        let back: Lines2DHeader = read_pod(&d.header);
        assert_eq!(back.stamp, header.stamp);
        assert_eq!(back.name(), "IMG_0004.JPG");
        assert_eq!((back.n_segments, back.n_chain), (1, 3));
        assert_eq!(d.stamp(), header.stamp);
    }

    #[test]
    fn image_cdr_is_the_header_then_the_pixels() {
        let header = ImageHeader {
            width: 3,
            height: 2,
            step: 3,
            name: fixed_str("a.png"),
            ..Default::default()
        };
        let pixels = [1u8, 2, 3, 4, 5, 6];
        let mut cdr = Vec::new();
        encode(MessageKind::Image, bytes_of(&header), &pixels, &mut cdr);
        assert_eq!(&cdr[..4], &[0, 1, 0, 0]);
        assert_eq!(&cdr[cdr.len() - 6..], &pixels);
        assert_eq!(decode(MessageKind::Image, &cdr).unwrap().payload, pixels);
        let mut scratch = Decoded::default();
        let (h, px) = decode_view(MessageKind::Image, &cdr, &mut scratch).unwrap();
        assert_eq!((h.len(), px), (size_of::<ImageHeader>(), &pixels[..]));
        assert!(
            std::ptr::eq(px.as_ptr(), cdr[cdr.len() - 6..].as_ptr()),
            "the pixels are borrowed, not copied"
        );
    }

    #[test]
    fn corrupt_cdr_is_an_error_not_a_panic() {
        let header = PosesHeader::default();
        let poses = [Pose::default(); 3];
        let mut cdr = Vec::new();
        encode(MessageKind::Poses, bytes_of(&header), slice_bytes(&poses), &mut cdr);
        assert_eq!(decode(MessageKind::Poses, &cdr).unwrap().payload.len(), 3 * size_of::<Pose>());
        for cut in [0, 3, 10, cdr.len() - 1] {
            assert!(decode(MessageKind::Poses, &cdr[..cut]).is_err(), "cut at {cut}");
        }
        let mut huge = cdr.clone();
        let at = 4 + 32 + 16; // the count of the poses sequence
        huge[at..at + 4].copy_from_slice(&u32::MAX.to_le_bytes());
        assert!(decode(MessageKind::Poses, &huge).is_err());
        assert!(decode(MessageKind::Poses, &[0, 0, 0, 0]).is_err(), "big-endian CDR is refused");
    }
}
