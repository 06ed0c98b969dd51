//! `Wireframe`: the building model.
use iceoryx2::prelude::ZeroCopySend;

use crate::Stamp;

/// Header of a `Wireframe` message. Two-part byte payload: `[[f64; 3]; n_vertices]` in metres, then
/// `[WireEdge; n_edges]`.
#[derive(Debug, Default, Clone, Copy, ZeroCopySend)]
#[repr(C)]
#[type_name("lineflow/Wireframe/v1")]
pub struct WireframeHeader {
    /// Common stamp; `stamp.revision` counts refinements.
    pub stamp: Stamp,
    /// Number of vertices.
    pub n_vertices: u32,
    /// Number of edges.
    pub n_edges: u32,
}

/// An edge between two vertices.
#[derive(Debug, Default, Clone, Copy, PartialEq, Eq, ZeroCopySend)]
#[repr(C)]
#[type_name("lineflow/WireEdge/v2")]
pub struct WireEdge {
    /// First vertex index.
    pub a: u32,
    /// Second vertex index.
    pub b: u32,
    /// Face the edge bounds (index into the model's faces, u32::MAX when none).
    pub face: u32,
    /// 0 wall, 1 roof, 2 opening, 3 ground.
    pub kind: u32,
    /// 1 when the edge was not observed but completed behind an occluder (hidden from the cameras), else 0.
    pub hidden: u32,
}

/// Header of a `ModelFaces` message: the faces of the wire-frame published with the same stamp, as rings of its
/// vertex indices (the edges alone cannot tell them: an edge bounds two faces).
#[derive(Debug, Default, Clone, Copy, ZeroCopySend)]
#[repr(C)]
#[type_name("lineflow/ModelFaces/v1")]
pub struct ModelFacesHeader {
    /// The stamp of the wire-frame these faces belong to.
    pub stamp: Stamp,
    /// Number of faces.
    pub n_faces: u32,
    /// Zero.
    pub reserved: u32,
}

/// One vertex of a face's boundary; a face's vertices come ring by ring, each ring in order.
#[derive(Debug, Default, Clone, Copy, PartialEq, Eq, ZeroCopySend)]
#[repr(C)]
#[type_name("lineflow/FaceVertex/v1")]
pub struct FaceVertex {
    /// Face index.
    pub face: u32,
    /// 0 for the outer ring, k for the face's k-th hole.
    pub ring: u32,
    /// Surface kind: 0 wall, 1 roof, 2 ground, 3 floor, 4 window, 5 door.
    pub kind: u32,
    /// Vertex index into the wire-frame.
    pub vertex: u32,
}

impl FaceVertex {
    /// `kind` of a window face.
    pub const KIND_WINDOW: u32 = 4;
    /// `kind` of a door face.
    pub const KIND_DOOR: u32 = 5;
}
