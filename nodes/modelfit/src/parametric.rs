//! What the fitting adjusts: a parametric primitive (the seed's box) or the free vertices of a wire-frame.
use lineflow_photogrammetry::Vec3;

/// A face for self-occlusion: its vertex ring and outward normal.
#[derive(Debug, Clone, PartialEq)]
pub struct FacePlane {
    /// Vertex indices around the face.
    pub ring: Vec<usize>,
    /// Outward unit normal.
    pub normal: Vec3,
}

/// A wire-frame whose vertices are functions of a parameter vector.
pub trait Parametric: Sync {
    /// Number of parameters.
    fn n_params(&self) -> usize;
    /// Parameter names, for logs and reports.
    fn param_name(&self, k: usize) -> String;
    /// Vertex positions for parameters `p`.
    fn vertices(&self, p: &[f64]) -> Vec<Vec3>;
    /// The model lines as vertex pairs.
    fn edges(&self) -> &[[usize; 2]];
    /// Faces for back-face culling at parameters `p`; an edge on no face counts as visible.
    fn faces(&self, p: &[f64]) -> Vec<FacePlane>;
    /// For each vertex, the parameters it depends on and ∂V/∂p.
    fn vertex_jacobians(&self, p: &[f64]) -> Vec<Vec<(usize, Vec3)>>;
    /// Why `p` is not a valid model (e.g. a non-positive length), if it is not.
    fn invalid(&self, p: &[f64]) -> Option<String>;
    /// The change below which parameter `k` counts as settled.
    fn tolerance(&self, k: usize) -> f64;
    /// Prior precision (m⁻²) of each 3-parameter block (a free vertex) toward its start, if the model has one;
    /// otherwise the scalar `prior_sigma` of the settings applies.
    fn prior_blocks(&self) -> Option<Vec<nalgebra::Matrix3<f64>>> {
        None
    }
}

/// The faces of a model at some parameters with the edges around each, for self-occlusion tests from many
/// viewpoints: built once per set of parameters, not once per image.
pub struct FaceEdges {
    faces: Vec<FacePlane>,
    /// Edge indices around each face.
    edges_of: Vec<Vec<usize>>,
    on_face: Vec<bool>,
}

impl FaceEdges {
    /// The faces of `model` at `p` and their edges.
    pub fn new(model: &dyn Parametric, p: &[f64]) -> Self {
        let edges = model.edges();
        let index: std::collections::HashMap<(usize, usize), usize> = edges
            .iter()
            .enumerate()
            .map(|(k, e)| ((e[0].min(e[1]), e[0].max(e[1])), k))
            .collect();
        let faces = model.faces(p);
        let mut on_face = vec![false; edges.len()];
        let edges_of = faces
            .iter()
            .map(|f| {
                let n = f.ring.len();
                (0..n)
                    .filter_map(|i| {
                        let (a, b) = (f.ring[i], f.ring[(i + 1) % n]);
                        index.get(&(a.min(b), a.max(b))).copied()
                    })
                    .inspect(|&k| on_face[k] = true)
                    .collect()
            })
            .collect();
        Self { faces, edges_of, on_face }
    }

    /// Which edges are seen from `eye` (vertices at `vertices`): those with a front-facing adjacent face, or on
    /// no face at all (self-occlusion only, as the seed models it).
    pub fn visible(&self, vertices: &[Vec3], eye: &Vec3) -> Vec<bool> {
        let mut seen: Vec<bool> = self.on_face.iter().map(|&on| !on).collect();
        for (f, edges) in self.faces.iter().zip(&self.edges_of) {
            if f.normal.dot(&(eye - vertices[f.ring[0]])) > 0.0 {
                for &k in edges {
                    seen[k] = true;
                }
            }
        }
        seen
    }
}

/// [`FaceEdges::visible`] for one viewpoint.
pub fn visible_edges(model: &dyn Parametric, p: &[f64], vertices: &[Vec3], eye: &Vec3) -> Vec<bool> {
    FaceEdges::new(model, p).visible(vertices, eye)
}

/// The seed's box: pose (dX, dY, dZ, θ) and shape (L, W, h). Model space has its origin at a base corner:
/// V = R_z(θ)·V_m + (dX, dY, dZ), V_m ∈ {0, L} × {0, W} × {0, h}; vertex i has x = bit 0, y = bit 1, z = bit 2.
#[derive(Debug, Clone, Copy, Default)]
pub struct BoxModel;

/// Indices of the box parameters.
pub mod box_param {
    /// Base corner easting, m.
    pub const DX: usize = 0;
    /// Base corner northing, m.
    pub const DY: usize = 1;
    /// Base elevation, m.
    pub const DZ: usize = 2;
    /// Rotation about the vertical, rad.
    pub const THETA: usize = 3;
    /// Length along the rotated x axis, m.
    pub const L: usize = 4;
    /// Width along the rotated y axis, m.
    pub const W: usize = 5;
    /// Height, m.
    pub const H: usize = 6;
    /// Names in order.
    pub const NAMES: [&str; 7] = ["dX", "dY", "dZ", "theta", "L", "W", "h"];
}

const BOX_EDGES: [[usize; 2]; 12] = [
    [0, 1],
    [2, 3],
    [4, 5],
    [6, 7],
    [0, 2],
    [1, 3],
    [4, 6],
    [5, 7],
    [0, 4],
    [1, 5],
    [2, 6],
    [3, 7],
];

impl BoxModel {
    fn local(p: &[f64], i: usize) -> Vec3 {
        Vec3::new(
            if i & 1 != 0 { p[box_param::L] } else { 0.0 },
            if i & 2 != 0 { p[box_param::W] } else { 0.0 },
            if i & 4 != 0 { p[box_param::H] } else { 0.0 },
        )
    }
}

impl Parametric for BoxModel {
    fn n_params(&self) -> usize {
        7
    }

    fn param_name(&self, k: usize) -> String {
        box_param::NAMES[k].to_string()
    }

    fn vertices(&self, p: &[f64]) -> Vec<Vec3> {
        let (s, c) = p[box_param::THETA].sin_cos();
        let d = Vec3::new(p[box_param::DX], p[box_param::DY], p[box_param::DZ]);
        (0..8)
            .map(|i| {
                let m = Self::local(p, i);
                d + Vec3::new(c * m.x - s * m.y, s * m.x + c * m.y, m.z)
            })
            .collect()
    }

    fn edges(&self) -> &[[usize; 2]] {
        &BOX_EDGES
    }

    fn faces(&self, p: &[f64]) -> Vec<FacePlane> {
        let (s, c) = p[box_param::THETA].sin_cos();
        let (ex, ey) = (Vec3::new(c, s, 0.0), Vec3::new(-s, c, 0.0));
        let face = |ring: [usize; 4], normal: Vec3| FacePlane {
            ring: ring.to_vec(),
            normal,
        };
        vec![
            face([0, 2, 6, 4], -ex),
            face([1, 3, 7, 5], ex),
            face([0, 1, 5, 4], -ey),
            face([2, 3, 7, 6], ey),
            face([0, 1, 3, 2], -Vec3::z()),
            face([4, 5, 7, 6], Vec3::z()),
        ]
    }

    fn vertex_jacobians(&self, p: &[f64]) -> Vec<Vec<(usize, Vec3)>> {
        use box_param::*;
        let (s, c) = p[THETA].sin_cos();
        (0..8)
            .map(|i| {
                let m = Self::local(p, i);
                let mut j = vec![
                    (DX, Vec3::x()),
                    (DY, Vec3::y()),
                    (DZ, Vec3::z()),
                    (THETA, Vec3::new(-s * m.x - c * m.y, c * m.x - s * m.y, 0.0)),
                ];
                if i & 1 != 0 {
                    j.push((L, Vec3::new(c, s, 0.0)));
                }
                if i & 2 != 0 {
                    j.push((W, Vec3::new(-s, c, 0.0)));
                }
                if i & 4 != 0 {
                    j.push((H, Vec3::z()));
                }
                j
            })
            .collect()
    }

    fn invalid(&self, p: &[f64]) -> Option<String> {
        use box_param::*;
        [L, W, H]
            .into_iter()
            .find(|&k| p[k].is_nan() || p[k] <= 0.0)
            .map(|k| format!("{} became {:.3} m", NAMES[k], p[k]))
    }

    fn tolerance(&self, k: usize) -> f64 {
        if k == box_param::THETA {
            0.001f64.to_radians()
        } else {
            0.001
        }
    }
}

/// A wire-frame whose vertices move freely: three coordinates per vertex.
#[derive(Debug, Clone)]
pub struct FreeVertices {
    edges: Vec<[usize; 2]>,
    faces: Vec<FacePlane>,
    prior: Option<DepthPrior>,
}

/// Keeps vertices near their start, tighter along the viewing direction: from a strip of photos the depth of an
/// edge is seen through a small parallax, so a tenth of a pixel of edge bias would move it by several pixels.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DepthPrior {
    /// Unit viewing direction (e.g. the mean camera axis).
    pub axis: Vec3,
    /// σ across the viewing direction, m.
    pub lateral_m: f64,
    /// σ along it, m.
    pub depth_m: f64,
}

impl DepthPrior {
    /// The 3×3 precision matrix, m⁻².
    pub fn precision(&self) -> nalgebra::Matrix3<f64> {
        let a = self.axis.normalize();
        let aat = a * a.transpose();
        (nalgebra::Matrix3::identity() - aat) / self.lateral_m.powi(2) + aat / self.depth_m.powi(2)
    }
}

impl FreeVertices {
    /// The wire-frame of `edges` over vertices packed as parameters (x, y, z per vertex); `faces` for culling.
    pub fn new(edges: Vec<[usize; 2]>, faces: Vec<FacePlane>) -> Self {
        Self { edges, faces, prior: None }
    }

    /// The same wire-frame with an anisotropic prior on every vertex.
    pub fn with_prior(mut self, prior: DepthPrior) -> Self {
        self.prior = Some(prior);
        self
    }

    /// Vertices as a parameter vector.
    pub fn pack(vertices: &[Vec3]) -> Vec<f64> {
        vertices.iter().flat_map(|v| [v.x, v.y, v.z]).collect()
    }
}

impl Parametric for FreeVertices {
    fn n_params(&self) -> usize {
        // The highest vertex any edge or face names decides the size; callers pack exactly that many.
        3 * self
            .edges
            .iter()
            .flatten()
            .chain(self.faces.iter().flat_map(|f| f.ring.iter()))
            .max()
            .map_or(0, |m| m + 1)
    }

    fn param_name(&self, k: usize) -> String {
        format!("v{}.{}", k / 3, ["x", "y", "z"][k % 3])
    }

    fn vertices(&self, p: &[f64]) -> Vec<Vec3> {
        p.chunks_exact(3).map(|c| Vec3::new(c[0], c[1], c[2])).collect()
    }

    fn edges(&self) -> &[[usize; 2]] {
        &self.edges
    }

    fn faces(&self, _: &[f64]) -> Vec<FacePlane> {
        self.faces.clone()
    }

    fn vertex_jacobians(&self, p: &[f64]) -> Vec<Vec<(usize, Vec3)>> {
        (0..p.len() / 3)
            .map(|v| vec![(3 * v, Vec3::x()), (3 * v + 1, Vec3::y()), (3 * v + 2, Vec3::z())])
            .collect()
    }

    fn invalid(&self, p: &[f64]) -> Option<String> {
        p.iter().any(|v| !v.is_finite()).then(|| "a vertex became non-finite".to_string())
    }

    fn tolerance(&self, _: usize) -> f64 {
        // Free vertices are façade-scale: half a millimetre is a tenth of a pixel at 10-20 m.
        5e-4
    }

    fn prior_blocks(&self) -> Option<Vec<nalgebra::Matrix3<f64>>> {
        let p = self.prior?.precision();
        Some(vec![p; self.n_params() / 3])
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn box_jacobians_match_central_differences() {
        let p = [10.0, -4.0, 1.5, 0.4, 22.0, 13.0, 17.0];
        let m = BoxModel;
        let jac = m.vertex_jacobians(&p);
        for k in 0..7 {
            let (mut a, mut b) = (p, p);
            a[k] += 1e-6;
            b[k] -= 1e-6;
            let (va, vb) = (m.vertices(&a), m.vertices(&b));
            for v in 0..8 {
                let numeric = (va[v] - vb[v]) / 2e-6;
                let analytic = jac[v].iter().find(|(j, _)| *j == k).map_or(Vec3::zeros(), |(_, d)| *d);
                assert!((numeric - analytic).norm() < 1e-6, "vertex {v} param {k}");
            }
        }
    }

    #[test]
    fn box_faces_point_outwards() {
        let p = [3.0, 2.0, 0.0, 0.7, 20.0, 10.0, 8.0];
        let m = BoxModel;
        let v = m.vertices(&p);
        let centre = v.iter().sum::<Vec3>() / 8.0;
        for f in m.faces(&p) {
            let c = f.ring.iter().map(|&i| v[i]).sum::<Vec3>() / 4.0;
            assert!((c - centre).normalize().dot(&f.normal) > 0.5);
            for &i in &f.ring {
                assert!((v[i] - c).dot(&f.normal).abs() < 1e-9, "planar");
            }
        }
        assert!(m.invalid(&p).is_none());
        assert!(m.invalid(&[0.0, 0.0, 0.0, 0.0, 1.0, -1.0, 1.0]).is_some());
    }
}
