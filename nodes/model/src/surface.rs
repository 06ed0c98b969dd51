//! What a face of the wire-frame is (its ring, normal and semantic kind) and the planar geometry that face
//! finding, opening inference and occlusion all measure with: planes, a 2-D frame in a plane, and the size of a
//! set of vertices in it.
use lineflow_photogrammetry::Vec3;

use crate::Vertex;

/// The CityJSON semantic surface of a face.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord)]
pub enum SurfaceKind {
    Wall,
    Roof,
    Ground,
    Floor,
    Window,
    Door,
}

impl SurfaceKind {
    /// Every kind, in the order of their codes in `FaceVertex.kind`.
    pub const ALL: [SurfaceKind; 6] = [
        SurfaceKind::Wall,
        SurfaceKind::Roof,
        SurfaceKind::Ground,
        SurfaceKind::Floor,
        SurfaceKind::Window,
        SurfaceKind::Door,
    ];

    /// The code of the kind in a `ModelFaces` message.
    pub fn code(self) -> u32 {
        Self::ALL.iter().position(|&k| k == self).unwrap_or(0) as u32
    }

    /// The kind of a code; `None` for an unknown one.
    pub fn from_code(code: u32) -> Option<SurfaceKind> {
        Self::ALL.get(code as usize).copied()
    }

    /// The CityJSON 2.0 semantic surface type.
    pub fn cityjson(self) -> &'static str {
        match self {
            SurfaceKind::Wall => "WallSurface",
            SurfaceKind::Roof => "RoofSurface",
            SurfaceKind::Ground => "GroundSurface",
            SurfaceKind::Floor => "OuterFloorSurface",
            SurfaceKind::Window => "Window",
            SurfaceKind::Door => "Door",
        }
    }
}

/// A planar face: its outer ring (vertex indices, counter-clockwise seen from outside), the rings of its openings,
/// its unit outward normal and its kind.
#[derive(Debug, Clone, PartialEq)]
pub struct Face {
    pub ring: Vec<usize>,
    pub holes: Vec<Vec<usize>>,
    pub normal: Vec3,
    pub kind: SurfaceKind,
}

/// A plane n · x = offset, n a unit normal.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Plane {
    pub normal: Vec3,
    pub offset: f64,
}

/// A 2-D frame in a plane: u, v with u × v = normal.
pub(crate) fn plane_basis(normal: Vec3) -> (Vec3, Vec3) {
    let helper = if normal.z.abs() < 0.9 { Vec3::z() } else { Vec3::x() };
    let u = helper.cross(&normal).normalize();
    (u, normal.cross(&u))
}

/// The smaller side of the bounding rectangle of the vertices `points` in the plane of `normal`.
pub(crate) fn smaller_side(vertices: &[Vertex], points: &[usize], normal: Vec3) -> f64 {
    let (u, v) = plane_basis(normal);
    let span = |axis: &Vec3| {
        let t = points.iter().map(|&k| vertices[k].point.dot(axis));
        t.clone().fold(f64::NEG_INFINITY, f64::max) - t.fold(f64::INFINITY, f64::min)
    };
    span(&u).min(span(&v))
}
