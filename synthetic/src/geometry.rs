//! Planar faces (parallelograms and triangles), structural edges, and ray-face intersection.
use lineflow_photogrammetry::Vec3;
use serde::Serialize;

/// What a face is made of; selects its texture.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Material {
    /// Façade brick (running bond).
    Brick,
    /// Rendered wall with noise.
    Plaster,
    /// Roof tiles.
    Tiles,
    /// Near-uniform glass: matches at every depth.
    Glass,
    /// Painted aluminium window frames.
    Frame,
    /// Sills, cornice, balcony slab.
    Stone,
    /// Door leaf.
    Wood,
    /// The ground.
    Asphalt,
}

/// A planar parallelogram `origin + a·u + b·v` (a, b in [0, 1]) or triangle (a, b ≥ 0, a + b ≤ 1).
#[derive(Debug, Clone, Serialize)]
pub struct Face {
    /// First corner.
    pub origin: [f64; 3],
    /// First edge vector.
    pub u: [f64; 3],
    /// Second edge vector.
    pub v: [f64; 3],
    /// Triangle instead of parallelogram.
    pub triangle: bool,
    /// Texture.
    pub material: Material,
    /// Faces of one continuous surface share this id (edges between them are not edges in the image).
    pub surface: u32,
}

/// A face prepared for fast intersection.
#[derive(Debug, Clone)]
pub(crate) struct Prepared {
    pub(crate) origin: Vec3,
    pub(crate) normal: Vec3,
    pub(crate) offset: f64,
    /// Dual basis: `a = (p − origin)·du`, `b = (p − origin)·dv`.
    pub(crate) du: Vec3,
    pub(crate) dv: Vec3,
    pub(crate) triangle: bool,
    pub(crate) material: Material,
    pub(crate) surface: u32,
    /// Texture axes in the face plane (metres).
    pub(crate) tex_s: Vec3,
    pub(crate) tex_t: Vec3,
    pub(crate) lo: Vec3,
    pub(crate) hi: Vec3,
}

impl Face {
    /// The corners of the face.
    pub fn corners(&self) -> Vec<Vec3> {
        let o = Vec3::from(self.origin);
        let (u, v) = (Vec3::from(self.u), Vec3::from(self.v));
        if self.triangle {
            vec![o, o + u, o + v]
        } else {
            vec![o, o + u, o + u + v, o + v]
        }
    }

    /// Precomputes the plane, the dual basis and the bounds.
    pub(crate) fn prepare(&self) -> Prepared {
        let o = Vec3::from(self.origin);
        let (u, v) = (Vec3::from(self.u), Vec3::from(self.v));
        let normal = u.cross(&v).normalize();
        let (uu, uv, vv) = (u.dot(&u), u.dot(&v), v.dot(&v));
        let det = uu * vv - uv * uv;
        let du = (u * vv - v * uv) / det;
        let dv = (v * uu - u * uv) / det;
        let tex_s = u.normalize();
        let tex_t = normal.cross(&tex_s);
        let corners = self.corners();
        let lo = corners.iter().fold(Vec3::repeat(f64::INFINITY), |a, c| a.inf(c));
        let hi = corners.iter().fold(Vec3::repeat(f64::NEG_INFINITY), |a, c| a.sup(c));
        Prepared {
            origin: o,
            normal,
            offset: normal.dot(&o),
            du,
            dv,
            triangle: self.triangle,
            material: self.material,
            surface: self.surface,
            tex_s,
            tex_t,
            lo,
            hi,
        }
    }
}

impl Prepared {
    /// Distance along the ray to the face, if hit within (t_min, t_max).
    #[inline]
    pub fn intersect(&self, origin: &Vec3, dir: &Vec3, t_min: f64, t_max: f64) -> Option<f64> {
        let denom = self.normal.dot(dir);
        if denom.abs() < 1e-12 {
            return None;
        }
        let t = (self.offset - self.normal.dot(origin)) / denom;
        if !(t > t_min && t < t_max) {
            return None;
        }
        let rel = origin + dir * t - self.origin;
        let a = rel.dot(&self.du);
        let b = rel.dot(&self.dv);
        let inside = if self.triangle {
            a >= 0.0 && b >= 0.0 && a + b <= 1.0
        } else {
            (0.0..=1.0).contains(&a) && (0.0..=1.0).contains(&b)
        };
        inside.then_some(t)
    }
}

/// A structural edge of the model: where two faces meet at an angle, or a face ends.
#[derive(Debug, Clone, Serialize)]
pub struct Edge {
    /// First endpoint.
    pub a: [f64; 3],
    /// Second endpoint.
    pub b: [f64; 3],
    /// What the edge belongs to (for reports: outline, opening, frame, sill, ...).
    pub kind: &'static str,
}

impl Edge {
    /// Length in metres.
    pub fn length(&self) -> f64 {
        (Vec3::from(self.b) - Vec3::from(self.a)).norm()
    }
}
