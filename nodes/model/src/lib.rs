//! The model stage: a polyhedral wire-frame from unordered, incomplete, noisy 3-D lines, after seed 003's
//! Construct-Shape-Refine (CSR), applied to façades.
//!
//! - Construct ([`junction`], [`corners`]): candidate junctions between lines, the seed's acceptance conditions
//!   (error-free logic, distance checks, topology), junctions clustered into corners, lines grouped into objects.
//! - Shape ([`adjust`]): the corners of each object adjusted from its lines in the Gauss-Helmert model, with
//!   standard deviations.
//! - Faces ([`faces`]): closed planar cycles of edges become wall, roof and opening surfaces; a face inside another
//!   face of the same plane is its opening (the seed's "roof inside a roof").
//! - Export ([`export`]): `model.obj` and `model.city.json` (CityJSON 2.0, LOD 3).
//!
//! Not yet: the seed's Refine step (fusion with 2-D image lines), occluded-edge completion along the shortest
//! path, and model-image fitting (LSMIF, seed 004).
pub mod adjust;
pub mod corners;
pub mod export;
pub mod faces;
mod grid;
pub mod junction;

use lineflow_photogrammetry::Vec3;
use serde::Deserialize;

pub use faces::{Face, SurfaceKind};
use junction::Resolution;

/// A 3-D line given to the model.
#[derive(Debug, Clone)]
pub struct ModelLine {
    pub start: Vec3,
    pub end: Vec3,
    /// Standard deviation of each endpoint coordinate across the line, metres.
    pub sigma_m: f64,
}

impl ModelLine {
    pub fn new(start: Vec3, end: Vec3, sigma_m: f64) -> Self {
        ModelLine { start, end, sigma_m }
    }
    pub fn length(&self) -> f64 {
        (self.end - self.start).norm()
    }
    pub fn direction(&self) -> Vec3 {
        (self.end - self.start).normalize()
    }
    pub fn midpoint(&self) -> Vec3 {
        (self.start + self.end) * 0.5
    }
}

/// Parameters of the model stage (launch-file `params` of node `model`).
#[derive(Debug, Clone, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct ModelParams {
    /// Endpoint standard deviation for lines that carry no RMS (e.g. a lines3d.csv without statistics), metres.
    pub sigma_m: f64,
    /// Smallest endpoint standard deviation credited to any line, metres (a fitted line's RMS over many points
    /// can be optimistic).
    pub min_sigma_m: f64,
    /// Lines shorter than this are ignored, metres.
    pub min_length_m: f64,
    /// Distance gate: a junction may lie at most this far beyond a segment, and must lie this close to an end of
    /// one of the two lines, metres.
    pub max_reach_m: f64,
    /// Gap gate: two lines meet when their common perpendicular is shorter than this many joint σ.
    pub gap_k: f64,
    /// Smallest angle between two lines that are intersected, degrees (the seed's 3σ gate is clamped to
    /// [this, 20°]).
    pub min_angle_deg: f64,
    /// Junctions closer than this many joint σ are one corner.
    pub corner_k: f64,
    /// Two planes of faces are one when their normals differ by less than this, degrees.
    pub plane_angle_deg: f64,
}

impl Default for ModelParams {
    fn default() -> Self {
        ModelParams {
            sigma_m: 0.01,
            min_sigma_m: 0.002,
            min_length_m: 0.02,
            max_reach_m: 0.05,
            gap_k: 3.0,
            min_angle_deg: 5.0,
            corner_k: 3.0,
            plane_angle_deg: 2.0,
        }
    }
}

impl ModelParams {
    /// Checks the values before anything is built.
    pub fn validate(&self) -> Result<(), String> {
        let positive = [
            ("sigma_m", self.sigma_m),
            ("min_sigma_m", self.min_sigma_m),
            ("max_reach_m", self.max_reach_m),
            ("gap_k", self.gap_k),
            ("corner_k", self.corner_k),
            ("plane_angle_deg", self.plane_angle_deg),
        ];
        for (name, v) in positive {
            if !(v.is_finite() && v > 0.0) {
                return Err(format!("{name} must be a positive number, got {v}"));
            }
        }
        if !(0.0..45.0).contains(&self.min_angle_deg) {
            return Err(format!("min_angle_deg must be in [0, 45), got {}", self.min_angle_deg));
        }
        if self.min_length_m.is_nan() || self.min_length_m < 0.0 {
            return Err(format!("min_length_m must be ≥ 0, got {}", self.min_length_m));
        }
        Ok(())
    }

    /// The endpoint σ of a fitted line: the RMS of its points about it, shrunk by the points' number as the end
    /// of a least-squares line is (≈ 2 RMS / √n), never below `min_sigma_m`; `sigma_m` when unknown.
    pub fn line_sigma(&self, rms_m: Option<f64>, n_points: Option<u32>) -> f64 {
        match (rms_m, n_points) {
            (Some(rms), Some(n)) if rms.is_finite() && rms > 0.0 && n > 0 => (2.0 * rms / (n as f64).sqrt()).max(self.min_sigma_m),
            _ => self.sigma_m,
        }
    }
}

/// A vertex of the wire-frame.
#[derive(Debug, Clone, PartialEq)]
pub struct Vertex {
    pub point: Vec3,
    /// Posterior standard deviations of an adjusted corner; `None` for a free line end.
    pub sigma: Option<Vec3>,
}

/// An edge of the wire-frame: two vertices and the input line it comes from.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Edge {
    pub a: usize,
    pub b: usize,
    pub line: usize,
}

/// What the model was built from and how, for the log and the report.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Diagnostics {
    pub lines_in: usize,
    /// Lines that reached at least one corner (the others are kept as loose edges).
    pub lines_used: usize,
    pub junction_candidates: usize,
    pub junctions_accepted: usize,
    /// Line ends resolved by stage 1, 2 and 3, and left free.
    pub ends_by_stage: [usize; 4],
    pub objects: usize,
    /// Objects whose adjustment failed (initial corners kept).
    pub objects_unadjusted: usize,
    /// Median σ̂0 over the objects with redundancy.
    pub median_sigma0: Option<f64>,
}

/// The wire-frame model.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Model {
    pub vertices: Vec<Vertex>,
    pub edges: Vec<Edge>,
    pub faces: Vec<Face>,
    pub diagnostics: Diagnostics,
}

impl Model {
    /// The faces of the given kinds.
    pub fn count(&self, kinds: &[SurfaceKind]) -> usize {
        self.faces.iter().filter(|f| kinds.contains(&f.kind)).count()
    }

    /// One line for logs: what was used, what came out, how the line ends were resolved, σ̂0.
    pub fn summary(&self) -> String {
        let d = &self.diagnostics;
        format!(
            "{} of {} lines used, {} objects, {} vertices, {} edges, {} faces ({} walls, {} window/door, {} roof), ends resolved by stage 1/2/3: {}/{}/{}, free {}, median sigma0 {}",
            d.lines_used,
            d.lines_in,
            d.objects,
            self.vertices.len(),
            self.edges.len(),
            self.faces.len(),
            self.count(&[SurfaceKind::Wall]),
            self.count(&[SurfaceKind::Window, SurfaceKind::Door]),
            self.count(&[SurfaceKind::Roof]),
            d.ends_by_stage[0],
            d.ends_by_stage[1],
            d.ends_by_stage[2],
            d.ends_by_stage[3],
            d.median_sigma0.map_or("-".into(), |s| format!("{s:.2}"))
        )
    }
}

/// Construct and Shape: the wire-frame of `lines`, then its faces, oriented towards `viewpoint` (e.g. the mean
/// camera centre) when given. Deterministic for a given line order.
pub fn build(lines: &[ModelLine], params: &ModelParams, viewpoint: Option<Vec3>) -> Model {
    let kept: Vec<usize> = (0..lines.len())
        .filter(|&k| {
            lines[k].length() >= params.min_length_m.max(1e-6) && lines[k].start.iter().chain(lines[k].end.iter()).all(|v| v.is_finite())
        })
        .collect();
    let used_lines: Vec<ModelLine> = kept.iter().map(|&k| lines[k].clone()).collect();
    let candidates = junction::candidates(&used_lines, params);
    let accepted = junction::accept(&used_lines, &candidates, params);
    let corners = corners::cluster(&candidates, &accepted.junctions, params.corner_k);
    let object_of = corners::objects(used_lines.len(), &corners);

    let mut diagnostics = Diagnostics {
        lines_in: lines.len(),
        junction_candidates: candidates.len(),
        junctions_accepted: accepted.junctions.len(),
        ..Default::default()
    };
    for r in accepted.ends.iter().flatten() {
        let slot = match r {
            Resolution::Logic => 0,
            Resolution::Distance => 1,
            Resolution::Topology => 2,
            Resolution::Free => 3,
        };
        diagnostics.ends_by_stage[slot] += 1;
    }

    // Shape, object by object.
    let n_objects = object_of.iter().copied().max().map_or(0, |m| m + 1);
    let mut corner_point: Vec<Vec3> = corners.iter().map(|c| c.point).collect();
    let mut corner_sigma: Vec<Option<Vec3>> = vec![None; corners.len()];
    let mut line_axis: Vec<Option<(Vec3, Vec3)>> = vec![None; used_lines.len()];
    let mut sigma0s = Vec::new();
    // Corners and lines bucketed by object once (ascending within each).
    let mut corners_of: Vec<Vec<usize>> = vec![Vec::new(); n_objects];
    for (c, corner) in corners.iter().enumerate() {
        corners_of[object_of[corner.lines[0]]].push(c);
    }
    let mut lines_of: Vec<Vec<usize>> = vec![Vec::new(); n_objects];
    for (l, &o) in object_of.iter().enumerate() {
        lines_of[o].push(l);
    }
    for (object_corners, object_lines) in corners_of.iter().zip(&lines_of) {
        if object_corners.is_empty() {
            continue;
        }
        diagnostics.objects += 1;
        let local_line = |l: usize| object_lines.binary_search(&l).ok();
        let incidences: Vec<(usize, usize)> = object_corners
            .iter()
            .enumerate()
            .flat_map(|(ci, &c)| corners[c].lines.iter().filter_map(move |&l| local_line(l).map(|ll| (ci, ll))))
            .collect();
        let sub_lines: Vec<ModelLine> = object_lines.iter().map(|&l| used_lines[l].clone()).collect();
        let start: Vec<Vec3> = object_corners.iter().map(|&c| corners[c].point).collect();
        match adjust::adjust(&sub_lines, &start, &incidences) {
            Some(r) => {
                for (ci, &c) in object_corners.iter().enumerate() {
                    corner_point[c] = r.corners[ci];
                    corner_sigma[c] = Some(r.sigmas[ci]);
                }
                for (li, &l) in object_lines.iter().enumerate() {
                    line_axis[l] = Some(r.lines[li]);
                }
                sigma0s.extend(r.sigma0);
            }
            None => diagnostics.objects_unadjusted += 1,
        }
    }
    sigma0s.sort_by(f64::total_cmp);
    diagnostics.median_sigma0 = sigma0s.get(sigma0s.len() / 2).copied();

    // Vertices: the corners, then free ends; edges: consecutive vertices along each line.
    let mut vertices: Vec<Vertex> = corner_point
        .iter()
        .zip(&corner_sigma)
        .map(|(p, s)| Vertex { point: *p, sigma: *s })
        .collect();
    let mut on_line: Vec<Vec<usize>> = vec![Vec::new(); used_lines.len()];
    for (c, corner) in corners.iter().enumerate() {
        for &l in &corner.lines {
            on_line[l].push(c);
        }
    }
    let mut edges = Vec::new();
    // Two fragments of one edge reach the same corners: one edge.
    let mut seen = std::collections::HashSet::new();
    for (l, line) in used_lines.iter().enumerate() {
        if !on_line[l].is_empty() {
            diagnostics.lines_used += 1;
        }
        let (origin, dir) = line_axis[l].unwrap_or((line.start, line.direction()));
        let t = |p: &Vec3| (p - origin).dot(&dir);
        let mut along: Vec<(f64, usize)> = on_line[l].iter().map(|&c| (t(&vertices[c].point), c)).collect();
        along.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
        // A free end beyond the outermost corner by more than the noise is kept as a vertex: the edge goes on.
        let gate = (3.0 * line.sigma_m).max(0.02);
        for (end, p) in [(0, line.start), (1, line.end)] {
            if accepted.ends[l][end] != Resolution::Free {
                continue;
            }
            let tp = t(&p);
            // A line that reached no corner is kept whole: an observed edge, if not part of any face.
            let (lo, hi) = along
                .first()
                .zip(along.last())
                .map_or((f64::INFINITY, f64::NEG_INFINITY), |(a, b)| (a.0, b.0));
            if tp < lo - gate || tp > hi + gate {
                vertices.push(Vertex {
                    point: origin + dir * tp,
                    sigma: None,
                });
                along.push((tp, vertices.len() - 1));
            }
        }
        along.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
        for w in along.windows(2) {
            if w[0].1 != w[1].1 && seen.insert((w[0].1.min(w[1].1), w[0].1.max(w[1].1))) {
                edges.push(Edge {
                    a: w[0].1,
                    b: w[1].1,
                    line: kept[l],
                });
            }
        }
    }
    let faces = faces::find(&vertices, &edges, params, viewpoint);
    Model {
        vertices,
        edges,
        faces,
        diagnostics,
    }
}

/// The model's lines from `lines3d.csv` rows (or `Lines3D` elements through their rows), each with the endpoint
/// σ its statistics give.
pub fn lines_from_rows(rows: &[lineflow_formats::Line3Row], params: &ModelParams) -> Vec<ModelLine> {
    rows.iter()
        .map(|r| ModelLine::new(r.start, r.end, params.line_sigma(r.rms_m, r.n_points)))
        .collect()
}
