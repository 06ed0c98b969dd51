//! Depth layers: the planes a façade's edges share, as a prior on lines whose images fix their place poorly.
//!
//! Seen from strips a few metres long at 20–30 m, a pixel across a line is decimetres of depth: the images fix a
//! plumb line's depth to a few centimetres at best and a level line's hardly. But a façade's edges lie in a few
//! planes parallel to its walls: the wall's face, the fronts of the sills, the backs of the reveals where the
//! frames sit, the frames' faces; and its plumb edges in a few planes square to them (the jambs of windows stacked
//! storey above storey). Each opening's recess has a depth of its own, so the planes are local: the lines whose
//! images fix them well and whose midpoints lie within `radius_m` of a line's find them (the densest clusters of
//! their coordinates along the wall's normal, or along the wall), and the line moves onto the densest within
//! `k_sigma` of its own standard deviation, where its images still show it there.
//!
//! Measured on the tuning buildings (docs/lines3d.md, "Depth layers"): it places plumb lines and the lines of
//! plastered recesses better, and pulls the sills (level lines 6 cm proud of the wall, which no well-fixed line
//! shares) onto the wall; `linefit` ships it off.
use lineflow_photogrammetry::{Camera, Vec3};
use rayon::prelude::*;

use crate::multiview::{line_support, MultiviewLine, MultiviewParams};
use crate::plumb_level::plan_azimuth;
use crate::segments::SlaveSegments;

/// Settings of the depth layers.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LayerParams {
    /// Lines within this distance of each other's coordinate are one layer, metres.
    pub bandwidth_m: f64,
    /// Lines a layer needs.
    pub min_lines: usize,
    /// Lines the images fix to this standard deviation (along the axis) or better define the layers, metres.
    pub define_sigma_m: f64,
    /// A line moves onto a layer within this many of its standard deviations...
    pub k_sigma: f64,
    /// ... and this many metres.
    pub max_move_m: f64,
    /// Lines within this angle of plumb or of level along an axis take part, degrees.
    pub max_angle_deg: f64,
    /// The layers near a line come from the lines whose midpoints lie within this distance of its own across the
    /// axis, metres (each opening's recess has a depth of its own); 0: the whole building.
    pub radius_m: f64,
}

impl Default for LayerParams {
    fn default() -> Self {
        Self {
            bandwidth_m: 0.01,
            min_lines: 4,
            define_sigma_m: 0.03,
            k_sigma: 3.0,
            max_move_m: 0.15,
            max_angle_deg: 1.0,
            radius_m: 1.5,
        }
    }
}

/// What [`snap_to_layers`] did.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct LayerStats {
    /// Lines that found a layer within reach, across the wall (depths) and along it.
    pub layers: [usize; 2],
    /// Lines moved onto a layer.
    pub moved: usize,
    /// Lines a layer was near but whose images did not show them there.
    pub refused: usize,
}

/// One line's coordinate along one axis and how well its images fix it.
#[derive(Debug, Clone, Copy)]
struct Offset {
    line: usize,
    axis: usize,
    coord: f64,
    sigma: f64,
    /// The line's midpoint.
    mid: Vec3,
}

/// Moves the lines the images leave uncertain onto the layers the well-fixed lines share (module docs). The axes
/// are the plan direction of the level lines and the horizontal square to it; lines need `mv.min_views` images.
pub fn snap_to_layers(
    camera: &Camera,
    lines: &mut [[Vec3; 2]],
    views: &[SlaveSegments],
    mv: &MultiviewParams,
    p: &LayerParams,
) -> LayerStats {
    let mut stats = LayerStats::default();
    let Some(azimuth) = plan_azimuth(lines, p.max_angle_deg.max(1.0)) else {
        return stats;
    };
    let along = Vec3::new(azimuth.cos(), azimuth.sin(), 0.0);
    let axes = [Vec3::new(-along.y, along.x, 0.0), along];
    let cos_max = p.max_angle_deg.to_radians().cos();
    let supports: Vec<Option<MultiviewLine>> = lines.par_iter().map(|[a, b]| line_support(camera, *a, *b, views, mv)).collect();
    let offsets: Vec<Offset> = lines
        .iter()
        .zip(&supports)
        .enumerate()
        .flat_map(|(i, ([a, b], support))| {
            let d = (b - a).try_normalize(1e-12);
            // The axes a line is square to: a plumb line both, a level line the one across it.
            let square: Vec<usize> = match d {
                Some(d) if d.z.abs() >= cos_max => vec![0, 1],
                Some(d) if d.dot(&axes[1]).abs() >= cos_max => vec![0],
                Some(d) if d.dot(&axes[0]).abs() >= cos_max => vec![1],
                _ => Vec::new(),
            };
            let mid = (a + b) * 0.5;
            square.into_iter().filter_map(move |k| {
                let s = support.as_ref()?;
                Some(Offset {
                    line: i,
                    axis: k,
                    coord: axes[k].dot(&mid),
                    sigma: s.sigma_along(&axes[k]),
                    mid,
                })
            })
        })
        .collect();
    let mut shift = vec![Vec3::zeros(); lines.len()];
    for (k, axis) in axes.iter().enumerate() {
        let mine: Vec<&Offset> = offsets.iter().filter(|o| o.axis == k).collect();
        let fixed: Vec<&Offset> = mine.iter().copied().filter(|o| o.sigma <= p.define_sigma_m).collect();
        let moves: Vec<Option<f64>> = mine
            .par_iter()
            .map(|o| {
                let reach = (p.k_sigma * o.sigma).min(p.max_move_m);
                let near: Vec<(f64, f64)> = fixed
                    .iter()
                    .filter(|f| f.line != o.line && (f.coord - o.coord).abs() <= reach + p.bandwidth_m)
                    .filter(|f| p.radius_m <= 0.0 || ((f.mid - o.mid) - axis * axis.dot(&(f.mid - o.mid))).norm() <= p.radius_m)
                    .map(|f| (f.coord, 1.0 / f.sigma.max(1e-4).powi(2)))
                    .collect();
                layer_within_reach(&near, o.coord, reach, p).map(|l| l - o.coord)
            })
            .collect();
        stats.layers[k] += moves.iter().filter(|m| m.is_some()).count();
        for (o, m) in mine.iter().zip(moves) {
            if let Some(d) = m {
                shift[o.line] += axis * d;
            }
        }
    }
    // A move the line's own images contradict is no move: the layer is a prior, the images decide. They contradict
    // it when more than one in five of the images that show the line where it is no longer show it there.
    let decided: Vec<Option<bool>> = lines
        .par_iter()
        .zip(&shift)
        .zip(&supports)
        .map(|(([a, b], s), before)| {
            let before = before.as_ref()?;
            (s.norm() > 1e-4)
                .then(|| line_support(camera, a + s, b + s, views, mv).is_some_and(|after| 5 * after.views >= 4 * before.views))
        })
        .collect();
    for ((line, s), d) in lines.iter_mut().zip(&shift).zip(decided) {
        match d {
            Some(true) => {
                line[0] += s;
                line[1] += s;
                stats.moved += 1;
            }
            Some(false) => stats.refused += 1,
            None => {}
        }
    }
    stats
}

/// The layer within `reach` of `coord` among the coordinates `near` (with their weights): the densest
/// places, `min_lines` coordinates within `bandwidth_m`, each the weighted mean of those; none when no such place
/// lies within reach.
fn layer_within_reach(near: &[(f64, f64)], coord: f64, reach: f64, p: &LayerParams) -> Option<f64> {
    near.iter()
        .filter_map(|&(c, _)| {
            let members: Vec<&(f64, f64)> = near.iter().filter(|(d, _)| (d - c).abs() <= p.bandwidth_m).collect();
            if members.len() < p.min_lines {
                return None;
            }
            let (sum, weight) = members.iter().fold((0.0, 0.0), |(s, t), (d, w)| (s + d * w, t + w));
            let layer = sum / weight;
            ((layer - coord).abs() <= reach).then_some((members.len(), layer))
        })
        .max_by(|x, y| x.0.cmp(&y.0).then((y.1 - coord).abs().total_cmp(&(x.1 - coord).abs())))
        .map(|(_, layer)| layer)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::segments::FrameSegments;
    use lineflow_messages::Segment2;
    use lineflow_photogrammetry::{rotation_from_opk, Pose};

    /// Five cameras 25 m in front of the wall y = 0, half a metre apart: a pixel is 6 mm on the wall and about
    /// 8 cm of depth at the widest baseline, as on a façade filmed from the street.
    fn setup() -> (Camera, Vec<Pose>) {
        let camera = Camera::pinhole(4000, 3000, 0.005, 20.0);
        let poses = (0..5)
            .map(|k| Pose {
                center: Vec3::new(k as f64 * 0.5 - 1.0, -25.0, 1.5),
                rotation: rotation_from_opk(std::f64::consts::FRAC_PI_2, 0.0, 0.0),
            })
            .collect();
        (camera, poses)
    }

    /// Every camera's 2-D segments of the true lines.
    fn frames(camera: &Camera, poses: &[Pose], truth: &[[Vec3; 2]]) -> Vec<FrameSegments> {
        poses
            .iter()
            .map(|pose| {
                let segments: Vec<Segment2> = truth
                    .iter()
                    .enumerate()
                    .map(|(i, [a, b])| Segment2 {
                        id: i as u32,
                        start_px: pose.project(camera, a).unwrap(),
                        end_px: pose.project(camera, b).unwrap(),
                        ..Default::default()
                    })
                    .collect();
                FrameSegments::new(camera, &segments, 10.0)
            })
            .collect()
    }

    fn plumb(x: f64, depth: f64) -> [Vec3; 2] {
        [Vec3::new(x, depth, 0.5), Vec3::new(x, depth, 2.0)]
    }

    fn snapped(truth: &[[Vec3; 2]], estimate: &[[Vec3; 2]], p: &LayerParams) -> (Vec<[Vec3; 2]>, LayerStats) {
        let (camera, poses) = setup();
        let frames = frames(&camera, &poses, truth);
        let views: Vec<SlaveSegments> = poses
            .iter()
            .zip(&frames)
            .map(|(&pose, segments)| SlaveSegments { pose, segments })
            .collect();
        let mut lines = estimate.to_vec();
        let stats = snap_to_layers(&camera, &mut lines, &views, &MultiviewParams::default(), p);
        (lines, stats)
    }

    /// A recess 0.3 m deep: the jambs of its openings (every 0.2 m here) fix its depth; one more, placed 3 cm too
    /// far forward, and a level line (the plan direction needs one).
    fn recess(extra: [Vec3; 2]) -> (Vec<[Vec3; 2]>, Vec<[Vec3; 2]>) {
        let mut truth: Vec<[Vec3; 2]> = (0..8).map(|k| plumb(-0.8 + 0.2 * k as f64, 0.3)).collect();
        truth.push([Vec3::new(-0.9, 0.0, 2.4), Vec3::new(0.9, 0.0, 2.4)]);
        truth.push(extra);
        let estimate = truth.clone();
        (truth, estimate)
    }

    #[test]
    fn a_line_placed_off_its_recess_moves_onto_the_depth_its_neighbours_share() {
        let (truth, mut estimate) = recess(plumb(0.8, 0.3));
        estimate[9] = plumb(0.8, 0.27);
        let p = LayerParams {
            define_sigma_m: 0.03,
            min_lines: 4,
            ..LayerParams::default()
        };
        let (lines, stats) = snapped(&truth, &estimate, &p);
        assert!(stats.moved >= 1, "{stats:?}");
        assert!(
            (lines[9][0].y - 0.3).abs() < 0.005 && (lines[9][1].y - 0.3).abs() < 0.005,
            "{:?}",
            lines[9]
        );
        // Across the wall it stays where the images put it.
        assert!((lines[9][0].x - 0.8).abs() < 1e-9);
        // Fewer lines than a layer needs: nothing moves.
        let few = LayerParams { min_lines: 12, ..p };
        let (lines, stats) = snapped(&truth, &estimate, &few);
        assert_eq!(stats.moved, 0, "{stats:?}");
        assert_eq!(lines[9], estimate[9]);
    }

    #[test]
    fn a_move_the_images_contradict_is_refused() {
        // A frame 15 cm behind the recess's jambs, placed where its images show it: the layer within reach is
        // refused, since its images put it two pixels off there.
        let (truth, estimate) = recess(plumb(0.8, 0.45));
        let p = LayerParams {
            define_sigma_m: 0.03,
            min_lines: 4,
            k_sigma: 100.0,
            max_move_m: 0.16,
            ..LayerParams::default()
        };
        let (lines, stats) = snapped(&truth, &estimate, &p);
        assert!(stats.refused >= 1, "{stats:?}");
        assert_eq!(lines[9], estimate[9]);
    }
}
