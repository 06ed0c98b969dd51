//! Level edges between plumb ones: an opening's head and sill hypothesised between the ends of its jambs and kept
//! where the images show them.
//!
//! Seen from two strips a few metres apart, a short level edge is placed in depth only by the baseline between the
//! strips (decimetres per pixel at 25 m), and most window heads and sills are missed by both line designs; their
//! jambs, plumb lines seen across the strip's own baseline, are placed well, and both ends of most missed heads and
//! sills meet jambs that were found (docs/lines3d.md, "Bridges"). So a level line is hypothesised between the upper
//! ends, and between the lower ends, of two plumb lines side by side at one height along the façade, and
//! re-estimated from every image's 2-D segments along it: the images fix its height, the jambs its depth.
use lineflow_linegeom::{
    azimuth_mod_quarter, covered_shares, plan_azimuth, refine_line, signed_quarter, MultiviewParams, Sight, SlaveSegments,
};
use lineflow_photogrammetry::{Camera, Pose, Vec3};

use crate::{FitParams, Merged};

/// Plumb lines shorter than this are no jambs, metres.
const MIN_JAMB_M: f64 = 0.3;
/// A bridge shorter than this joins a line to its own reveal or frame, not to the opening's other side, metres.
const MIN_SPAN_M: f64 = 0.3;
/// A line within this of plumb is a jamb, degrees (linefit turns lines within `snap_deg` onto plumb first).
const PLUMB_DEG: f64 = 1.0;
/// A bridge runs along the façade's plan direction within this, degrees.
const ALONG_DEG: f64 = 3.0;
/// A bridge the lines already cover this much of is there already.
const MAX_COVERED: f64 = 0.5;

/// An upper or lower end of a plumb line.
#[derive(Clone, Copy)]
struct End {
    at: Vec3,
    line: usize,
}

/// The level lines between the ends of plumb lines in `lines` that the images show and `lines` do not already
/// have: `p.bridge_max_span_m` the longest span, `p.bridge_height_m` the largest difference in height between the
/// two ends; a hypothesis is re-estimated from the 2-D segments of `views` found within `p.bridge_search_px` of its
/// projection, then again within `p.multiview_max_distance_px`, and kept when at least `p.multiview_min_views`
/// images and `p.bridge_min_share` of those whose frame holds it show it.
pub fn bridges(camera: &Camera, lines: &[Merged], views: &[SlaveSegments], p: &FitParams) -> Vec<Merged> {
    let ends: Vec<[Vec3; 2]> = lines.iter().map(|l| [l.start, l.end]).collect();
    let Some(plan) = plan_azimuth(&ends, p.snap_deg) else {
        return Vec::new();
    };
    let cos = PLUMB_DEG.to_radians().cos();
    let (mut tops, mut bottoms) = (Vec::new(), Vec::new());
    for (k, [a, b]) in ends.iter().enumerate() {
        let d = b - a;
        if d.norm() < MIN_JAMB_M || d.z.abs() < cos * d.norm() {
            continue;
        }
        let (low, high) = if a.z < b.z { (*a, *b) } else { (*b, *a) };
        tops.push(End { at: high, line: k });
        bottoms.push(End { at: low, line: k });
    }
    let mut candidates: Vec<[Vec3; 2]> = Vec::new();
    for ends in [&tops, &bottoms] {
        candidates.extend(neighbour_pairs(ends, plan, p));
    }
    let params = p.multiview();
    let poses: Vec<Pose> = views.iter().map(|v| v.pose).collect();
    let sight = Sight { camera, poses: &poses };
    use rayon::prelude::*;
    let seen: Vec<Option<Merged>> = candidates
        .par_iter()
        .map(|[a, b]| {
            // The jambs' ends may stop short of the corner: the first search reaches farther across.
            let first = refine_line(
                camera,
                *a,
                *b,
                views,
                &MultiviewParams {
                    max_distance_px: p.bridge_search_px,
                    ..params
                },
            )?;
            let r = refine_line(camera, first.start, first.end, views, &params)?;
            if (r.views as f64) < p.bridge_min_share * f64::from(sight.images_seeing(&[r.start, r.end])) {
                return None;
            }
            Some(Merged {
                start: r.start,
                end: r.end,
                n_points: 0,
                n_images: r.views as u32,
                rms_m: 0.0,
                fragments: Vec::new(),
            })
        })
        .collect();
    let seen: Vec<Merged> = seen.into_iter().flatten().collect();
    let rule = p.cover();
    let theirs: Vec<[Vec3; 2]> = seen.iter().map(|l| [l.start, l.end]).collect();
    let shares = covered_shares(&ends, &theirs, &rule);
    // Two bridges of one edge (from either jamb's end, or a jamb and its frame): the first, in order, stays.
    let mut out: Vec<Merged> = Vec::new();
    let mut taken: Vec<[Vec3; 2]> = Vec::new();
    for ((l, ends), share) in seen.into_iter().zip(theirs).zip(shares) {
        if share < MAX_COVERED && covered_shares(&taken, &[ends], &rule)[0] < MAX_COVERED {
            taken.push(ends);
            out.push(l);
        }
    }
    out
}

/// For each end, the nearest other end on either side along the façade's plan direction (`plan`, radians modulo
/// 90°) at about its height: the candidate bridges, each pair once, in a fixed order.
fn neighbour_pairs(ends: &[End], plan: f64, p: &FitParams) -> Vec<[Vec3; 2]> {
    // By height, so that each end looks only at those within `bridge_height_m` of it.
    let mut by_z: Vec<usize> = (0..ends.len()).collect();
    by_z.sort_by(|&a, &b| ends[a].at.z.total_cmp(&ends[b].at.z).then(a.cmp(&b)));
    let mut pairs: Vec<(usize, usize)> = Vec::new();
    for (i, e) in ends.iter().enumerate() {
        let mut nearest: [Option<(f64, usize)>; 2] = [None, None];
        let from = by_z.partition_point(|&k| ends[k].at.z < e.at.z - p.bridge_height_m);
        for &j in by_z[from..].iter().take_while(|&&k| ends[k].at.z <= e.at.z + p.bridge_height_m) {
            let f = &ends[j];
            if f.line == e.line {
                continue;
            }
            let d = f.at - e.at;
            let span = d.xy().norm();
            if !(MIN_SPAN_M..=p.bridge_max_span_m).contains(&span) {
                continue;
            }
            let off = signed_quarter(azimuth_mod_quarter(&Vec3::new(d.x, d.y, 0.0)) - plan).abs();
            if off > ALONG_DEG.to_radians() {
                continue;
            }
            // The two sides: along the plan direction itself or its square, whichever the offset follows.
            let side = usize::from(d.x * plan.cos() + d.y * plan.sin() + (-d.x * plan.sin() + d.y * plan.cos()) > 0.0);
            if nearest[side].is_none_or(|(s, _)| span < s) {
                nearest[side] = Some((span, j));
            }
        }
        pairs.extend(nearest.iter().flatten().map(|&(_, j)| (i.min(j), i.max(j))));
    }
    pairs.sort_unstable();
    pairs.dedup();
    pairs
        .into_iter()
        .map(|(i, j)| {
            let (a, b) = (ends[i].at, ends[j].at);
            let z = (a.z + b.z) / 2.0;
            [Vec3::new(a.x, a.y, z), Vec3::new(b.x, b.y, z)]
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use lineflow_linegeom::FrameSegments;
    use lineflow_messages::Segment2;
    use lineflow_photogrammetry::rotation_from_opk;

    fn line(a: [f64; 3], b: [f64; 3]) -> Merged {
        Merged {
            start: Vec3::from(a),
            end: Vec3::from(b),
            n_points: 10,
            n_images: 9,
            rms_m: 0.002,
            fragments: Vec::new(),
        }
    }

    /// A strip of nine cameras 12 m in front of the wall y = 0, every metre along x, each with the 2-D segment of
    /// a window's head (x from -0.5 to 0.5 at z = 2.5) and nothing else.
    fn strip(camera: &Camera) -> Vec<(Pose, FrameSegments)> {
        let (a, b) = (Vec3::new(-0.5, 0.0, 2.5), Vec3::new(0.5, 0.0, 2.5));
        (0..9)
            .map(|k| {
                let pose = Pose {
                    center: Vec3::new(k as f64 - 4.0, -12.0, 1.5),
                    rotation: rotation_from_opk(std::f64::consts::FRAC_PI_2, 0.0, 0.0),
                };
                let segment = Segment2 {
                    id: 1,
                    start_px: pose.project(camera, &a).unwrap(),
                    end_px: pose.project(camera, &b).unwrap(),
                    ..Default::default()
                };
                (pose, FrameSegments::new(camera, &[segment], 10.0))
            })
            .collect()
    }

    #[test]
    fn a_head_the_images_show_is_bridged_between_its_jambs_and_nothing_else_is() {
        let camera = Camera::pinhole(4000, 3000, 0.005, 20.0);
        let frames = strip(&camera);
        let views: Vec<SlaveSegments> = frames
            .iter()
            .map(|(pose, segments)| SlaveSegments { pose: *pose, segments })
            .collect();
        // Jambs stopping 1 cm (3 px) short of the head; their lower ends (z = 1) have no sill in the images; a level
        // ground line gives the façade's direction.
        let mut lines = vec![
            line([-0.5, 0.0, 1.0], [-0.5, 0.0, 2.49]),
            line([0.5, 0.0, 2.49], [0.5, 0.0, 1.0]),
            line([-3.0, 0.0, 0.0], [3.0, 0.0, 0.0]),
        ];
        let p = FitParams {
            bridge_max_span_m: 4.0,
            ..FitParams::default()
        };
        let found = bridges(&camera, &lines, &views, &p);
        assert_eq!(found.len(), 1, "the head only, not the sill the images do not show");
        let head = &found[0];
        for end in [head.start, head.end] {
            assert!((end.z - 2.5).abs() < 0.005 && end.y.abs() < 0.005, "{end:?}");
            assert!((end.x.abs() - 0.5).abs() < 0.005, "{end:?}");
        }
        assert_eq!(head.n_images, 9);
        // Already there: no bridge. Off: none.
        lines.push(line([-0.5, 0.0, 2.5], [0.5, 0.0, 2.5]));
        assert!(bridges(&camera, &lines, &views, &p).is_empty());
        lines.pop();
        let off = FitParams {
            bridge_max_span_m: 0.8,
            ..p.clone()
        };
        assert!(bridges(&camera, &lines, &views, &off).is_empty(), "the jambs are 1 m apart");
    }
}
