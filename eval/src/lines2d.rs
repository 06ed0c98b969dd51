//! 2-D lines: per image, the share of the visible true edges' length that estimated segments cover (recall),
//! and the share of estimated length that lies on visible true edges (precision), at 1.5 px and 5°, compared in
//! corrected (distortion-free) pixel coordinates where straight edges are straight.
use lineflow_formats::Line2Row;
use lineflow_photogrammetry::Vec3;
use rayon::prelude::*;

use crate::geometry::{bounds, Grid, Seg};
use crate::Truth;

/// Distance tolerance, pixels.
pub const TOL_PX: f64 = 1.5;
/// Angle tolerance, degrees.
pub const TOL_DEG: f64 = 5.0;

#[derive(Debug, Clone)]
pub struct ImageScores {
    pub image: String,
    pub n_true: usize,
    pub n_estimated: usize,
    pub recall: f64,
    pub precision: f64,
    /// Lengths behind the shares, corrected pixels: true, true covered, estimated, estimated on truth.
    pub lengths: [f64; 4],
}

#[derive(Debug, Clone)]
pub struct Lines2dReport {
    pub images: Vec<ImageScores>,
    /// Over all images, weighted by length.
    pub recall: f64,
    pub precision: f64,
}

/// The parts of the true edges that frame `frame` sees, as segments in corrected pixels (z = 0).
pub fn visible_truth(truth: &Truth, frame: usize) -> Vec<Seg> {
    let cam = truth.scene.camera();
    let pose = &truth.poses[frame].pose;
    let ps = cam.pixel_size_mm;
    let world = truth.scene.world();
    truth
        .lines
        .par_iter()
        .flat_map_iter(|l| {
            let ends = [pose.project_ideal(cam, &l.start), pose.project_ideal(cam, &l.end)];
            let approx_px = match ends {
                [Some(a), Some(b)] => ((a[0] - b[0]).hypot(a[1] - b[1]) / ps).min(4000.0),
                _ => 400.0,
            };
            let n = ((approx_px / 2.0).ceil() as usize).clamp(4, 2000);
            let seen: Vec<Option<[f64; 2]>> = (0..=n)
                .map(|k| {
                    let p = l.start + (l.end - l.start) * (k as f64 / n as f64);
                    let ideal = pose.project_ideal(cam, &p)?;
                    let px = cam.ideal_to_pixel(ideal)?;
                    (cam.contains(px, 0.0) && world.visible(&pose.center, &p)).then_some([ideal[0] / ps, ideal[1] / ps])
                })
                .collect();
            let mut runs = Vec::new();
            let mut start: Option<[f64; 2]> = None;
            let mut last = [0.0; 2];
            for s in seen.iter().chain(std::iter::once(&None)) {
                match (s, start) {
                    (Some(p), None) => {
                        start = Some(*p);
                        last = *p;
                    }
                    (Some(p), Some(_)) => last = *p,
                    (None, Some(a)) => {
                        if (a[0] - last[0]).hypot(a[1] - last[1]) >= 2.0 {
                            runs.push(Seg::new(Vec3::new(a[0], a[1], 0.0), Vec3::new(last[0], last[1], 0.0)));
                        }
                        start = None;
                    }
                    (None, None) => {}
                }
            }
            runs
        })
        .collect()
}

/// Length of `from` within `TOL_PX` of, and within `TOL_DEG` of the direction of, a segment of `to`.
fn covered(from: &[Seg], to: &[Seg], grid: &Grid) -> (f64, f64) {
    let (mut total, mut ok) = (0.0, 0.0);
    for s in from {
        let n = (s.length().ceil() as usize).max(1);
        for (p, w) in s.samples(n) {
            total += w;
            let hit = grid.near(&p).iter().any(|&i| {
                let t = &to[i as usize];
                t.distance(&p) <= TOL_PX && t.angle_deg(s) <= TOL_DEG
            });
            if hit {
                ok += w;
            }
        }
    }
    (total, ok)
}

fn grid_of(set: &[Seg]) -> Grid {
    let (lo, hi) = bounds(set.iter().flat_map(|s| [&s.a, &s.b]));
    let mut g = Grid::new(8.0, lo - Vec3::repeat(8.0), hi + Vec3::repeat(8.0));
    for (i, s) in set.iter().enumerate() {
        let (a, b) = bounds([&s.a, &s.b]);
        g.insert(i as u32, a, b, TOL_PX);
    }
    g
}

/// The scores of frame `frame` from the rows of its image among `rows`.
pub fn score_image(truth: &Truth, frame: usize, rows: &[Line2Row]) -> ImageScores {
    let cam = truth.scene.camera();
    let ps = cam.pixel_size_mm;
    let name = &truth.poses[frame].image;
    let gt = visible_truth(truth, frame);
    let est: Vec<Seg> = rows
        .iter()
        .filter(|r| &r.image == name)
        .map(|r| {
            let (a, b) = (cam.pixel_to_ideal(r.start_px), cam.pixel_to_ideal(r.end_px));
            Seg::new(Vec3::new(a[0] / ps, a[1] / ps, 0.0), Vec3::new(b[0] / ps, b[1] / ps, 0.0))
        })
        .filter(|s| s.length() > 0.0)
        .collect();
    let (gt_len, gt_ok) = if est.is_empty() {
        (gt.iter().map(Seg::length).sum(), 0.0)
    } else {
        covered(&gt, &est, &grid_of(&est))
    };
    let (est_len, est_ok) = if gt.is_empty() {
        (est.iter().map(Seg::length).sum(), 0.0)
    } else {
        covered(&est, &gt, &grid_of(&gt))
    };
    ImageScores {
        image: name.clone(),
        n_true: gt.len(),
        n_estimated: est.len(),
        recall: if gt_len > 0.0 { gt_ok / gt_len } else { f64::NAN },
        precision: if est_len > 0.0 { est_ok / est_len } else { f64::NAN },
        lengths: [gt_len, gt_ok, est_len, est_ok],
    }
}

pub fn evaluate(truth: &Truth, rows: &[Line2Row]) -> Lines2dReport {
    report((0..truth.poses.len()).map(|frame| score_image(truth, frame, rows)).collect())
}

/// The report of the frames scored one by one as their lines came (`scored`, by frame), the frames of the truth
/// that none came for scored with none (recall 0).
pub fn evaluate_scored(truth: &Truth, scored: &std::collections::BTreeMap<usize, ImageScores>) -> Lines2dReport {
    report(
        (0..truth.poses.len())
            .map(|frame| scored.get(&frame).cloned().unwrap_or_else(|| score_image(truth, frame, &[])))
            .collect(),
    )
}

/// The frame of `truth` named `image`.
pub fn frame_of(truth: &Truth, image: &str) -> Option<usize> {
    truth.poses.iter().position(|p| p.image == image)
}

fn report(images: Vec<ImageScores>) -> Lines2dReport {
    let sum = |k: usize| images.iter().map(|i| i.lengths[k]).sum::<f64>();
    Lines2dReport {
        recall: sum(1) / sum(0).max(1e-12),
        precision: if sum(2) > 0.0 { sum(3) / sum(2) } else { f64::NAN },
        images,
    }
}
