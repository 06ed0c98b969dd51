//! The least-squares model-image fitting loop (seed 004 §2.4–2.5): project, collect the edge pixels in a
//! shrinking buffer around each visible projected line, weight them, and adjust the parameters by Gauss-Newton
//! on the perpendicular pixel-to-line distances over every image at once.
use std::borrow::Borrow;

use nalgebra::{DMatrix, DVector};
use rayon::prelude::*;
use serde::Deserialize;

use crate::observations::ImageEdges;
use crate::parametric::{FaceEdges, Parametric};
use crate::sparse::SparseSym;
use crate::weights::Weighting;
use lineflow_photogrammetry::Vec3;

/// Settings of the fitting; the defaults are the seed's.
#[derive(Debug, Clone, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct FitParams {
    /// Edge-pixel weighting.
    pub weighting: Weighting,
    /// First buffer half-width, mm in the photo.
    pub buffer_start_mm: f64,
    /// Shrink per iteration, mm.
    pub buffer_step_mm: f64,
    /// Final buffer half-width, mm.
    pub buffer_min_mm: f64,
    /// The combined scheme keeps pixels whose gradient is within this angle of the line's normal, degrees.
    pub angle_gate_deg: f64,
    /// Iterations at most.
    pub max_iterations: usize,
    /// Pseudo-observations keeping each parameter near its start, standard deviation (metres or radians);
    /// 0 = none. Free vertices need it where an edge has no pixels; a box does not.
    pub prior_sigma: f64,
    /// Free vertices only: σ of the prior along the mean viewing direction, m (0: the same as `prior_sigma`).
    pub prior_depth_sigma: f64,
    /// At most this many pixels per projected line and image, evenly spread (0: all). A façade edge of 2,000
    /// pixels seen in ten images says little more with all of them than with a tenth.
    pub max_pixels_per_line: usize,
    /// Keep the pixels' assignment to lines once the buffer is final (the seed re-selects every iteration).
    pub freeze_at_final: bool,
    /// Parameters known from another source (seed §2.6: a height from a map when the bottom edges are hidden).
    pub constraints: Vec<Constraint>,
}

/// A weighted pseudo-observation p_k = value.
#[derive(Debug, Clone, Copy, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Constraint {
    /// Parameter index.
    pub param: usize,
    /// Known value.
    pub value: f64,
    /// Its standard deviation (metres or radians).
    pub sigma: f64,
}

impl Default for FitParams {
    fn default() -> Self {
        Self {
            weighting: Weighting::Combined,
            buffer_start_mm: 0.4,
            buffer_step_mm: 0.05,
            buffer_min_mm: 0.05,
            angle_gate_deg: 30.0,
            max_iterations: 30,
            prior_sigma: 0.0,
            prior_depth_sigma: 0.0,
            max_pixels_per_line: 0,
            freeze_at_final: false,
            constraints: Vec::new(),
        }
    }
}

impl FitParams {
    /// The buffer half-width at iteration `it` (0-based): start, shrinking by the step, then constant (fact C4).
    pub fn buffer_mm(&self, it: usize) -> f64 {
        (self.buffer_start_mm - self.buffer_step_mm * it as f64).max(self.buffer_min_mm)
    }

    /// The first iteration at the final buffer.
    fn final_buffer_from(&self) -> usize {
        if self.buffer_step_mm <= 0.0 {
            return 0;
        }
        ((self.buffer_start_mm - self.buffer_min_mm) / self.buffer_step_mm - 1e-9)
            .ceil()
            .max(0.0) as usize
    }
}

impl lineflow_runtime::StageParams for FitParams {
    fn validate(&self) -> Result<(), lineflow_runtime::ParamError> {
        use lineflow_runtime::params::{at_least, check, in_closed, non_negative, positive};
        positive("buffer_min_mm", self.buffer_min_mm)?;
        let (start, min) = (self.buffer_start_mm, self.buffer_min_mm);
        check(
            start.is_finite() && start >= min,
            "buffer_start_mm",
            &format!(">= buffer_min_mm ({min})"),
            start,
        )?;
        non_negative("buffer_step_mm", self.buffer_step_mm)?;
        for c in &self.constraints {
            positive(&format!("sigma of the constraint on parameter {}", c.param), c.sigma)?;
            check(
                c.value.is_finite(),
                &format!("value of the constraint on parameter {}", c.param),
                "finite",
                c.value,
            )?;
        }
        in_closed("angle_gate_deg", self.angle_gate_deg, 0.0, 90.0)?;
        at_least("max_iterations", self.max_iterations, 1)?;
        non_negative("prior_sigma", self.prior_sigma)?;
        non_negative("prior_depth_sigma", self.prior_depth_sigma)
    }
}

/// One iteration's record.
#[derive(Debug, Clone, PartialEq)]
pub struct Iteration {
    /// Buffer half-width, mm.
    pub buffer_mm: f64,
    /// Edge pixels used (non-zero weight).
    pub pixels: usize,
    /// Largest parameter change relative to its tolerance.
    pub step_ratio: f64,
}

/// The outcome of one fit.
#[derive(Debug, Clone)]
pub struct Fit {
    /// Adjusted parameters (the start where the fit failed).
    pub params: Vec<f64>,
    /// Standard deviation of every parameter, σ̂0²(JᵀΩJ)⁻¹; empty where the fit failed.
    pub sigmas: Vec<f64>,
    /// σ̂0 of unit weight, photo mm.
    pub sigma0_mm: f64,
    /// Weighted RMS of the final pixel-to-line distances, photo mm.
    pub residual_rms_mm: f64,
    /// Whether the changes fell below the tolerances at the final buffer.
    pub converged: bool,
    /// Why the fit failed, if it did.
    pub failure: Option<String>,
    /// Pixels used per model edge at the end, summed over images.
    pub edge_pixels: Vec<usize>,
    /// The iteration log.
    pub iterations: Vec<Iteration>,
}

impl Fit {
    /// Whether the fit ended with a model (converged or at least not failed).
    pub fn ok(&self) -> bool {
        self.failure.is_none()
    }
}

/// A projected model line in one image.
struct Projected {
    edge: usize,
    p: [f64; 2],
    q: [f64; 2],
}

/// One pixel's observation row: the signed distance, its weight and ∂d/∂p as sparse entries.
struct Row {
    d: f64,
    w: f64,
    edge: usize,
    /// The pixel's index in its image.
    obs: u32,
    grad: Vec<(usize, f64)>,
}

/// An ideal photo point and its 2×3 Jacobian with respect to the object point.
type Projection = ([f64; 2], [[f64; 3]; 2]);

/// The projection of `x` into `img`, if it is in front of the camera.
fn project_with_jacobian(img: &ImageEdges, x: &Vec3) -> Option<Projection> {
    let m = &img.pose.rotation;
    let uvw = m * (x - img.pose.center);
    if uvw.z >= -1e-9 {
        return None;
    }
    let f = img.camera.focal_mm;
    let (u, v, w) = (uvw.x, uvw.y, uvw.z);
    let mut jac = [[0.0; 3]; 2];
    for c in 0..3 {
        jac[0][c] = -f * (m[(0, c)] * w - u * m[(2, c)]) / (w * w);
        jac[1][c] = -f * (m[(1, c)] * w - v * m[(2, c)]) / (w * w);
    }
    Some(([-f * u / w, -f * v / w], jac))
}

/// Lines that another line overlaps, parallel (within 5°) and nearer than `separation_mm`: no pixel can tell
/// them apart (an opening's edge and the frame recessed behind it, seen at a grazing angle), so neither is used
/// in this image; other images, where parallax separates them, fit them.
fn unresolvable(lines: &[Projected], separation_mm: f64) -> Vec<bool> {
    let sin_tol = 5f64.to_radians().sin();
    let mut out = vec![false; lines.len()];
    let units: Vec<([f64; 2], f64)> = lines
        .iter()
        .map(|l| {
            let (tx, ty) = (l.q[0] - l.p[0], l.q[1] - l.p[1]);
            let len = (tx * tx + ty * ty).sqrt();
            ([tx / len, ty / len], len)
        })
        .collect();
    for i in 0..lines.len() {
        let (ui, li) = units[i];
        for j in i + 1..lines.len() {
            let (uj, _) = units[j];
            if (ui[0] * uj[1] - ui[1] * uj[0]).abs() > sin_tol {
                continue;
            }
            // j's ends in i's frame: along (s) and across (d).
            let local = |x: [f64; 2]| {
                let (ex, ey) = (x[0] - lines[i].p[0], x[1] - lines[i].p[1]);
                (ex * ui[0] + ey * ui[1], ui[1] * ex - ui[0] * ey)
            };
            let ((s0, d0), (s1, d1)) = (local(lines[j].p), local(lines[j].q));
            let overlap = s0.max(s1).min(li) - s0.min(s1).max(0.0);
            if overlap > 0.0 && d0.abs().max(d1.abs()) < separation_mm {
                out[i] = true;
                out[j] = true;
            }
        }
    }
    out
}

/// The observation rows of one image at parameters `p`.
fn rows_of_image(
    model: &dyn Parametric,
    faces: &FaceEdges,
    vertices: &[Vec3],
    jacobians: &[Vec<(usize, Vec3)>],
    img: &ImageEdges,
    buffer_mm: f64,
    params: &FitParams,
) -> Vec<Row> {
    let projections: Vec<Option<Projection>> = vertices.iter().map(|v| project_with_jacobian(img, v)).collect();
    let visible = faces.visible(vertices, &img.pose.center);
    let min_len = 2.0 * img.camera.pixel_size_mm;
    let lines: Vec<Projected> = model
        .edges()
        .iter()
        .enumerate()
        .filter(|(k, _)| visible[*k])
        .filter_map(|(k, e)| {
            let (p, _) = projections[e[0]]?;
            let (q, _) = projections[e[1]]?;
            (((q[0] - p[0]).powi(2) + (q[1] - p[1]).powi(2)).sqrt() >= min_len).then_some(Projected { edge: k, p, q })
        })
        .collect();
    let ambiguous = unresolvable(&lines, params.buffer_min_mm);
    let lines: Vec<Projected> = lines.into_iter().zip(ambiguous).filter(|(_, a)| !a).map(|(l, _)| l).collect();
    // (observation, |d|, line slot): the nearest line takes a pixel within several buffers.
    let mut candidates: Vec<(u32, f64, u32)> = Vec::new();
    let obs = img.observations();
    for (slot, l) in lines.iter().enumerate() {
        let (tx, ty) = (l.q[0] - l.p[0], l.q[1] - l.p[1]);
        let len = (tx * tx + ty * ty).sqrt();
        let (ux, uy) = (tx / len, ty / len);
        img.near_segment(l.p, l.q, buffer_mm, |i| {
            let e = obs[i].xy;
            let (ex, ey) = (e[0] - l.p[0], e[1] - l.p[1]);
            let s = (ex * ux + ey * uy) / len;
            let d = uy * ex - ux * ey;
            if (0.0..=1.0).contains(&s) && d.abs() <= buffer_mm {
                candidates.push((i as u32, d.abs(), slot as u32));
            }
        });
    }
    candidates.sort_by(|a, b| a.0.cmp(&b.0).then(a.1.total_cmp(&b.1)).then(a.2.cmp(&b.2)));
    candidates.dedup_by_key(|c| c.0);
    if params.max_pixels_per_line > 0 {
        let mut count = vec![0usize; lines.len()];
        for c in &candidates {
            count[c.2 as usize] += 1;
        }
        let stride: Vec<usize> = count.iter().map(|&n| n.div_ceil(params.max_pixels_per_line).max(1)).collect();
        let mut seen = vec![0usize; lines.len()];
        candidates.retain(|c| {
            let slot = c.2 as usize;
            seen[slot] += 1;
            (seen[slot] - 1).is_multiple_of(stride[slot])
        });
    }
    let gate = params.angle_gate_deg.to_radians().sin();
    candidates
        .into_iter()
        .filter_map(|(i, _, slot)| row_for(model, &projections, jacobians, img, i, lines[slot as usize].edge, gate, params))
        .collect()
}

/// The observation row of pixel `i` of `img` on model edge `edge`, if both ends project and its weight is not 0.
#[allow(clippy::too_many_arguments)]
fn row_for(
    model: &dyn Parametric,
    projections: &[Option<Projection>],
    jacobians: &[Vec<(usize, Vec3)>],
    img: &ImageEdges,
    i: u32,
    edge: usize,
    gate: f64,
    params: &FitParams,
) -> Option<Row> {
    let [a, b] = model.edges()[edge];
    let ((p1, ja), (p2, jb)) = (projections[a]?, projections[b]?);
    let o = &img.observations()[i as usize];
    let (tx, ty) = (p2[0] - p1[0], p2[1] - p1[1]);
    let len = (tx * tx + ty * ty).sqrt();
    if len <= 0.0 {
        return None;
    }
    let cos_lambda = (o.gradient[0] * tx + o.gradient[1] * ty) / len;
    let w = params.weighting.weight(o.relative, cos_lambda, gate);
    if w <= 0.0 {
        return None;
    }
    // d = n·(e − P1) with n = (ty, −tx)/len: ∂d/∂P1 = −(1 − s)n, ∂d/∂P2 = −s·n.
    let n = [ty / len, -tx / len];
    let (ex, ey) = (o.xy[0] - p1[0], o.xy[1] - p1[1]);
    let d = n[0] * ex + n[1] * ey;
    let s = (ex * tx + ey * ty) / (len * len);
    let mut grad: Vec<(usize, f64)> = Vec::with_capacity(14);
    for (vertex, share, jp) in [(a, 1.0 - s, ja), (b, s, jb)] {
        let dd_dv = Vec3::new(
            -share * (n[0] * jp[0][0] + n[1] * jp[1][0]),
            -share * (n[0] * jp[0][1] + n[1] * jp[1][1]),
            -share * (n[0] * jp[0][2] + n[1] * jp[1][2]),
        );
        for (k, dv) in &jacobians[vertex] {
            let g = dd_dv.dot(dv);
            match grad.iter_mut().find(|(j, _)| j == k) {
                Some(entry) => entry.1 += g,
                None => grad.push((*k, g)),
            }
        }
    }
    Some(Row { d, w, edge, obs: i, grad })
}

/// The rows of pixels already assigned to edges, at parameters `p`, in image order.
fn rows_of_selection<I: Borrow<ImageEdges> + Sync>(
    model: &dyn Parametric,
    p: &[f64],
    images: &[I],
    selection: &[Vec<(u32, usize)>],
    params: &FitParams,
) -> Vec<Vec<Row>> {
    let vertices = model.vertices(p);
    let jacobians = model.vertex_jacobians(p);
    let gate = params.angle_gate_deg.to_radians().sin();
    images
        .par_iter()
        .zip(selection)
        .map(|(img, sel)| {
            let img = img.borrow();
            let projections: Vec<Option<Projection>> = vertices.iter().map(|v| project_with_jacobian(img, v)).collect();
            sel.iter()
                .filter_map(|&(i, edge)| row_for(model, &projections, &jacobians, img, i, edge, gate, params))
                .collect()
        })
        .collect()
}

/// Every image's rows at `p`, in image order (deterministic whatever the thread count).
fn collect_rows<I: Borrow<ImageEdges> + Sync>(
    model: &dyn Parametric,
    p: &[f64],
    images: &[I],
    buffer_mm: f64,
    params: &FitParams,
) -> Vec<Vec<Row>> {
    let vertices = model.vertices(p);
    let jacobians = model.vertex_jacobians(p);
    let faces = FaceEdges::new(model, p);
    images
        .par_iter()
        .map(|img| rows_of_image(model, &faces, &vertices, &jacobians, img.borrow(), buffer_mm, params))
        .collect()
}

/// Models up to this many parameters are solved densely (exact covariance); larger ones sparsely.
const DENSE_MAX: usize = 96;

/// The normal matrix, dense for primitives and small components, sparse for large wire-frames.
enum Normal {
    Dense(DMatrix<f64>),
    Sparse(SparseSym),
}

impl Normal {
    fn new(model: &dyn Parametric, p: &[f64]) -> Self {
        let n = model.n_params();
        if n <= DENSE_MAX || !n.is_multiple_of(3) {
            return Normal::Dense(DMatrix::zeros(n, n));
        }
        let params_of: Vec<Vec<usize>> = model
            .vertex_jacobians(p)
            .into_iter()
            .map(|j| j.into_iter().map(|(k, _)| k).collect())
            .collect();
        let groups = model.edges().iter().map(|e| {
            let mut g = params_of[e[0]].clone();
            g.extend_from_slice(&params_of[e[1]]);
            g
        });
        Normal::Sparse(SparseSym::with_pattern(n, groups))
    }

    fn add(&mut self, i: usize, j: usize, v: f64) {
        match self {
            Normal::Dense(m) => m[(i, j)] += v,
            Normal::Sparse(m) => m.add(i, j, v),
        }
    }

    fn clear(&mut self) {
        match self {
            Normal::Dense(m) => m.fill(0.0),
            Normal::Sparse(m) => m.clear(),
        }
    }

    fn solve(&self, b: &DVector<f64>) -> Option<DVector<f64>> {
        match self {
            Normal::Dense(m) => m.clone().cholesky().map(|c| c.solve(b)),
            Normal::Sparse(m) => m.solve(b.as_slice(), 1e-10, 10 * m.n()).map(DVector::from_vec),
        }
    }

    /// Diagonal of the inverse: exact when dense, from the 3×3 diagonal blocks (each vertex given its
    /// neighbours) when sparse.
    fn inverse_diagonal(&self) -> Vec<f64> {
        match self {
            Normal::Dense(m) => match m.clone().try_inverse() {
                Some(q) => (0..m.nrows()).map(|k| q[(k, k)]).collect(),
                None => vec![f64::NAN; m.nrows()],
            },
            Normal::Sparse(m) => m
                .block_inverses()
                .into_iter()
                .flat_map(|b| match b {
                    Some(q) => [q[(0, 0)], q[(1, 1)], q[(2, 2)]],
                    None => [f64::NAN; 3],
                })
                .collect(),
        }
    }
}

/// Pseudo-observations toward the start: one weight for every parameter, or a 3×3 precision per vertex block.
enum Prior {
    None,
    Scalar(f64),
    Blocks(Vec<nalgebra::Matrix3<f64>>),
}

/// Fills the normal equations of the rows plus the priors toward `start`; the right-hand side.
fn normal_equations(
    normal: &mut Normal,
    rows: &[Vec<Row>],
    p: &[f64],
    start: &[f64],
    prior: &Prior,
    constraints: &[(usize, f64, f64)],
) -> DVector<f64> {
    normal.clear();
    let mut b = DVector::<f64>::zeros(p.len());
    for r in rows.iter().flatten() {
        for &(i, gi) in &r.grad {
            b[i] -= r.w * gi * r.d;
            for &(j, gj) in &r.grad {
                normal.add(i, j, r.w * gi * gj);
            }
        }
    }
    for &(k, value, w) in constraints {
        normal.add(k, k, w);
        b[k] -= w * (p[k] - value);
    }
    match prior {
        Prior::None => {}
        Prior::Scalar(w) => {
            for k in 0..p.len() {
                normal.add(k, k, *w);
                b[k] -= w * (p[k] - start[k]);
            }
        }
        Prior::Blocks(blocks) => {
            for (v, m) in blocks.iter().enumerate() {
                let off = nalgebra::Vector3::from_fn(|r, _| p[3 * v + r] - start[3 * v + r]);
                let g = m * off;
                for r in 0..3 {
                    b[3 * v + r] -= g[r];
                    for c in 0..3 {
                        normal.add(3 * v + r, 3 * v + c, m[(r, c)]);
                    }
                }
            }
        }
    }
    b
}

/// Fits `model` from parameters `start` to the edge pixels of `images`.
pub fn fit<I: Borrow<ImageEdges> + Sync>(model: &dyn Parametric, start: &[f64], images: &[I], params: &FitParams) -> Fit {
    let n = model.n_params();
    assert_eq!(start.len(), n, "start vector of {} for a model of {n} parameters", start.len());
    let pixel_mm = images.first().map_or(1.0, |i| i.borrow().camera.pixel_size_mm);
    // A pixel of weight 1 stands for a distance of about one pixel: the prior's weight in the same units.
    let prior = match model.prior_blocks() {
        Some(blocks) => Prior::Blocks(blocks.into_iter().map(|m| m * pixel_mm * pixel_mm).collect()),
        None if params.prior_sigma > 0.0 => Prior::Scalar((pixel_mm / params.prior_sigma).powi(2)),
        None => Prior::None,
    };
    let constraints: Vec<(usize, f64, f64)> = params
        .constraints
        .iter()
        .filter(|c| c.param < n)
        .map(|c| (c.param, c.value, (pixel_mm / c.sigma).powi(2)))
        .collect();
    let has_prior = !matches!(prior, Prior::None) || !constraints.is_empty();
    let mut p = start.to_vec();
    let mut log = Vec::new();
    let final_from = params.final_buffer_from();
    let failed = |p: Vec<f64>, log: Vec<Iteration>, why: String| Fit {
        params: p,
        sigmas: Vec::new(),
        sigma0_mm: f64::NAN,
        residual_rms_mm: f64::NAN,
        converged: false,
        failure: Some(why),
        edge_pixels: vec![0; model.edges().len()],
        iterations: log,
    };
    let mut converged = false;
    let mut normal = Normal::new(model, start);
    // From the first iteration at the final buffer on, the pixels keep their lines: re-selecting them every
    // step lets a component hop between neighbouring parallel edges without ever settling.
    let mut frozen: Option<Vec<Vec<(u32, usize)>>> = None;
    for it in 0..params.max_iterations {
        let buffer = params.buffer_mm(it);
        let rows = match &frozen {
            Some(selection) => rows_of_selection(model, &p, images, selection, params),
            None => collect_rows(model, &p, images, buffer, params),
        };
        if it >= final_from && params.freeze_at_final && frozen.is_none() {
            frozen = Some(rows.iter().map(|r| r.iter().map(|r| (r.obs, r.edge)).collect()).collect());
        }
        let used: usize = rows.iter().map(Vec::len).sum();
        if used < n && !has_prior {
            return failed(start.to_vec(), log, format!("{used} edge pixels for {n} parameters"));
        }
        let b = normal_equations(&mut normal, &rows, &p, start, &prior, &constraints);
        let Some(dp) = normal.solve(&b) else {
            return failed(
                start.to_vec(),
                log,
                "the normal equations are singular: some parameters see no edge pixels".into(),
            );
        };
        let ratio = (0..n).map(|k| dp[k].abs() / model.tolerance(k)).fold(0.0, f64::max);
        for k in 0..n {
            p[k] += dp[k];
        }
        log.push(Iteration {
            buffer_mm: buffer,
            pixels: used,
            step_ratio: ratio,
        });
        if let Some(why) = model.invalid(&p) {
            return failed(start.to_vec(), log, why);
        }
        if it >= final_from && ratio < 1.0 {
            converged = true;
            break;
        }
    }
    // Precision and residuals from the pixels at the final parameters and buffer.
    let rows = collect_rows(model, &p, images, params.buffer_min_mm, params);
    normal_equations(&mut normal, &rows, &p, start, &prior, &constraints);
    let (mut sum_wdd, mut sum_w, mut count) = (0.0, 0.0, 0usize);
    let mut edge_pixels = vec![0; model.edges().len()];
    for r in rows.iter().flatten() {
        sum_wdd += r.w * r.d * r.d;
        sum_w += r.w;
        count += 1;
        edge_pixels[r.edge] += 1;
    }
    let redundancy = match prior {
        Prior::None => (count + constraints.len()).saturating_sub(n),
        _ => count,
    }
    .max(1);
    let sigma0_mm = (sum_wdd / redundancy as f64).sqrt();
    let sigmas = normal
        .inverse_diagonal()
        .into_iter()
        .map(|q| sigma0_mm * q.max(0.0).sqrt())
        .collect();
    Fit {
        params: p,
        sigmas,
        sigma0_mm,
        residual_rms_mm: if sum_w > 0.0 { (sum_wdd / sum_w).sqrt() } else { f64::NAN },
        converged,
        failure: None,
        edge_pixels,
        iterations: log,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use lineflow_runtime::StageParams;

    /// Seed fact C4: 0.40 → 0.05 mm in steps of 0.05 mm, then constant.
    #[test]
    fn buffer_schedule_is_the_seeds() {
        let p = FitParams::default();
        let got: Vec<f64> = (0..11).map(|i| (p.buffer_mm(i) * 1000.0).round() / 1000.0).collect();
        assert_eq!(got, [0.4, 0.35, 0.3, 0.25, 0.2, 0.15, 0.1, 0.05, 0.05, 0.05, 0.05]);
        assert_eq!(p.final_buffer_from(), 7);
        assert!(p.validate().is_ok());
        let bad = FitParams {
            buffer_min_mm: 0.0,
            ..FitParams::default()
        };
        assert!(bad.validate().is_err());
    }
}
