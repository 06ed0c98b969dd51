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
/// [`MIN_WALL_SPAN_M`] and at least a quarter of the length of the busiest depth. The `surface` lines (known to lie
/// in a surface: mortar courses, joints) add their length and spread to their depth, and a depth where they alone
/// make a quarter of the busiest one's length is a wall without the standing edges: on brick they mark the wall's
/// face, where the openings' outlines are outnumbered by the frames behind them. None without level edges or where
/// no depth qualifies.
pub(super) fn wall_from_edges(vertices: &[Vertex], edges: &[Edge], surface: &[[Vec3; 2]], viewpoint: &Vec3) -> Option<Plane> {
    let segments: Vec<(Vec3, Vec3)> = edges
        .iter()
        .filter(|e| e.observed())
        .map(|e| (vertices[e.a].point, vertices[e.b].point))
        .filter(|(p, q)| (q - p).norm() >= 0.05)
        .collect();
    let along = plan_direction(&segments)?;
    let normal = Vec3::z().cross(&along);
    let cos5 = 5f64.to_radians().cos();
    let surface = surface.iter().map(|[p, q]| (*p, *q, true));
    // Depth bin → [length, across from, across to, height from, height to, standing length, lying length, surface
    // lines' length].
    let mut bins: BTreeMap<i64, [f64; 8]> = BTreeMap::new();
    for (p, q, in_surface) in segments.iter().map(|(p, q)| (*p, *q, false)).chain(surface) {
        let d = q - p;
        let len = d.norm();
        let upright = d.z.abs() >= len * cos5;
        if !upright && d.dot(&along).abs() < len * cos5 {
            continue;
        }
        let (dp, dq) = (normal.dot(&p), normal.dot(&q));
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
        bin[if in_surface {
            7
        } else if upright {
            5
        } else {
            6
        }] += len;
    }
    let busiest = bins.values().map(|b| b[0]).fold(0.0, f64::max);
    let towards_viewer = normal.dot(viewpoint);
    bins.iter()
        .filter(|(_, b)| {
            // A row of sills stands only at its ends; a depth that the surface lines mark needs no standing edges.
            let standing = b[5] >= MIN_STANDING_SHARE * (b[5] + b[6]) && b[6] > 0.0;
            b[0] >= busiest / 4.0 && b[2] - b[1] >= MIN_WALL_SPAN_M && b[4] - b[3] >= MIN_WALL_SPAN_M && (standing || b[7] >= busiest / 4.0)
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

#[cfg(test)]
mod tests {
    use super::*;

    /// Segments as the model's vertices and observed edges.
    fn wire(segments: &[[Vec3; 2]]) -> (Vec<Vertex>, Vec<Edge>) {
        let vertices = segments.iter().flatten().map(|&point| Vertex { point, sigma: None }).collect();
        let edges = (0..segments.len())
            .map(|k| Edge {
                a: 2 * k,
                b: 2 * k + 1,
                line: k,
                origin: EdgeOrigin::Observed,
            })
            .collect();
        (vertices, edges)
    }

    /// A brick façade along x (wall face y = 0, cameras at y = -25) whose line stage kept ten windows' heads and
    /// sills on the face but few of their jambs, and every frame (all four sides) 10 cm behind it.
    fn facade() -> Vec<[Vec3; 2]> {
        let mut lines = Vec::new();
        for k in 0..10 {
            let (x0, x1) = (1.0 + 3.0 * k as f64, 2.4 + 3.0 * k as f64);
            for z in [1.0, 3.1] {
                lines.push([Vec3::new(x0, 0.0, z), Vec3::new(x1, 0.0, z)]);
                lines.push([Vec3::new(x0 + 0.05, 0.1, z), Vec3::new(x1 - 0.05, 0.1, z)]);
            }
            for x in [x0 + 0.05, x1 - 0.05] {
                lines.push([Vec3::new(x, 0.1, 1.0), Vec3::new(x, 0.1, 3.1)]);
            }
        }
        lines.push([Vec3::new(1.0, 0.0, 1.0), Vec3::new(1.0, 0.0, 3.1)]);
        lines
    }

    #[test]
    fn mortar_courses_put_the_wall_on_its_face_not_on_the_frames_behind_it() {
        let (vertices, edges) = wire(&facade());
        let viewpoint = Vec3::new(15.0, -25.0, 2.0);
        // The face carries 28 m lying and 2.1 m standing: a row of sills by its edges alone; the frames' plane wins.
        let alone = wall_from_edges(&vertices, &edges, &[], &viewpoint).expect("a wall");
        assert!((alone.offset.abs() - 0.1).abs() < 0.011, "{alone:?}");
        // Courses every 7.5 cm between the windows' rows lie in the face.
        let courses: Vec<[Vec3; 2]> = (0..40)
            .map(|i| {
                let z = 3.2 + 0.075 * i as f64;
                [Vec3::new(0.0, 0.0, z), Vec3::new(30.0, 0.0, z)]
            })
            .collect();
        let wall = wall_from_edges(&vertices, &edges, &courses, &viewpoint).expect("a wall");
        assert!(wall.offset.abs() < 0.011, "{wall:?}");
        // A handful of surface lines (a plastered wall's few joints) do not make a wall.
        let joints = [4.0, 5.0].map(|z| [Vec3::new(5.0, 0.0, z), Vec3::new(6.0, 0.0, z)]);
        let few = wall_from_edges(&vertices, &edges, &joints, &viewpoint).expect("a wall");
        assert_eq!((few.normal, few.offset), (alone.normal, alone.offset));
    }
}
