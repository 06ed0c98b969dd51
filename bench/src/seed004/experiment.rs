//! Seed 004's experiments on synthetic aerial photos ([`super::aerial`]): edge detector × weighting, pull-in
//! range per parameter, and number of photos, scored by the seed's correctness rate (eq. 3).
use lineflow_messages::EdgePixel;
use lineflow_photogrammetry::{Camera, Pose, Vec3};
use rayon::prelude::*;

use super::aerial::BuildingScene;
use lineflow_modelfit::fit::{fit, Fit, FitParams};
use lineflow_modelfit::observations::{point_segment_distance, ImageEdges};
use lineflow_modelfit::parametric::{box_param, visible_edges, BoxModel, Parametric};
use lineflow_modelfit::weights::Weighting;

/// The seed's three detectors with its settings (§2.2), mapped onto our 8-bit Sobel-magnitude scale.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Detector {
    /// Threshold 0.02 on the MATLAB-scaled magnitude (kernel / 8, image in [0, 1]) = 0.02 · 8 · 255 here.
    Sobel,
    /// Gaussian σ = 1, hysteresis 0.09 / 0.036 of the image's largest gradient magnitude.
    Canny,
    /// σ = 1 zero crossings. Our LoG gates crossings by the Sobel magnitude, not by the seed's zero-crossing
    /// slope (0.0036); the gate is Canny's low threshold, 0.036 of the image's largest magnitude.
    Log,
}

impl Detector {
    /// All three, in the seed's order.
    pub const ALL: [Detector; 3] = [Detector::Sobel, Detector::Canny, Detector::Log];

    /// Name as in the launch file.
    pub fn name(self) -> &'static str {
        match self {
            Detector::Sobel => "sobel",
            Detector::Canny => "canny",
            Detector::Log => "log",
        }
    }

    /// Edge pixels of an 8-bit image with gradients.
    pub fn detect(self, gray: &[u8], w: usize, h: usize) -> Vec<EdgePixel> {
        match self {
            Detector::Sobel => {
                let map = lineflow_edges::sobel(gray, w, h, 0.02 * 8.0 * 255.0);
                lineflow_edges::pixels(gray, w, h, &map)
            }
            Detector::Canny => {
                let smooth = lineflow_edges::gaussian_blur(gray, w, h, 1.0);
                let g = lineflow_imaging::gradient(&smooth, w, h);
                let max = (g.mag2.iter().copied().max().unwrap_or(0) as f64).sqrt();
                let map = lineflow_edges::canny(&smooth, w, h, 0.036 * max, 0.09 * max);
                lineflow_edges::pixels(&smooth, w, h, &map)
            }
            Detector::Log => {
                let g = lineflow_imaging::gradient(gray, w, h);
                let max = (g.mag2.iter().copied().max().unwrap_or(0) as f64).sqrt();
                let map = lineflow_edges::log(gray, w, h, 1.0, 0.036 * max);
                lineflow_edges::pixels(gray, w, h, &map)
            }
        }
    }
}

/// A building with its photos rendered and edge-detected by every detector.
pub struct Prepared {
    /// The scene.
    pub scene: BuildingScene,
    /// (camera, pose) per photo.
    pub photos: Vec<(Camera, Pose)>,
    /// Edge images per detector (index as [`Detector::ALL`]), per photo.
    pub edges: Vec<Vec<ImageEdges>>,
}

impl Prepared {
    /// Renders the scene's four photos and runs every detector on them.
    pub fn new(scene: BuildingScene) -> Self {
        let photos = scene.photos(4);
        let images: Vec<Vec<u8>> = photos.iter().map(|(c, p)| scene.render(c, p)).collect();
        let edges = Detector::ALL
            .iter()
            .map(|d| {
                photos
                    .iter()
                    .zip(&images)
                    .map(|((c, p), img)| ImageEdges::new(*c, *p, &d.detect(img, c.width as usize, c.height as usize)))
                    .collect()
            })
            .collect();
        Self { scene, photos, edges }
    }

    /// The edge images of `detector` in the first `n` photos.
    pub fn images(&self, detector: Detector, n: usize) -> &[ImageEdges] {
        let d = Detector::ALL.iter().position(|&x| x == detector).unwrap_or(0);
        &self.edges[d][..n.min(self.edges[d].len())]
    }
}

/// Eq. 3 over the first `n` photos: (fitted lines needing no correction, visible building lines). A fitted line
/// needs no correction when both its projected ends lie within 1 pixel of the true projected edge.
pub fn correct_lines(scene: &BuildingScene, photos: &[(Camera, Pose)], fitted: &[f64]) -> (usize, usize) {
    let model = BoxModel;
    let (truth_v, fit_v) = (model.vertices(&scene.truth), model.vertices(fitted));
    let (mut good, mut visible) = (0, 0);
    for (camera, pose) in photos {
        let seen = visible_edges(&model, &scene.truth, &truth_v, &pose.center);
        for (k, e) in model.edges().iter().enumerate() {
            if !seen[k] {
                continue;
            }
            visible += 1;
            let px = |v: &Vec3| pose.project(camera, v);
            let (Some(t0), Some(t1)) = (px(&truth_v[e[0]]), px(&truth_v[e[1]])) else {
                continue;
            };
            let (Some(f0), Some(f1)) = (px(&fit_v[e[0]]), px(&fit_v[e[1]])) else {
                continue;
            };
            if point_segment_distance(f0, t0, t1) <= 1.0 && point_segment_distance(f1, t0, t1) <= 1.0 {
                good += 1;
            }
        }
    }
    (good, visible)
}

/// The seed's success test (§4 item 7): within 0.1 m and 0.2° of the truth and every visible line correct.
pub fn succeeded(scene: &BuildingScene, photos: &[(Camera, Pose)], f: &Fit) -> bool {
    if !f.ok() {
        return false;
    }
    let close = (0..7).all(|k| {
        let tol = if k == box_param::THETA { 0.2f64.to_radians() } else { 0.1 };
        (f.params[k] - scene.truth[k]).abs() <= tol
    });
    let (good, visible) = correct_lines(scene, photos, &f.params);
    close && good == visible
}

/// A start perturbed uniformly by up to ±`metres` in dX, dY, dZ, L, W, h and ±`degrees` in θ.
pub fn perturbed(truth: &[f64; 7], metres: f64, degrees: f64, seed: u64) -> Vec<f64> {
    let mut rng = lineflow_photogrammetry::random::Rng::from_state(seed);
    (0..7)
        .map(|k| {
            let r = 2.0 * lineflow_photogrammetry::random::unit(rng.next_u64()) - 1.0;
            truth[k] + r * if k == box_param::THETA { degrees.to_radians() } else { metres }
        })
        .collect()
}

/// Rate and success share of many fits.
#[derive(Debug, Clone, Copy, Default)]
pub struct Score {
    /// Σ l'_i.
    pub good: usize,
    /// Σ l_i.
    pub visible: usize,
    /// Fits that met the success test.
    pub successes: usize,
    /// Fits.
    pub runs: usize,
    /// Sum of the final residual RMS (px) over successful fits.
    pub rms_px_sum: f64,
}

impl Score {
    /// Correctness rate, %.
    pub fn rate(&self) -> f64 {
        100.0 * self.good as f64 / self.visible.max(1) as f64
    }
    /// Success share, %.
    pub fn success(&self) -> f64 {
        100.0 * self.successes as f64 / self.runs.max(1) as f64
    }
    /// Mean final residual RMS of the successful fits, px.
    pub fn rms_px(&self) -> f64 {
        self.rms_px_sum / self.successes.max(1) as f64
    }
    fn add(&mut self, o: Score) {
        self.good += o.good;
        self.visible += o.visible;
        self.successes += o.successes;
        self.runs += o.runs;
        self.rms_px_sum += o.rms_px_sum;
    }
}

/// Fits the building from `start` with `detector` on the first `n` photos and scores it.
pub fn score_one(b: &Prepared, detector: Detector, n: usize, start: &[f64], params: &FitParams) -> Score {
    let photos = &b.photos[..n];
    let f = fit(&BoxModel, start, b.images(detector, n), params);
    let (good, visible) = correct_lines(&b.scene, photos, &f.params);
    let ok = succeeded(&b.scene, photos, &f);
    Score {
        good,
        visible,
        successes: usize::from(ok),
        runs: 1,
        rms_px_sum: if ok { f.residual_rms_mm / photos[0].0.pixel_size_mm } else { 0.0 },
    }
}

/// Experiments 1 and 3: `trials` perturbed starts per building.
pub fn score_many(
    buildings: &[Prepared],
    detector: Detector,
    n: usize,
    params: &FitParams,
    trials: usize,
    metres: f64,
    degrees: f64,
) -> Score {
    let jobs: Vec<(usize, usize)> = (0..buildings.len()).flat_map(|b| (0..trials).map(move |t| (b, t))).collect();
    let scores: Vec<Score> = jobs
        .par_iter()
        .map(|&(b, t)| {
            let start = perturbed(&buildings[b].scene.truth, metres, degrees, 7919 * b as u64 + t as u64);
            score_one(&buildings[b], detector, n, &start, params)
        })
        .collect();
    let mut total = Score::default();
    for s in scores {
        total.add(s);
    }
    total
}

/// Experiment 2: the pull-in range of parameter `k` for one building, the mean of the two sides; each side is
/// the largest offset (in `step`s up to `max`) such that every smaller offset succeeds.
pub fn pull_in(b: &Prepared, k: usize, step: f64, max: f64, n: usize, params: &FitParams) -> f64 {
    let sides: Vec<f64> = [-1.0, 1.0]
        .par_iter()
        .map(|&sign| {
            let mut reached = 0.0;
            let steps = (max / step).round() as usize;
            for i in 1..=steps {
                let delta = step * i as f64;
                let mut start = b.scene.truth.to_vec();
                start[k] += sign * delta;
                let f = fit(&BoxModel, &start, b.images(Detector::Canny, n), params);
                if !succeeded(&b.scene, &b.photos[..n], &f) {
                    break;
                }
                reached = delta;
            }
            reached
        })
        .collect();
    (sides[0] + sides[1]) / 2.0
}

/// The weighting schemes and detectors of experiment 1 as (detector, weighting, score) rows.
pub fn detector_weighting_grid(
    buildings: &[Prepared],
    params: &FitParams,
    trials: usize,
    metres: f64,
    degrees: f64,
) -> Vec<(Detector, Weighting, Score)> {
    let mut rows = Vec::new();
    for d in Detector::ALL {
        for w in Weighting::ALL {
            let p = FitParams {
                weighting: w,
                ..params.clone()
            };
            rows.push((d, w, score_many(buildings, d, 4, &p, trials, metres, degrees)));
        }
    }
    rows
}
