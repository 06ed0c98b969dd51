//! A wall found from the observed edges alone, where no face closed on one: on a plastered façade with deep
//! recesses the wall carries only the openings' outlines, seldom joined into faces, while the frames behind them
//! close many.
use std::collections::BTreeMap;

use super::*;

/// The width of a depth bin, metres.
const BIN_M: f64 = 0.02;
/// The least share of a wall's edge length standing: a row of sills, stacked, spreads as far but stands only at
/// its ends.
const MIN_STANDING_SHARE: f64 = 0.1;

/// The wall plane of the observed edges: the plan direction most level edge length runs along, and across it the
/// depth (in [`BIN_M`] bins, by length) nearest the viewpoint that carries standing and lying edges spread over
/// [`MIN_WALL_SPAN_M`] and at least a quarter of the length of the busiest depth. None without level edges or
/// where no depth qualifies.
pub(super) fn wall_from_edges(vertices: &[Vertex], edges: &[Edge], viewpoint: &Vec3) -> Option<Plane> {
    let segments: Vec<(Vec3, Vec3)> = edges
        .iter()
        .filter(|e| !e.completed)
        .map(|e| (vertices[e.a].point, vertices[e.b].point))
        .filter(|(p, q)| (q - p).norm() >= 0.05)
        .collect();
    let along = plan_direction(&segments)?;
    let normal = Vec3::z().cross(&along);
    let cos5 = 5f64.to_radians().cos();
    // Depth bin → [length, across from, across to, height from, height to, standing length, lying length].
    let mut bins: BTreeMap<i64, [f64; 7]> = BTreeMap::new();
    for (p, q) in &segments {
        let d = q - p;
        let len = d.norm();
        let upright = d.z.abs() >= len * cos5;
        if !upright && d.dot(&along).abs() < len * cos5 {
            continue;
        }
        let (dp, dq) = (normal.dot(p), normal.dot(q));
        if (dp - dq).abs() > DEPTH_TOLERANCE_M {
            continue;
        }
        let bin = bins.entry(((dp + dq) / 2.0 / BIN_M).round() as i64).or_insert([
            0.0,
            f64::INFINITY,
            f64::NEG_INFINITY,
            f64::INFINITY,
            f64::NEG_INFINITY,
            0.0,
            0.0,
        ]);
        bin[0] += len;
        for x in [p.dot(&along), q.dot(&along)] {
            bin[1] = bin[1].min(x);
            bin[2] = bin[2].max(x);
        }
        for z in [p.z, q.z] {
            bin[3] = bin[3].min(z);
            bin[4] = bin[4].max(z);
        }
        bin[if upright { 5 } else { 6 }] += len;
    }
    let busiest = bins.values().map(|b| b[0]).fold(0.0, f64::max);
    let towards_viewer = normal.dot(viewpoint);
    bins.iter()
        .filter(|(_, b)| {
            b[0] >= busiest / 4.0
                && b[2] - b[1] >= MIN_WALL_SPAN_M
                && b[4] - b[3] >= MIN_WALL_SPAN_M
                && b[5] >= MIN_STANDING_SHARE * b[0]
                && b[6] > 0.0
        })
        .map(|(&k, _)| k as f64 * BIN_M)
        .min_by(|a, b| (towards_viewer - a).abs().total_cmp(&(towards_viewer - b).abs()))
        .map(|offset| Plane { normal, offset })
}

/// The horizontal direction (a unit vector) most level edge length runs along, in 1° bins modulo 180°.
fn plan_direction(segments: &[(Vec3, Vec3)]) -> Option<Vec3> {
    let mut bins = [0.0f64; 180];
    for (p, q) in segments {
        let d = q - p;
        let len = d.norm();
        if d.z.abs() > len * 5f64.to_radians().sin() {
            continue;
        }
        let azimuth = d.y.atan2(d.x).to_degrees().rem_euclid(180.0);
        bins[(azimuth.round() as usize) % 180] += len;
    }
    let (best, &weight) = bins.iter().enumerate().max_by(|a, b| a.1.total_cmp(b.1).then(b.0.cmp(&a.0)))?;
    (weight > 0.0).then(|| {
        let a = (best as f64).to_radians();
        Vec3::new(a.cos(), a.sin(), 0.0)
    })
}
