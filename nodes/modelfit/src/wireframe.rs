//! Fitting a whole wire-frame by its free vertices. The vertices of different connected components share no
//! observation (a pixel lies on one edge), so each component is an independent adjustment: a façade's wall
//! outline and each opening are solved as small dense systems instead of one large one.
use std::borrow::Borrow;

use rayon::prelude::*;

use crate::fit::{fit, FitParams};
use crate::observations::ImageEdges;
use crate::parametric::{DepthPrior, FacePlane, FreeVertices};
use lineflow_photogrammetry::Vec3;

/// A free vertex is held near its start with this σ when the settings give none: weak against the pixels
/// (thousands of them at a fraction of a pixel each), but it fixes a vertex whose edges see no pixel.
pub const DEFAULT_PRIOR_M: f64 = 0.01;
/// σ of a free vertex along the mean viewing direction when the settings give none, m.
pub const DEFAULT_DEPTH_PRIOR_M: f64 = 0.003;
/// Pixels an edge needs, over all images, to count as fitted.
pub const MIN_EDGE_PIXELS: usize = 10;

/// Settings for a façade wire-frame seen by a camera of `pixel_mm` pixels. The seed's buffer (0.4 → 0.05 mm)
/// is 16 → 2 pixels of its aerial camera, where the initial model may be metres off; a façade model built from
/// 3-D lines is a pixel or two off, and frames, reveals and sills lie a few pixels apart, so the buffer starts
/// at 3 pixels and shrinks by half a pixel to 2.
pub fn facade_params(pixel_mm: f64) -> FitParams {
    FitParams {
        buffer_start_mm: 3.0 * pixel_mm,
        buffer_step_mm: 0.5 * pixel_mm,
        buffer_min_mm: 2.0 * pixel_mm,
        prior_sigma: DEFAULT_PRIOR_M,
        prior_depth_sigma: DEFAULT_DEPTH_PRIOR_M,
        max_pixels_per_line: 25,
        freeze_at_final: true,
        ..FitParams::default()
    }
}

/// The fitted wire-frame.
#[derive(Debug, Clone, Default)]
pub struct WireframeFit {
    /// Vertex positions (the input position where a vertex could not be fitted).
    pub vertices: Vec<Vec3>,
    /// Standard deviations of the coordinates of fitted vertices.
    pub sigmas: Vec<Option<Vec3>>,
    /// Whether the images pin the vertex: two of its edges (or its only one) saw enough pixels.
    pub fitted: Vec<bool>,
    /// Connected components, and how many of them failed (left as they were).
    pub components: usize,
    /// Components whose fit failed.
    pub failed: usize,
    /// Pixels used at the end, all images.
    pub pixels: usize,
    /// RMS of the final pixel-to-line distances, photo mm: each component's weighted RMS, pooled by its pixel
    /// count.
    pub residual_rms_mm: f64,
    /// Failure messages of the failed components.
    pub failures: Vec<String>,
    /// Iterations summed over the components.
    pub iterations: usize,
}

impl WireframeFit {
    /// One line for logs: fitted vertices, components, residual.
    pub fn summary(&self, pixel_mm: f64) -> String {
        format!(
            "{}/{} vertices fitted in {} components ({} failed, {:.1} iterations each), {} edge pixels, residual {:.2} px",
            self.fitted.iter().filter(|&&f| f).count(),
            self.vertices.len(),
            self.components,
            self.failed,
            self.iterations as f64 / self.components.max(1) as f64,
            self.pixels,
            self.residual_rms_mm / pixel_mm
        )
    }
}

fn components(n: usize, edges: &[[usize; 2]]) -> Vec<Vec<usize>> {
    let mut parent: Vec<usize> = (0..n).collect();
    fn root(parent: &mut [usize], mut i: usize) -> usize {
        while parent[i] != i {
            parent[i] = parent[parent[i]];
            i = parent[i];
        }
        i
    }
    for e in edges {
        let (a, b) = (root(&mut parent, e[0]), root(&mut parent, e[1]));
        if a != b {
            parent[a.max(b)] = a.min(b);
        }
    }
    let mut groups: Vec<Vec<usize>> = Vec::new();
    let mut slot = vec![usize::MAX; n];
    for v in 0..n {
        let r = root(&mut parent, v);
        if slot[r] == usize::MAX {
            slot[r] = groups.len();
            groups.push(Vec::new());
        }
        groups[slot[r]].push(v);
    }
    groups
}

/// Fits the free vertices of a wire-frame to the edge pixels of `images`. Faces are used for self-occlusion;
/// edges must name existing vertices (checked by the callers that read user files).
pub fn fit_wireframe<I: Borrow<ImageEdges> + Sync>(
    vertices: &[Vec3],
    edges: &[[usize; 2]],
    faces: &[FacePlane],
    images: &[I],
    params: &FitParams,
) -> WireframeFit {
    let lateral = if params.prior_sigma > 0.0 {
        params.prior_sigma
    } else {
        DEFAULT_PRIOR_M
    };
    let depth = if params.prior_depth_sigma > 0.0 {
        params.prior_depth_sigma
    } else {
        DEFAULT_DEPTH_PRIOR_M
    };
    let axis = images.iter().map(|i| i.borrow().pose.axis()).sum::<Vec3>();
    let prior = DepthPrior {
        axis: if axis.norm() > 0.0 { axis.normalize() } else { Vec3::z() },
        lateral_m: lateral,
        depth_m: depth,
    };
    let groups: Vec<Vec<usize>> = components(vertices.len(), edges).into_iter().filter(|g| g.len() > 1).collect();
    let mut local = vec![usize::MAX; vertices.len()];
    for g in &groups {
        for (i, &v) in g.iter().enumerate() {
            local[v] = i;
        }
    }
    let mut group_of = vec![usize::MAX; vertices.len()];
    for (k, g) in groups.iter().enumerate() {
        for &v in g {
            group_of[v] = k;
        }
    }
    let results: Vec<_> = groups
        .par_iter()
        .enumerate()
        .map(|(k, g)| {
            let sub_edges: Vec<[usize; 2]> = edges
                .iter()
                .filter(|e| group_of[e[0]] == k)
                .map(|e| [local[e[0]], local[e[1]]])
                .collect();
            let sub_faces: Vec<FacePlane> = faces
                .iter()
                .filter(|f| f.ring.iter().all(|&v| group_of[v] == k))
                .map(|f| FacePlane {
                    ring: f.ring.iter().map(|&v| local[v]).collect(),
                    normal: f.normal,
                })
                .collect();
            let start = FreeVertices::pack(&g.iter().map(|&v| vertices[v]).collect::<Vec<_>>());
            let model = FreeVertices::new(sub_edges, sub_faces).with_prior(prior);
            let f = fit(&model, &start, images, params);
            (f, model)
        })
        .collect();
    let mut out = WireframeFit {
        vertices: vertices.to_vec(),
        sigmas: vec![None; vertices.len()],
        fitted: vec![false; vertices.len()],
        components: groups.len(),
        ..WireframeFit::default()
    };
    let (mut sum_wdd, mut pixels) = (0.0, 0usize);
    for (g, (f, model)) in groups.iter().zip(&results) {
        out.iterations += f.iterations.len();
        if let Some(why) = &f.failure {
            out.failed += 1;
            out.failures.push(why.clone());
            continue;
        }
        // A vertex is pinned by the images when two of its edges (or its only edge) saw enough pixels.
        let mut seen = vec![0usize; g.len()];
        let mut degree = vec![0usize; g.len()];
        for (e, &count) in crate::parametric::Parametric::edges(model).iter().zip(&f.edge_pixels) {
            for v in [e[0], e[1]] {
                degree[v] += 1;
                seen[v] += usize::from(count >= MIN_EDGE_PIXELS);
            }
            pixels += count;
        }
        let ok: Vec<bool> = seen.iter().zip(&degree).map(|(&s, &d)| s >= d.min(2)).collect();
        let used: usize = f.edge_pixels.iter().sum();
        if used > 0 {
            sum_wdd += f.residual_rms_mm.powi(2) * used as f64;
        }
        for (i, &v) in g.iter().enumerate() {
            out.vertices[v] = Vec3::new(f.params[3 * i], f.params[3 * i + 1], f.params[3 * i + 2]);
            out.fitted[v] = ok[i];
            if ok[i] && f.sigmas.len() == f.params.len() {
                out.sigmas[v] = Some(Vec3::new(f.sigmas[3 * i], f.sigmas[3 * i + 1], f.sigmas[3 * i + 2]));
            }
        }
    }
    out.pixels = pixels;
    out.residual_rms_mm = if pixels > 0 { (sum_wdd / pixels as f64).sqrt() } else { f64::NAN };
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn components_split_at_disconnected_parts() {
        let g = components(7, &[[0, 1], [1, 2], [4, 5], [6, 5]]);
        assert_eq!(g, vec![vec![0, 1, 2], vec![3], vec![4, 5, 6]]);
    }
}
