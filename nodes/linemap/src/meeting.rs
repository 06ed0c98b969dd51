//! Level lines take their depth from the vertical lines they meet.
//!
//! A level edge near an opening is rarely alone in the images: the head and the frame's top, the sill's top and
//! front, lie one to four pixels apart, and their blurred steps merge. Measured on the brick and plaster tuning
//! buildings at full size with the true poses, the 2-D segments of level edges near windows lie 0.2–0.5 px off
//! the edge (median), those of vertical edges 0.03–0.08 px, and those of long isolated level edges (eaves)
//! 0.005 px. The strips see such a bundle from above and below, so the bias differs between them, and two strips
//! 3 m apart at 25 m turn a 0.3 px disagreement into 2–3 GSD of depth. The verticals the level line meets (the
//! jambs of its opening, the frame's sides) are placed by images spread along the strip and keep their sub-pixel
//! accuracy: where a level line's end meets one, within reach along the wall and within `k` joint σ in depth,
//! the line takes that vertical's depth.
use lineflow_photogrammetry::Vec3;

use crate::guide::Guide;
use crate::line::MappedLine;

/// Settings of the corner depths.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MeetingParams {
    /// A level line's end meets a vertical when their depths differ by at most this many joint σ; 0 turns the
    /// pass off.
    pub k: f64,
    /// How far a level line's end may lie from the vertical (along the wall, and beyond the vertical's ends),
    /// pixels of the nearest image.
    pub reach_px: f64,
}

/// A line this close to the vertical (sine of the angle) is a vertical.
const VERTICAL_SIN: f64 = 0.01;
/// A line this close to level and to its wall's plane (sine of the angle) is a level line of the wall.
const LEVEL_SIN: f64 = 0.02;
/// Verticals and level lines this far in front of or behind a wall belong to it, metres (reveals, frames,
/// sills, pilasters and balcony fronts; not the far side of the building).
const WALL_DEPTH_M: f64 = 1.5;

/// A vertical line over a wall: its position along the wall, its height span, its depth and its depth σ.
struct Vertical {
    along: f64,
    z: [f64; 2],
    depth: f64,
    sigma: f64,
}

/// Moves every level line of a wall whose end meets a vertical line onto that vertical's depth, wall by wall;
/// `metres_per_px` gives the size of a pixel at a point (in the nearest image). Returns how many lines moved.
pub fn settle_on_verticals(lines: &mut [MappedLine], guide: &Guide, metres_per_px: impl Fn(&Vec3) -> f64, p: &MeetingParams) -> usize {
    if p.k <= 0.0 {
        return 0;
    }
    let normals: Vec<Vec3> = guide.wall_normals().collect();
    let mut moved = vec![false; lines.len()];
    for (w, normal) in normals.iter().enumerate() {
        let Some(along) = Vec3::z().cross(normal).try_normalize(1e-9) else {
            continue;
        };
        let depth = |q: &Vec3| guide.in_front_of_wall(w, q, WALL_DEPTH_M).filter(|d| d.abs() <= WALL_DEPTH_M);
        let verticals: Vec<Vertical> = lines
            .iter()
            .filter(|l| direction(l).is_some_and(|d| d.z.abs() >= (1.0 - VERTICAL_SIN * VERTICAL_SIN).sqrt()))
            .filter_map(|l| {
                let (d0, d1) = (depth(&l.start)?, depth(&l.end)?);
                Some(Vertical {
                    along: along.dot(&(l.start + l.end)) * 0.5,
                    z: [l.start.z.min(l.end.z), l.start.z.max(l.end.z)],
                    depth: 0.5 * (d0 + d1),
                    sigma: l.sigma_along(normal),
                })
            })
            .collect();
        if verticals.is_empty() {
            continue;
        }
        for (l, moved) in lines.iter_mut().zip(&mut moved) {
            let Some(d) = direction(l) else { continue };
            if d.z.abs() > LEVEL_SIN || d.dot(normal).abs() > LEVEL_SIN || *moved {
                continue;
            }
            let sigma = l.sigma_along(normal);
            // The depth shift to the vertical an end meets, and that vertical's σ.
            let meet = |e: &Vec3| -> Option<(f64, f64)> {
                let de = depth(e)?;
                let reach = p.reach_px * metres_per_px(e);
                let (u, z) = (along.dot(e), e.z);
                verticals
                    .iter()
                    .filter(|v| (v.along - u).abs() <= reach && z >= v.z[0] - reach && z <= v.z[1] + reach)
                    .map(|v| (v.depth - de, (v.depth - de).abs() / sigma.hypot(v.sigma).max(1e-6), v.sigma))
                    .filter(|&(_, score, _)| score <= p.k)
                    .min_by(|a, b| a.1.total_cmp(&b.1))
                    .map(|(shift, _, sigma)| (shift, sigma))
            };
            let shift = match (meet(&l.start), meet(&l.end)) {
                (None, None) => continue,
                (Some((s, _)), None) | (None, Some((s, _))) => s,
                // Both ends meet verticals: one depth if they agree, else the nearer (a frame's jamb at one end
                // and the opening's at the other).
                (Some((a, sa)), Some((b, sb))) if (a - b).abs() <= p.k * sa.hypot(sb) => 0.5 * (a + b),
                (Some((a, _)), Some((b, _))) => {
                    if a.abs() <= b.abs() {
                        a
                    } else {
                        b
                    }
                }
            };
            l.start += normal * shift;
            l.end += normal * shift;
            l.from_corner = true;
            *moved = true;
        }
    }
    moved.iter().filter(|&&m| m).count()
}

/// Unit direction of a line, if it has a length.
fn direction(l: &MappedLine) -> Option<Vec3> {
    (l.end - l.start).try_normalize(1e-12)
}

#[cfg(test)]
mod tests {
    use super::*;
    use lineflow_photogrammetry::Mat3;

    use crate::guide::one_wall as guide;

    /// A line from `a` to `b` with depth σ `sigma` (across it in the other direction: 1 mm).
    fn line(a: [f64; 3], b: [f64; 3], sigma: f64) -> MappedLine {
        MappedLine {
            start: Vec3::from(a),
            end: Vec3::from(b),
            n_segments: 4,
            n_images: 4,
            rms_m: 0.001,
            across_cov: Mat3::from_diagonal(&Vec3::new(1e-6, sigma * sigma, 1e-6)),
            from_corner: false,
        }
    }

    fn params() -> MeetingParams {
        MeetingParams { k: 3.0, reach_px: 4.0 }
    }

    /// 7 mm pixels everywhere.
    fn gsd(_: &Vec3) -> f64 {
        0.007
    }

    #[test]
    fn a_level_line_takes_the_depth_of_the_jambs_it_meets() {
        // An opening 2 cm deep: jambs at y = 0 (the outline) and y = 0.02 (the frame), σ 3 mm. Its head measured
        // 2 cm behind the outline with σ 2 cm, its ends 1 cm from the jambs' ends: it joins the outline (the
        // nearer depth in σ), both ends agreeing.
        let mut lines = vec![
            line([2.0, 0.0, 1.0], [2.0, 0.0, 2.5], 0.003),
            line([3.2, 0.0, 1.0], [3.2, 0.0, 2.5], 0.003),
            line([2.0, 0.05, 1.0], [2.0, 0.05, 2.5], 0.003),
            line([3.2, 0.05, 1.0], [3.2, 0.05, 2.5], 0.003),
            line([2.01, 0.018, 2.51], [3.19, 0.018, 2.51], 0.02),
        ];
        assert_eq!(settle_on_verticals(&mut lines, &guide(), gsd, &params()), 1);
        let head = lines[4];
        assert!(head.start.y.abs() < 1e-12 && head.end.y.abs() < 1e-12, "{head:?}");
        assert!(head.from_corner);
        assert_eq!(head.start.z, 2.51, "only the depth moves");
    }

    #[test]
    fn lines_out_of_reach_or_far_in_depth_keep_theirs() {
        // A jamb at y = 0; a level line 10 px along the wall beyond it; a sill 6 cm proud with σ 5 mm, which its
        // segments place clearly; a line across the wall (a reveal's depth edge).
        let mut lines = vec![
            line([2.0, 0.0, 1.0], [2.0, 0.0, 2.5], 0.003),
            line([2.07, 0.01, 2.5], [3.0, 0.01, 2.5], 0.02),
            line([1.5, -0.06, 1.0], [2.0, -0.06, 1.0], 0.005),
            line([2.0, 0.0, 2.5], [2.0, 0.2, 2.5], 0.02),
        ];
        let before = lines.clone();
        assert_eq!(settle_on_verticals(&mut lines, &guide(), gsd, &params()), 0);
        assert_eq!(lines, before);
        let off = MeetingParams { k: 0.0, ..params() };
        let mut near = vec![
            line([2.0, 0.0, 1.0], [2.0, 0.0, 2.5], 0.003),
            line([2.0, 0.01, 2.5], [3.0, 0.01, 2.5], 0.02),
        ];
        assert_eq!(settle_on_verticals(&mut near, &guide(), gsd, &off), 0, "k = 0 is off");
        assert_eq!(settle_on_verticals(&mut near, &Guide::default(), gsd, &params()), 0, "no walls");
    }
}
