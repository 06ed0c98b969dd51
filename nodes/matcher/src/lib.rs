//! The matcher stage: tie points between each new frame and the earlier frames it overlaps.
//!
//! Partners are the previous `window` frames plus the earlier frames that look most alike (a quick match of the
//! strongest keypoints), so that a second strip finds the first one although file order puts other images between
//! them. Each pair is matched (ratio test, Laplacian sign, mutual check) and verified with RANSAC on the essential
//! matrix (interior orientation known). Verified matches join tracks; a track keeps its id for good.
pub mod descriptors;

use std::collections::HashMap;

use descriptors::{match_features, FrameFeatures};
use lineflow_photogrammetry::epipolar::{dominant_plane, verify, Ransac, Ray};
use lineflow_photogrammetry::Camera;

/// Matcher settings.
#[derive(Debug, Clone, serde::Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct MatcherParams {
    /// Nearest / second-nearest descriptor distance ratio.
    pub ratio: f32,
    /// Previous frames always tried.
    pub window: usize,
    /// Further earlier frames tried, the most alike first.
    pub retrieval: usize,
    /// Keypoints per frame used to rank earlier frames by likeness.
    pub retrieval_keypoints: usize,
    /// Matches of the ranking needed before a frame is tried.
    pub retrieval_min_matches: usize,
    /// RANSAC inlier threshold, pixels (Sampson distance).
    pub threshold_px: f64,
    /// RANSAC iterations at most.
    pub iterations: usize,
    /// Verified matches needed to accept a pair.
    pub min_inliers: usize,
    /// Share of the mutual matches that must survive verification to accept a pair: between frames that do not
    /// really overlap, the few "verified" matches are repeated texture.
    pub min_inlier_ratio: f64,
    /// Neighbours compared in the displacement-consistency check (0 turns it off).
    pub neighbours: usize,
    /// Largest difference, pixels, between a match's displacement and its neighbours' median displacement.
    pub displacement_tolerance_px: f64,
    /// Matches must also fit the dominant plane (the façade) within this many pixels, relief included (0 = off).
    pub plane_tolerance_px: f64,
}

impl Default for MatcherParams {
    fn default() -> Self {
        Self {
            ratio: 0.7,
            window: 2,
            retrieval: 3,
            retrieval_keypoints: 300,
            retrieval_min_matches: 12,
            threshold_px: 1.5,
            iterations: 1000,
            min_inliers: 15,
            min_inlier_ratio: 0.3,
            neighbours: 8,
            displacement_tolerance_px: 3.0,
            plane_tolerance_px: 6.0,
        }
    }
}

/// One observation of a tie point.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Observation {
    /// Track id (from 1).
    pub track: u64,
    /// Frame number.
    pub frame: u64,
    /// Measured pixel position.
    pub px: [f64; 2],
}

/// What matching one new frame gave.
#[derive(Debug, Clone, Default)]
pub struct FrameResult {
    /// Partners tried: (frame, mutual matches, verified inliers; 0 when refused).
    pub partners: Vec<(u64, usize, usize)>,
    /// New observations, of this frame and of partners' keypoints that started tracks.
    pub observations: Vec<Observation>,
}

/// Which matches move like their neighbours. The epipolar constraint cannot see a match shifted along its
/// epipolar line, and on a façade the epipolar lines of a strip run along the brick courses, whose repetition makes
/// exactly such matches; their displacement differs from their neighbours' by a brick period.
pub fn consistent_displacements(pairs: &[([f64; 2], [f64; 2])], neighbours: usize, tolerance_px: f64) -> Vec<bool> {
    if neighbours == 0 || pairs.len() <= neighbours {
        return vec![true; pairs.len()];
    }
    let disp: Vec<[f64; 2]> = pairs.iter().map(|(a, b)| [b[0] - a[0], b[1] - a[1]]).collect();
    (0..pairs.len())
        .map(|i| {
            let a = pairs[i].0;
            let mut near: Vec<(f64, usize)> = (0..pairs.len())
                .filter(|&j| j != i)
                .map(|j| ((pairs[j].0[0] - a[0]).hypot(pairs[j].0[1] - a[1]), j))
                .collect();
            near.select_nth_unstable_by(neighbours - 1, |x, y| x.0.total_cmp(&y.0).then(x.1.cmp(&y.1)));
            let median = |axis: usize| {
                let mut v: Vec<f64> = near[..neighbours].iter().map(|&(_, j)| disp[j][axis]).collect();
                v.sort_by(f64::total_cmp);
                v[v.len() / 2]
            };
            (disp[i][0] - median(0)).hypot(disp[i][1] - median(1)) <= tolerance_px
        })
        .collect()
}

struct Frame {
    number: u64,
    features: FrameFeatures,
    rays: Vec<Ray>,
    sample: FrameFeatures,
}

/// The streaming matcher: frames in, tie-point observations out.
pub struct Matcher {
    params: MatcherParams,
    camera: Camera,
    frames: Vec<Frame>,
    /// (frame index, keypoint) → track.
    track_of: HashMap<(usize, usize), u64>,
    /// track → frame indices it is observed in.
    frames_of: HashMap<u64, Vec<usize>>,
    next_track: u64,
}

impl Matcher {
    /// A matcher for images of `camera`.
    pub fn new(params: MatcherParams, camera: Camera) -> Self {
        Self {
            params,
            camera,
            frames: Vec::new(),
            track_of: HashMap::new(),
            frames_of: HashMap::new(),
            next_track: 1,
        }
    }

    fn ray(&self, px: [f64; 2]) -> Ray {
        let [x, y] = self.camera.pixel_to_ideal(px);
        let f = self.camera.focal_mm;
        Ray::new(x / f, y / f, -1.0)
    }

    /// Earlier frames to match against: the window, then the most alike of the rest.
    fn partners(&self, sample: &FrameFeatures) -> Vec<usize> {
        let k = self.frames.len();
        let mut chosen: Vec<usize> = (k.saturating_sub(self.params.window)..k).rev().collect();
        let mut ranked: Vec<(usize, usize)> = (0..k.saturating_sub(self.params.window))
            .map(|i| (match_features(sample, &self.frames[i].sample, self.params.ratio).len(), i))
            .filter(|&(n, _)| n >= self.params.retrieval_min_matches)
            .collect();
        // Most matches first; ties to the later frame, deterministically.
        ranked.sort_by(|a, b| b.cmp(a));
        chosen.extend(ranked.into_iter().take(self.params.retrieval).map(|(_, i)| i));
        chosen
    }

    /// Matches a new frame against its partners and extends the tracks.
    pub fn add_frame(&mut self, number: u64, features: FrameFeatures) -> FrameResult {
        let rays: Vec<Ray> = features.px.iter().map(|&p| self.ray(p)).collect();
        let sample = features.strongest(self.params.retrieval_keypoints);
        let new = self.frames.len();
        let mut result = FrameResult::default();
        let ransac = Ransac {
            threshold: self.params.threshold_px * self.camera.pixel_size_mm / self.camera.focal_mm,
            iterations: self.params.iterations,
            seed: 0x5EED ^ number,
        };
        for p in self.partners(&sample) {
            let other = &self.frames[p];
            let matches = match_features(&features, &other.features, self.params.ratio);
            let (ra, rb): (Vec<Ray>, Vec<Ray>) = matches.iter().map(|&(i, j)| (rays[i], other.rays[j])).unzip();
            let mut inliers = verify(&ra, &rb, &ransac, self.params.min_inliers);
            let pairs: Vec<([f64; 2], [f64; 2])> = inliers
                .iter()
                .map(|&m| (features.px[matches[m].0], other.features.px[matches[m].1]))
                .collect();
            let keep = consistent_displacements(&pairs, self.params.neighbours, self.params.displacement_tolerance_px);
            inliers = inliers.into_iter().zip(keep).filter_map(|(m, k)| k.then_some(m)).collect();
            if self.params.plane_tolerance_px > 0.0 {
                let (pa, pb): (Vec<Ray>, Vec<Ray>) = inliers.iter().map(|&m| (ra[m], rb[m])).unzip();
                let plane = Ransac {
                    threshold: self.params.plane_tolerance_px * self.camera.pixel_size_mm / self.camera.focal_mm,
                    ..ransac
                };
                let on_plane = dominant_plane(&pa, &pb, &plane);
                // A scene without a dominant plane (a roof, a corner) keeps its epipolar inliers.
                if on_plane.len() >= self.params.min_inliers {
                    inliers = on_plane.into_iter().map(|i| inliers[i]).collect();
                }
            }
            if inliers.len() < self.params.min_inliers {
                inliers.clear();
            }
            if (inliers.len() as f64) < self.params.min_inlier_ratio * matches.len() as f64 {
                inliers.clear();
            }
            result.partners.push((other.number, matches.len(), inliers.len()));
            for &m in &inliers {
                let (i, j) = matches[m];
                self.link((new, i), (p, j), &features, &mut result.observations, number);
            }
        }
        self.frames.push(Frame {
            number,
            features,
            rays,
            sample,
        });
        result
    }

    fn observe(&mut self, track: u64, at: (usize, usize)) {
        self.track_of.insert(at, track);
        self.frames_of.entry(track).or_default().push(at.0);
    }

    /// Joins a verified match (`new` keypoint in the new frame, `old` in a partner) to the tracks. Tracks are never
    /// merged: two existing tracks stay apart, so every id published stays valid.
    fn link(&mut self, new: (usize, usize), old: (usize, usize), features: &FrameFeatures, out: &mut Vec<Observation>, number: u64) {
        let has = |s: &Self, t: u64, f: usize| s.frames_of.get(&t).is_some_and(|v| v.contains(&f));
        let of_old = |s: &Self, track: u64| {
            let o = &s.frames[old.0];
            Observation {
                track,
                frame: o.number,
                px: o.features.px[old.1],
            }
        };
        let of_new = |track: u64| Observation {
            track,
            frame: number,
            px: features.px[new.1],
        };
        match (self.track_of.get(&new).copied(), self.track_of.get(&old).copied()) {
            (None, Some(t)) if !has(self, t, new.0) => {
                self.observe(t, new);
                out.push(of_new(t));
            }
            (None, None) => {
                let t = self.next_track;
                self.next_track += 1;
                self.observe(t, old);
                self.observe(t, new);
                out.extend([of_old(self, t), of_new(t)]);
            }
            (Some(t), None) if !has(self, t, old.0) => {
                self.observe(t, old);
                out.push(of_old(self, t));
            }
            _ => {}
        }
    }
}
