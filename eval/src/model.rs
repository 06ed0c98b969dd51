//! Model metrics (`docs/eval.md`): the wire-frame against the true one, built from the ground-truth edges.
//!
//! The true wire-frame's vertices are the ends of the true edges (merged within 1 mm); an edge with another
//! edge's end on it is split there, as a model edge would be. A model vertex matches the true vertex it is
//! mutually nearest to within 5 GSD; the vertex RMSE is over those pairs. A model edge is right when both its ends
//! lie within 3 GSD of the two ends of one true edge; edge precision is the share of model edges that are right,
//! edge recall the share of true edges some model edge matches. The truth holds the edges two images see;
//! a model edge on an edge of the building fewer images see (a frame's foot behind its sill, seen from below) is
//! neither right nor wrong: it is left out of the precision and counted apart.
use lineflow_formats::Line3Row;

use crate::geometry::Seg;
use lineflow_photogrammetry::Vec3;

/// The model metrics.
#[derive(Debug, Clone, PartialEq)]
pub struct ModelReport {
    pub gsd_m: f64,
    pub true_vertices: usize,
    pub model_vertices: usize,
    pub matched_vertices: usize,
    /// 3-D RMSE of the matched vertices, metres.
    pub vertex_rmse_m: f64,
    pub true_edges: usize,
    pub model_edges: usize,
    pub edge_precision: f64,
    pub edge_recall: f64,
    /// Model edges on an edge of the building that the truth leaves out (fewer than two images see it): left out of
    /// the precision.
    pub unseen_edges: usize,
    /// Reach for vertex matching and tolerance for edge ends, metres.
    pub vertex_reach_m: f64,
    pub edge_tolerance_m: f64,
    /// The model's edges and the true ones as segments, for the report's views.
    pub edge_segments: Vec<Seg>,
    pub true_segments: Vec<Seg>,
    /// Per model edge: the mean distance of its ends from those of the true edge it matches, metres; NaN where it
    /// matches none.
    pub edge_error_m: Vec<f64>,
}

/// A model edge's ends lie within this many GSD of a true edge's ends to match it.
const EDGE_TOLERANCE_GSD: f64 = 3.0;

/// The true wire-frame: vertices and edges from the true segments.
pub fn true_wireframe(lines: &[Line3Row]) -> (Vec<Vec3>, Vec<[usize; 2]>) {
    let merge = 1e-3;
    let mut vertices: Vec<Vec3> = Vec::new();
    let index = |p: Vec3, vertices: &mut Vec<Vec3>| {
        if let Some(k) = vertices.iter().position(|v| (v - p).norm() < merge) {
            k
        } else {
            vertices.push(p);
            vertices.len() - 1
        }
    };
    let ends: Vec<[usize; 2]> = lines
        .iter()
        .map(|l| [index(l.start, &mut vertices), index(l.end, &mut vertices)])
        .collect();
    let mut edges = Vec::new();
    for (l, [a, b]) in lines.iter().zip(&ends) {
        let d = l.end - l.start;
        let len2 = d.norm_squared();
        if len2 < 1e-12 {
            continue;
        }
        let mut on: Vec<(f64, usize)> = vec![(0.0, *a), (1.0, *b)];
        for (k, v) in vertices.iter().enumerate() {
            let t = (v - l.start).dot(&d) / len2;
            if t > 1e-6 && t < 1.0 - 1e-6 && (l.start + d * t - v).norm() < merge {
                on.push((t, k));
            }
        }
        on.sort_by(|x, y| x.0.total_cmp(&y.0));
        edges.extend(on.windows(2).filter(|w| w[0].1 != w[1].1).map(|w| [w[0].1, w[1].1]));
    }
    (vertices, edges)
}

fn nearest(points: &[Vec3], p: &Vec3) -> Option<(usize, f64)> {
    points
        .iter()
        .enumerate()
        .map(|(k, q)| (k, (q - p).norm()))
        .min_by(|a, b| a.1.total_cmp(&b.1))
}

/// Scores a wire-frame (`vertices`, `edges`) against the true segments `truth` (seen in two images) at ground
/// sample distance `gsd_m`; `every` holds every edge of the building, seen or not (empty: none is forgiven).
pub fn evaluate(truth: &[Line3Row], every: &[Line3Row], vertices: &[Vec3], edges: &[[usize; 2]], gsd_m: f64) -> ModelReport {
    let (tv, te) = true_wireframe(truth);
    let reach = 5.0 * gsd_m;
    let tol = EDGE_TOLERANCE_GSD * gsd_m;
    let mut sq = 0.0;
    let mut matched = 0;
    for (k, v) in vertices.iter().enumerate() {
        let Some((t, d)) = nearest(&tv, v) else { continue };
        if d <= reach && nearest(vertices, &tv[t]).is_some_and(|(back, _)| back == k) {
            matched += 1;
            sq += d * d;
        }
    }
    let edge_matches = edge_matcher(&tv, vertices, tol);
    // The error of an edge against the true edge it matches best (a short reveal can match a neighbour too).
    let end_error = |m: &[usize; 2], t: &[usize; 2]| {
        let (a, b) = (vertices[m[0]], vertices[m[1]]);
        let (p, q) = (tv[t[0]], tv[t[1]]);
        ((a - p).norm() + (b - q).norm()).min((a - q).norm() + (b - p).norm()) / 2.0
    };
    let edge_error_m: Vec<f64> = edges
        .iter()
        .map(|m| {
            te.iter()
                .filter(|t| edge_matches(m, t))
                .map(|t| end_error(m, t))
                .min_by(f64::total_cmp)
                .unwrap_or(f64::NAN)
        })
        .collect();
    let right = edge_error_m.iter().filter(|e| !e.is_nan()).count();
    let (ev, ee) = true_wireframe(every);
    let on_every = edge_matcher(&ev, vertices, tol);
    let unseen = edges
        .iter()
        .zip(&edge_error_m)
        .filter(|(m, e)| e.is_nan() && ee.iter().any(|t| on_every(m, t)))
        .count();
    let found = te.iter().filter(|t| edges.iter().any(|m| edge_matches(m, t))).count();
    let share = |n: usize, d: usize| if d == 0 { 0.0 } else { n as f64 / d as f64 };
    ModelReport {
        gsd_m,
        true_vertices: tv.len(),
        model_vertices: vertices.len(),
        matched_vertices: matched,
        vertex_rmse_m: if matched == 0 { f64::NAN } else { (sq / matched as f64).sqrt() },
        true_edges: te.len(),
        model_edges: edges.len(),
        edge_precision: share(right, edges.len() - unseen),
        unseen_edges: unseen,
        edge_recall: share(found, te.len()),
        vertex_reach_m: reach,
        edge_tolerance_m: tol,
        edge_segments: edges.iter().map(|m| Seg::new(vertices[m[0]], vertices[m[1]])).collect(),
        true_segments: te.iter().map(|t| Seg::new(tv[t[0]], tv[t[1]])).collect(),
        edge_error_m,
    }
}

/// Whether a model edge (vertex pair into `vertices`) is a true edge (vertex pair into `tv`): both ends within
/// `tol` of its two ends.
fn edge_matcher<'a>(tv: &'a [Vec3], vertices: &'a [Vec3], tol: f64) -> impl Fn(&[usize; 2], &[usize; 2]) -> bool + 'a {
    move |m, t| {
        let close = |p: &Vec3, q: &Vec3| (p - q).norm() <= tol;
        let (a, b) = (&vertices[m[0]], &vertices[m[1]]);
        let (p, q) = (&tv[t[0]], &tv[t[1]]);
        (close(a, p) && close(b, q)) || (close(a, q) && close(b, p))
    }
}

/// The lines a model set aside as lying inside a surface (`surface_lines` of `model.obj`): how many, and how many
/// of them are true edges after all (the class's mistakes), by the edge rule of [`evaluate`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct SurfaceLinesReport {
    pub lines: usize,
    pub true_edges: usize,
}

/// Scores the surface lines `lines` (vertex pairs into `vertices`) against the true segments.
pub fn evaluate_surface_lines(truth: &[Line3Row], vertices: &[Vec3], lines: &[[usize; 2]], gsd_m: f64) -> SurfaceLinesReport {
    let (tv, te) = true_wireframe(truth);
    let edge_matches = edge_matcher(&tv, vertices, EDGE_TOLERANCE_GSD * gsd_m);
    SurfaceLinesReport {
        lines: lines.len(),
        true_edges: lines.iter().filter(|m| te.iter().any(|t| edge_matches(m, t))).count(),
    }
}

/// An opening face of a model: its outer ring and whether the model calls it a door.
#[derive(Debug, Clone, PartialEq)]
pub struct ModelOpening {
    pub door: bool,
    pub ring: Vec<Vec3>,
}

impl From<(bool, Vec<Vec3>)> for ModelOpening {
    /// From (door, ring), as `lineflow_model::Model::openings` gives them.
    fn from((door, ring): (bool, Vec<Vec3>)) -> Self {
        ModelOpening { door, ring }
    }
}

/// Openings (windows and doors) of the model against the true ones.
#[derive(Debug, Clone, PartialEq)]
pub struct OpeningReport {
    pub true_openings: usize,
    /// Window and door faces of the model (frames and panes behind an opening included).
    pub model_openings: usize,
    /// True openings whose four corners each have a vertex of one model opening face within `reach_m`.
    pub found: usize,
    /// Of those, the ones the model calls a door when it is one and a window when it is one.
    pub kind_right: usize,
    /// RMSE of the found openings' corners (each to its nearest vertex of the matching face), metres.
    pub corner_rmse_m: f64,
    pub reach_m: f64,
    /// Found openings whose reveal the model gives: an opening face behind the matching one (the frame or the door
    /// leaf) whose centre lies inside the true outline ([`reveal_depth`]). Without one the model's opening is flush.
    pub reveals_measured: usize,
    /// Found openings whose reveal depth (0 where the model gives none) lies within `reveal_tolerance_m` of the
    /// truth.
    pub reveals_right: usize,
    /// RMSE of the found openings' reveal depths (0 where the model gives none), metres.
    pub reveal_rmse_m: f64,
    /// 1.5 GSD (#29's target).
    pub reveal_tolerance_m: f64,
}

/// Reveals deeper than this are no reveal of the opening: a frame lies 3–50 cm behind the wall's face.
const REVEAL_MAX_M: f64 = 0.6;
/// A face this close behind the opening's own face is the same face, split.
const REVEAL_MIN_M: f64 = 0.01;

/// The reveal the model gives true opening `t`, whose outline `ring` matched: the depth behind `ring`, along the
/// wall's inward normal, of the nearest other opening face (the frame or door leaf; the panes lie further back)
/// whose centre lies inside the true outline, 1 cm to 0.6 m behind.
pub fn reveal_depth(t: &lineflow_synthetic::scene::Opening, ring: &[Vec3], model: &[ModelOpening]) -> Option<f64> {
    let c: Vec<Vec3> = t.corners.iter().map(|&c| Vec3::from(c)).collect();
    let (u, v) = (c[1] - c[0], c[3] - c[0]);
    // The corners run counter-clockwise seen from outside.
    let outward = u.cross(&v).try_normalize(1e-12)?;
    let centre = |r: &[Vec3]| r.iter().sum::<Vec3>() / r.len().max(1) as f64;
    let front = centre(ring).dot(&outward);
    model
        .iter()
        .filter(|m| !m.ring.is_empty() && m.ring.as_slice() != ring)
        .filter_map(|m| {
            let p = centre(&m.ring);
            let (a, b) = ((p - c[0]).dot(&u) / u.norm_squared(), (p - c[0]).dot(&v) / v.norm_squared());
            let depth = front - p.dot(&outward);
            ((0.0..=1.0).contains(&a) && (0.0..=1.0).contains(&b) && (REVEAL_MIN_M..=REVEAL_MAX_M).contains(&depth)).then_some(depth)
        })
        .min_by(f64::total_cmp)
}

/// Scores the model's opening faces against the true openings (outlines in the wall plane) at `gsd_m`: an opening
/// is found when some model opening face has a vertex within 5 GSD of each of its four corners (the face with the
/// smallest corner RMS is its match).
pub fn evaluate_openings(truth: &[lineflow_synthetic::scene::Opening], model: &[ModelOpening], gsd_m: f64) -> OpeningReport {
    let reach = 5.0 * gsd_m;
    let reveal_tolerance = 1.5 * gsd_m;
    let (mut found, mut kind_right, mut sq) = (0, 0, 0.0);
    let (mut reveals, mut reveals_measured) = (Vec::new(), 0);
    for t in truth {
        let corners: Vec<Vec3> = t.corners.iter().map(|&c| Vec3::from(c)).collect();
        let best = model
            .iter()
            .filter_map(|m| {
                let d: Vec<f64> = corners.iter().map(|c| nearest(&m.ring, c).map_or(f64::INFINITY, |n| n.1)).collect();
                d.iter().all(|&x| x <= reach).then(|| (d.iter().map(|x| x * x).sum::<f64>(), m))
            })
            .min_by(|a, b| a.0.total_cmp(&b.0));
        if let Some((s, m)) = best {
            found += 1;
            kind_right += usize::from(m.door == t.door);
            sq += s;
            let depth = reveal_depth(t, &m.ring, model);
            reveals_measured += usize::from(depth.is_some());
            reveals.push(depth.unwrap_or(0.0) - t.reveal_m);
        }
    }
    OpeningReport {
        true_openings: truth.len(),
        model_openings: model.len(),
        found,
        kind_right,
        corner_rmse_m: if found == 0 { f64::NAN } else { (sq / (4 * found) as f64).sqrt() },
        reach_m: reach,
        reveals_measured,
        reveals_right: reveals.iter().filter(|e| e.abs() <= reveal_tolerance).count(),
        reveal_rmse_m: if reveals.is_empty() {
            f64::NAN
        } else {
            (reveals.iter().map(|e| e * e).sum::<f64>() / reveals.len() as f64).sqrt()
        },
        reveal_tolerance_m: reveal_tolerance,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn an_opening_is_found_by_its_four_corners_and_its_kind_is_checked() {
        let rect = |x0: f64, y: f64| [[x0, y, 1.0], [x0 + 1.0, y, 1.0], [x0 + 1.0, y, 2.0], [x0, y, 2.0]];
        let truth = vec![
            lineflow_synthetic::scene::Opening {
                door: false,
                corners: rect(0.0, 0.0),
                reveal_m: 0.095,
            },
            lineflow_synthetic::scene::Opening {
                door: true,
                corners: rect(3.0, 0.0),
                reveal_m: 0.2,
            },
        ];
        let ring = |c: [[f64; 3]; 4], dy: f64| c.iter().map(|&p| Vec3::from(p) + Vec3::new(0.0, dy, 0.0)).collect();
        let model = vec![
            // The first opening 1 cm off, called a window; its frame 10 cm behind; the second one's frame only.
            ModelOpening {
                door: false,
                ring: ring(rect(0.0, 0.0), 0.01),
            },
            ModelOpening {
                door: false,
                ring: ring(rect(0.0, 0.0), 0.1),
            },
            ModelOpening {
                door: true,
                ring: ring(rect(3.0, 0.0), 0.1),
            },
        ];
        let r = evaluate_openings(&truth, &model, 0.005);
        assert_eq!((r.true_openings, r.model_openings, r.found, r.kind_right), (2, 3, 1, 1));
        assert!((r.corner_rmse_m - 0.01).abs() < 1e-12);
        // The frame gives the found opening's reveal: 9 cm behind its outline, 5 mm short of the truth.
        assert_eq!((r.reveals_measured, r.reveals_right), (1, 1));
        assert!((r.reveal_rmse_m - 0.005).abs() < 1e-12, "{r:?}");
        // Without the frame the opening is flush: 9.5 cm short.
        let r = evaluate_openings(&truth, &[model[0].clone()], 0.005);
        assert_eq!((r.found, r.reveals_measured, r.reveals_right), (1, 0, 0));
        assert!((r.reveal_rmse_m - 0.095).abs() < 1e-12, "{r:?}");
    }

    #[test]
    fn a_reveal_is_the_nearest_face_behind_inside_the_outline() {
        let rect = |x0: f64, y: f64| [[x0, y, 1.0], [x0 + 1.0, y, 1.0], [x0 + 1.0, y, 2.0], [x0, y, 2.0]];
        let truth = lineflow_synthetic::scene::Opening {
            door: false,
            corners: rect(0.0, 0.0),
            reveal_m: 0.2,
        };
        let face = |x0: f64, y: f64| ModelOpening {
            door: false,
            ring: rect(x0, y).iter().map(|&p| Vec3::from(p)).collect(),
        };
        let outline = face(0.0, 0.0);
        // In front (a sill's face), beside the outline (the next window's frame), the panes and the frame behind.
        let model = [face(0.0, -0.05), face(0.8, 0.1), face(0.0, 0.3), face(0.0, 0.18), outline.clone()];
        let depth = reveal_depth(&truth, &outline.ring, &model).unwrap();
        assert!((depth - 0.18).abs() < 1e-12, "{depth}");
        assert_eq!(reveal_depth(&truth, &outline.ring, &model[..2]), None);
        let r = evaluate_openings(&[truth], &model, 0.01);
        assert_eq!((r.found, r.reveals_measured, r.reveals_right), (1, 1, 0));
    }

    fn row(a: [f64; 3], b: [f64; 3]) -> Line3Row {
        Line3Row {
            id: String::new(),
            start: Vec3::from(a),
            end: Vec3::from(b),
            n_points: None,
            n_images: None,
            rms_m: None,
            class: lineflow_formats::LineClass::Unknown,
        }
    }

    #[test]
    fn the_truth_scores_perfectly_and_a_t_junction_splits_its_edge() {
        let lines = vec![row([0.0, 0.0, 0.0], [4.0, 0.0, 0.0]), row([2.0, 0.0, 0.0], [2.0, 0.0, 1.0])];
        let (v, e) = true_wireframe(&lines);
        assert_eq!((v.len(), e.len()), (4, 3));
        let r = evaluate(&lines, &[], &v, &e, 0.005);
        assert_eq!((r.edge_precision, r.edge_recall, r.matched_vertices), (1.0, 1.0, 4));
        assert_eq!(r.vertex_rmse_m, 0.0);
    }

    #[test]
    fn a_shifted_model_has_that_rmse_and_loses_its_edges_beyond_the_tolerance() {
        let lines = vec![row([0.0, 0.0, 0.0], [1.0, 0.0, 0.0])];
        let (v, e) = true_wireframe(&lines);
        let near: Vec<Vec3> = v.iter().map(|p| p + Vec3::new(0.0, 0.01, 0.0)).collect();
        let r = evaluate(&lines, &[], &near, &e, 0.005);
        assert!((r.vertex_rmse_m - 0.01).abs() < 1e-12);
        assert_eq!(r.edge_precision, 1.0, "1 cm is within 3 GSD = 1.5 cm");
        let far: Vec<Vec3> = v.iter().map(|p| p + Vec3::new(0.0, 0.02, 0.0)).collect();
        assert_eq!(evaluate(&lines, &[], &far, &e, 0.005).edge_precision, 0.0);
    }
}
