//! The observed edges behind a wall and on it, gathered into standing and lying sides.
use super::*;

pub(super) fn min(v: &[f64]) -> f64 {
    v.iter().copied().fold(f64::INFINITY, f64::min)
}

pub(super) fn max(v: &[f64]) -> f64 {
    v.iter().copied().fold(f64::NEG_INFINITY, f64::max)
}

/// A side of a candidate rectangle: edges behind the wall along one direction, gathered at one position across
/// it and one depth.
#[derive(Debug, Clone)]
pub(super) struct Side {
    /// Position across the direction (x of a standing side, z of a lying one), length-weighted.
    pub(super) at: f64,
    pub(super) depth: f64,
    /// Intervals covered along the direction.
    pub(super) spans: Vec<(f64, f64)>,
    /// The σ of a vertex of one of its edges.
    pub(super) sigma: Option<Vec3>,
}

impl Side {
    pub(super) fn extent(&self) -> (f64, f64) {
        self.spans
            .iter()
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), s| (lo.min(s.0), hi.max(s.1)))
    }

    /// Share of [lo, hi] its spans cover.
    pub(super) fn cover(&self, lo: f64, hi: f64) -> f64 {
        covered_share(&self.spans, lo, hi)
    }
}

/// Share of [lo, hi] the intervals `spans` cover (overlaps counted once).
pub(super) fn covered_share(spans: &[(f64, f64)], lo: f64, hi: f64) -> f64 {
    let mut spans: Vec<(f64, f64)> = spans.iter().map(|&(a, b)| (a.max(lo), b.min(hi))).filter(|(a, b)| b > a).collect();
    spans.sort_by(|a, b| a.0.total_cmp(&b.0));
    let (mut covered, mut end) = (0.0, lo);
    for (a, b) in spans {
        let a = a.max(end);
        if b > a {
            covered += b - a;
            end = b;
        }
    }
    covered / (hi - lo).max(1e-9)
}

/// One observed edge in a wall's coordinates: its position across its direction, its depth, the interval it
/// covers along its direction, and the σ of one of its vertices.
pub(super) type Piece = (f64, f64, f64, f64, Option<Vec3>);

/// The observed edges parallel to `wall` with both ends `depths` behind it, standing (`upright`) or lying, one
/// [`Piece`] each, in order across. Completed edges are left out: they run along occluders, not along what was
/// seen.
pub(super) fn pieces(wall: &Wall, vertices: &[Vertex], edges: &[Edge], upright: bool, depths: (f64, f64)) -> Vec<Piece> {
    let mut pieces: Vec<Piece> = edges
        .iter()
        .filter(|e| e.observed())
        .filter_map(|e| {
            let (p, q) = (vertices[e.a].point, vertices[e.b].point);
            let d = q - p;
            let len = d.norm();
            let (dp, dq) = (wall.depth(&p), wall.depth(&q));
            let within = |x: f64| (depths.0..=depths.1).contains(&x);
            if len < 0.05 || !within(dp) || !within(dq) || (dp - dq).abs() > DEPTH_TOLERANCE_M {
                return None;
            }
            let along = if upright { d.z.abs() } else { d.dot(&wall.across).abs() };
            if along < len * 5f64.to_radians().cos() {
                return None;
            }
            let (cross, a, b) = if upright {
                ((p.dot(&wall.across) + q.dot(&wall.across)) / 2.0, p.z.min(q.z), p.z.max(q.z))
            } else {
                let (s, t) = (p.dot(&wall.across), q.dot(&wall.across));
                ((p.z + q.z) / 2.0, s.min(t), s.max(t))
            };
            Some((cross, (dp + dq) / 2.0, a, b, vertices[e.a].sigma.or(vertices[e.b].sigma)))
        })
        .collect();
    pieces.sort_by(|x, y| x.0.total_cmp(&y.0).then(x.1.total_cmp(&y.1)).then(x.2.total_cmp(&y.2)));
    pieces
}

/// The [`pieces`] gathered into sides.
pub(super) fn sides(wall: &Wall, vertices: &[Vertex], edges: &[Edge], upright: bool, depths: (f64, f64)) -> Vec<Side> {
    let pieces = self::pieces(wall, vertices, edges, upright, depths);
    // Greedy gathering in order across: a piece joins the first side within the tolerances.
    let mut out: Vec<(Side, f64)> = Vec::new();
    for (cross, depth, a, b, sigma) in pieces {
        let w = b - a;
        match out
            .iter_mut()
            .rev()
            .take_while(|(s, _)| cross - s.at <= 2.0 * SIDE_TOLERANCE_M)
            .find(|(s, _)| (cross - s.at).abs() <= SIDE_TOLERANCE_M && (depth - s.depth).abs() <= DEPTH_TOLERANCE_M)
        {
            Some((side, weight)) => {
                side.at = (side.at * *weight + cross * w) / (*weight + w);
                side.depth = (side.depth * *weight + depth * w) / (*weight + w);
                side.spans.push((a, b));
                *weight += w;
            }
            None => out.push((
                Side {
                    at: cross,
                    depth,
                    spans: vec![(a, b)],
                    sigma,
                },
                w,
            )),
        }
    }
    // A side ends at a gap: the frames of windows stacked one above the other share their sides' line.
    out.into_iter()
        .flat_map(|(mut side, _)| {
            side.spans.sort_by(|a, b| a.0.total_cmp(&b.0));
            let mut runs: Vec<Side> = Vec::new();
            for &(a, b) in &side.spans {
                match runs.last_mut() {
                    Some(run) if a <= run.extent().1 + MAX_SIDE_GAP_M => run.spans.push((a, b)),
                    _ => runs.push(Side {
                        spans: vec![(a, b)],
                        ..side.clone()
                    }),
                }
            }
            runs
        })
        .collect()
}
