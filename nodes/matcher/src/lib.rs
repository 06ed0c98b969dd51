//! The matcher stage: tie points between each new frame and the earlier frames it overlaps.
//!
//! Partners are the previous `window` frames plus the earlier frames that look most alike (a quick match of the
//! strongest keypoints), so that a second strip finds the first one although file order puts other images between
//! them. Each pair is matched (ratio test, Laplacian sign, mutual check); a façade being nearly a plane, the
//! dominant plane's homography is found by RANSAC and guides a second, much richer matching among the keypoints
//! near their predicted positions. Repeated window bays make more than one transfer plausible; the loop through
//! the partners already accepted (or the camera's steady motion) picks the true one. Scenes without a dominant
//! plane are verified with the essential matrix instead. Verified matches join tracks; a track keeps its id for
//! good.
#![warn(missing_docs)]
pub mod descriptors;
pub mod lattice;
pub mod lsm;
pub mod stage;

use std::collections::HashMap;

use descriptors::{guided_match, match_features, FrameFeatures};
use lattice::{lattice_steps, repetition_periods};
use lineflow_photogrammetry::epipolar::{dominant_plane, homography, verify, Ransac, Ray};
use lineflow_photogrammetry::Camera;
use lineflow_runtime::params::{self, ParamError};
use lsm::{Gray, LsmParams};
use nalgebra::Matrix3;
use rayon::prelude::*;

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
    /// Ratio test among the candidates of guided matching (within `plane_tolerance_px` of the dominant plane's
    /// transfer).
    pub guided_ratio: f32,
    /// Largest descriptor distance of a guided match that has no second candidate.
    pub guided_max_distance: f32,
    /// Plane transfers tried per pair (repeated bays make more than one plausible).
    pub plane_hypotheses: usize,
    /// A frame's first partner, when that is not the previous frame, has its transfers also tried shifted by one
    /// period of the façade's repetition (the bay, the storey; [`Matcher::with_lattice_shifts`]).
    pub lattice_shifts: bool,
    /// Longest chain of consecutive frames through which two frames' plane transfer is composed for the loop check.
    pub loop_chain: usize,
    /// Refine every observation by least-squares matching against its track's first observation (needs the
    /// frames' grey images).
    pub refine: bool,
    /// Half the side of the least-squares matching template, pixels.
    pub refine_half_window: usize,
    /// Smallest correlation of a refined observation; an observation that fails is dropped.
    pub refine_min_correlation: f64,
    /// Grey images kept for refinement (the most recent frames); older anchors are not refined against.
    pub refine_keep_frames: usize,
    /// Frames whose keypoints are kept to match against (the most recent): older frames are let go, their
    /// keypoints, descriptors and track links with them, so that a stream of any length holds bounded state (about
    /// 0.7 MB a frame at 1.4 MP, besides the grey images of the last `refine_keep_frames`). A session that comes
    /// back to a place photographed more than this many frames earlier needs it raised.
    pub keep_frames: usize,
}

impl lineflow_runtime::StageParams for MatcherParams {
    fn validate(&self) -> Result<(), ParamError> {
        params::check(self.ratio > 0.0 && self.ratio <= 1.0, "ratio", "in (0, 1]", self.ratio)?;
        params::positive("threshold_px", self.threshold_px)?;
        params::at_least("iterations", self.iterations, 1)?;
        params::at_least("keep_frames", self.keep_frames, self.window.max(1))?;
        params::check(
            self.min_inliers >= 8,
            "min_inliers",
            ">= 8 (the eight-point solution)",
            self.min_inliers,
        )
    }
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
            guided_ratio: 0.8,
            guided_max_distance: 0.5,
            plane_hypotheses: 3,
            lattice_shifts: true,
            loop_chain: 40,
            refine: true,
            refine_half_window: 8,
            refine_min_correlation: 0.8,
            refine_keep_frames: 60,
            keep_frames: 200,
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
    /// Observations refined by least-squares matching.
    pub refined: usize,
    /// Observations dropped because their refinement failed.
    pub unrefined: usize,
}

/// The hypotheses with at least [`COMPARABLE_SUPPORT`] of the matches of the best supported one. The camera's steady
/// motion only tells apart transfers that differ by more than its own irregularity (at full size the step between
/// frames of a hand-held strip varies by 30–200 px), and it says nothing where the strip ends and the next begins;
/// a hypothesis clearly less supported can fall closer to the previous step than the true transfer, and must not
/// win on that. The step decides only where the images cannot: bays so alike that a transfer one bay off finds
/// about as many matches as the true one.
fn comparable_support(mut hypotheses: Vec<Hypothesis>) -> Vec<Hypothesis> {
    let most = hypotheses.iter().map(|h| h.matches.len()).max().unwrap_or(0) as f64;
    hypotheses.retain(|h| h.matches.len() as f64 >= COMPARABLE_SUPPORT * most);
    hypotheses
}

/// Share of the best hypothesis's matches that another needs for the steady motion to choose between them. On the
/// held-out A55 buildings at full size a transfer one bay off found 0.53–0.67 of the true one's matches, and at
/// 0.5 the step chose it twice: at the jump from the first strip's end to the second's start (1,427 against 2,443
/// matches) and within a strip whose step varied by 214 px (1,668 against 2,950).
const COMPARABLE_SUPPORT: f64 = 0.8;

/// The ratio test of a frame that no partner verifies under the strict one.
const LOOSE_RATIO: f32 = 0.85;

/// How much farther than `plane_tolerance_px` a shifted transfer's first guided matching looks.
const SHIFT_TOLERANCE: f64 = 3.0;

/// Rounds of [`Matcher::grown`] at most.
const GROWING_ROUNDS: usize = 3;

/// Keypoints of a partner image (the strongest) among which its repetition periods are looked for.
const LATTICE_KEYPOINTS: usize = 1500;

/// Which matches move like their neighbours. The epipolar constraint cannot see a match shifted along its
/// epipolar line, and on a façade the epipolar lines of a strip run along the brick courses, whose repetition makes
/// exactly such matches; their displacement differs from their neighbours' by a brick period.
pub fn consistent_displacements(pairs: &[([f64; 2], [f64; 2])], neighbours: usize, tolerance_px: f64) -> Vec<bool> {
    if neighbours == 0 || pairs.len() <= neighbours {
        return vec![true; pairs.len()];
    }
    let disp: Vec<[f64; 2]> = pairs.iter().map(|(a, b)| [b[0] - a[0], b[1] - a[1]]).collect();
    let at: Vec<[f64; 2]> = pairs.iter().map(|p| p.0).collect();
    k_nearest(&at, neighbours)
        .par_iter()
        .enumerate()
        .map(|(i, near)| {
            let median = |axis: usize| {
                let mut v: Vec<f64> = near.iter().map(|&j| disp[j][axis]).collect();
                v.sort_by(f64::total_cmp);
                v[v.len() / 2]
            };
            (disp[i][0] - median(0)).hypot(disp[i][1] - median(1)) <= tolerance_px
        })
        .collect()
}

/// The `k` nearest other points of every point (by distance, ties to the lower index), through a uniform grid of
/// about `k` points per cell: searched ring by ring until no unvisited cell can hold a nearer point.
fn k_nearest(points: &[[f64; 2]], k: usize) -> Vec<Vec<usize>> {
    let n = points.len();
    let (mut lo, mut hi) = ([f64::INFINITY; 2], [f64::NEG_INFINITY; 2]);
    for p in points {
        for a in 0..2 {
            lo[a] = lo[a].min(p[a]);
            hi[a] = hi[a].max(p[a]);
        }
    }
    let area = ((hi[0] - lo[0]) * (hi[1] - lo[1])).max(1.0);
    let cell = (area * k as f64 / n.max(1) as f64).sqrt().max(1e-6);
    let dims = [0, 1].map(|a| (((hi[a] - lo[a]) / cell) as usize + 1).min(4096));
    let cell_of = |p: [f64; 2]| [0, 1].map(|a| (((p[a] - lo[a]) / cell) as usize).min(dims[a] - 1));
    let mut buckets = vec![Vec::new(); dims[0] * dims[1]];
    for (j, &p) in points.iter().enumerate() {
        let [cx, cy] = cell_of(p);
        buckets[cy * dims[0] + cx].push(j);
    }
    (0..n)
        .into_par_iter()
        .map(|i| {
            let p = points[i];
            let [cx, cy] = cell_of(p).map(|c| c as isize);
            let mut candidates: Vec<(f64, usize)> = Vec::new();
            for ring in 0..=dims[0].max(dims[1]) as isize {
                for y in cy - ring..=cy + ring {
                    for x in cx - ring..=cx + ring {
                        let on_ring = (x - cx).abs() == ring || (y - cy).abs() == ring;
                        if !on_ring || x < 0 || y < 0 || x >= dims[0] as isize || y >= dims[1] as isize {
                            continue;
                        }
                        for &j in &buckets[y as usize * dims[0] + x as usize] {
                            if j != i {
                                let d = [points[j][0] - p[0], points[j][1] - p[1]];
                                candidates.push((d[0] * d[0] + d[1] * d[1], j));
                            }
                        }
                    }
                }
                // Cells beyond this ring are at least `ring` whole cells away.
                if candidates.len() >= k {
                    candidates.select_nth_unstable_by(k - 1, |a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
                    let reach = ring as f64 * cell;
                    if candidates[k - 1].0 <= reach * reach {
                        break;
                    }
                }
            }
            if candidates.len() > k {
                candidates.select_nth_unstable_by(k - 1, |a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
            }
            candidates.truncate(k);
            candidates.into_iter().map(|(_, j)| j).collect()
        })
        .collect()
}

/// One explanation of a pair's matches.
#[derive(Default)]
struct Hypothesis {
    /// Verified matches (new frame keypoint, partner keypoint).
    matches: Vec<(usize, usize)>,
    /// The dominant plane's homography, new frame → partner, normalised image coordinates (the image plane at
    /// distance 1).
    plane: Option<Matrix3<f64>>,
}

/// Where `h` takes the ray `r`, in normalised image coordinates.
fn transfer_point(h: &Matrix3<f64>, r: &Ray) -> Option<[f64; 2]> {
    let m = h * (r / r.z);
    (m.z.abs() > 1e-12).then(|| [m.x / m.z, m.y / m.z])
}

struct Frame {
    number: u64,
    features: FrameFeatures,
    rays: Vec<Ray>,
    sample: FrameFeatures,
    image: Option<Gray>,
}

impl Frame {
    /// The keypoints' rays on the image plane at unit distance (normalised image coordinates).
    fn image_plane(&self) -> Vec<[f64; 2]> {
        self.rays.iter().map(|r| [r.x / r.z, r.y / r.z]).collect()
    }
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
    /// Accepted pairs' plane homographies, (later, earlier) frame index → later to earlier.
    planes: HashMap<(usize, usize), Matrix3<f64>>,
    /// track → its first observation (frame index, pixel), which the others are refined against.
    anchors: HashMap<u64, (usize, [f64; 2])>,
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
            planes: HashMap::new(),
            anchors: HashMap::new(),
        }
    }

    /// The camera the matcher was made for.
    pub fn camera(&self) -> &Camera {
        &self.camera
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
        let mut ranked: Vec<(usize, usize)> = (k.saturating_sub(self.params.keep_frames)..k.saturating_sub(self.params.window))
            .map(|i| (match_features(sample, &self.frames[i].sample, self.params.ratio).len(), i))
            .filter(|&(n, _)| n >= self.params.retrieval_min_matches)
            .collect();
        // Most matches first; ties to the later frame, deterministically.
        ranked.sort_by(|a, b| b.cmp(a));
        chosen.extend(ranked.into_iter().take(self.params.retrieval).map(|(_, i)| i));
        chosen
    }

    /// Matches a new frame against its partners and extends the tracks. With the frame's grey `image` (and
    /// `refine` on), the new observations are refined by least-squares matching.
    pub fn add_frame(&mut self, number: u64, features: FrameFeatures, image: Option<Gray>) -> FrameResult {
        let rays: Vec<Ray> = features.px.iter().map(|&p| self.ray(p)).collect();
        let sample = features.strongest(self.params.retrieval_keypoints);
        let new = self.frames.len();
        let mut result = FrameResult::default();
        let ransac = Ransac {
            threshold: self.params.threshold_px * self.camera.pixel_size_mm / self.camera.focal_mm,
            iterations: self.params.iterations,
            seed: 0x5EED ^ number,
        };
        // Partners in order of preference (the window first): each pair's hypotheses are judged against the
        // pairs already accepted for this frame.
        let mut accepted: Vec<(usize, Matrix3<f64>)> = Vec::new();
        // The new observations with the index of their frame.
        let mut linked: Vec<(Observation, usize)> = Vec::new();
        // A frame no partner verifies under the strict ratio test is matched again under a looser one: two strips
        // at different heights see a plain or repeated façade too differently for the strict test, while a looser
        // one, with RANSAC's plane to sort it, still joins them. Frames the strict test joins are left as they are.
        let ratios = if LOOSE_RATIO > self.params.ratio {
            vec![self.params.ratio, LOOSE_RATIO]
        } else {
            vec![self.params.ratio]
        };
        for ratio in ratios {
            result.partners.clear();
            for p in self.partners(&sample) {
                let mutual = match_features(&features, &self.frames[p].features, ratio);
                let predicted = accepted.iter().find_map(|&(a, h_ka)| Some(self.plane_between(a, p)? * h_ka));
                let mut hypotheses = self.hypotheses(&features, &rays, p, &mutual, &ransac, predicted);
                // Only where `choose` has neither a loop nor the previous frame's step to judge by: the first
                // partner when it is not the previous frame (the previous frame found nothing, as at a jump).
                if accepted.is_empty() && p + 1 != new {
                    hypotheses = self.with_lattice_shifts(&features, &rays, p, hypotheses);
                }
                let chosen = self.choose(new, p, hypotheses, &accepted, &rays);
                result.partners.push((self.frames[p].number, mutual.len(), chosen.matches.len()));
                if chosen.matches.is_empty() {
                    continue;
                }
                if let Some(h) = chosen.plane {
                    self.planes.insert((new, p), h);
                    accepted.push((p, h));
                }
                for (i, j) in chosen.matches {
                    self.link((new, i), (p, j), &features, &mut linked, number);
                }
            }
            if !linked.is_empty() || new == 0 {
                break;
            }
        }
        self.frames.push(Frame {
            number,
            features,
            rays,
            sample,
            image: image.filter(|_| self.params.refine),
        });
        if let Some(old) = self.frames.len().checked_sub(self.params.refine_keep_frames + 1) {
            self.frames[old].image = None;
        }
        self.refine_observations(&mut linked, &mut result);
        if let Some(old) = self.frames.len().checked_sub(self.params.keep_frames + 1) {
            self.forget(old);
        }
        result.observations = linked.into_iter().map(|(o, _)| o).collect();
        result
    }

    /// Refines each new observation that is not its track's anchor against the anchor, by least-squares matching
    /// through the local affine transfer of the plane between the two frames. An observation whose refinement
    /// fails (low texture or correlation, a move beyond the pull-in range) is dropped: left at its keypoint
    /// position it would be several times less precise than the rest and dominate the adjustment. Observations
    /// that cannot be tried (no image, no plane between the frames) keep their keypoint position.
    fn refine_observations(&self, linked: &mut Vec<(Observation, usize)>, result: &mut FrameResult) {
        if !self.params.refine {
            return;
        }
        let lsm = LsmParams {
            half_window: self.params.refine_half_window,
            min_correlation: self.params.refine_min_correlation,
            ..LsmParams::default()
        };
        let outcomes: Vec<Option<Option<[f64; 2]>>> = linked
            .par_iter()
            .map(|&(o, at)| {
                let &(anchor, anchor_px) = self.anchors.get(&o.track).filter(|(a, _)| *a != at)?;
                let (a, b) = (self.frames[anchor].image.as_ref()?, self.frames[at].image.as_ref()?);
                let h = self.plane_between(anchor, at)?;
                let affine = self.local_affine(&h, anchor_px)?;
                Some(lsm::refine(a, anchor_px, b, o.px, affine, &lsm).map(|r| r.px))
            })
            .collect();
        let mut outcome = outcomes.into_iter();
        linked.retain_mut(|(o, _)| match outcome.next().flatten() {
            Some(Some(px)) => {
                o.px = px;
                result.refined += 1;
                true
            }
            Some(None) => {
                result.unrefined += 1;
                false
            }
            None => true,
        });
    }

    /// Where the plane transfer `h` (normalised image coordinates) takes a measured pixel position.
    fn transfer_pixel(&self, h: &Matrix3<f64>, px: [f64; 2]) -> Option<[f64; 2]> {
        let [u, v] = transfer_point(h, &self.ray(px))?;
        let f = self.camera.focal_mm;
        self.camera.ideal_to_pixel([-u * f, -v * f])
    }

    /// The Jacobian of the transfer `h` at `px`, pixels to pixels, by central differences.
    fn local_affine(&self, h: &Matrix3<f64>, px: [f64; 2]) -> Option<[[f64; 2]; 2]> {
        let at = |dx: f64, dy: f64| self.transfer_pixel(h, [px[0] + dx, px[1] + dy]);
        let (xp, xm, yp, ym) = (at(1.0, 0.0)?, at(-1.0, 0.0)?, at(0.0, 1.0)?, at(0.0, -1.0)?);
        Some([
            [(xp[0] - xm[0]) / 2.0, (yp[0] - ym[0]) / 2.0],
            [(xp[1] - xm[1]) / 2.0, (yp[1] - ym[1]) / 2.0],
        ])
    }

    /// The candidate verified match sets between the new frame and partner `p`, none when the pair is refused.
    ///
    /// A façade is nearly a plane, which makes the eight-point essential matrix ill-conditioned and, with the low
    /// inlier share of repeated texture, hard to find by sampling eight at a time. So the dominant plane comes
    /// first (four-point samples), and when it holds a fair share of the matches its homography guides a second,
    /// much richer matching: candidates only near their predicted position. Scenes without a dominant plane (a
    /// roof, a corner) are verified with the essential matrix.
    /// `predicted` is the transfer the loops through partners already accepted expect; it guides a matching of
    /// its own, which finds the pair's true matches even where its mutual matches are mostly repeated texture.
    fn hypotheses(
        &self,
        features: &FrameFeatures,
        rays: &[Ray],
        p: usize,
        matches: &[(usize, usize)],
        ransac: &Ransac,
        predicted: Option<Matrix3<f64>>,
    ) -> Vec<Hypothesis> {
        let other = &self.frames[p];
        let (ra, rb): (Vec<Ray>, Vec<Ray>) = matches.iter().map(|&(i, j)| (rays[i], other.rays[j])).unzip();
        let enough = |n: usize| n >= self.params.min_inliers && n as f64 >= self.params.min_inlier_ratio * matches.len() as f64;
        let tolerance = self.params.plane_tolerance_px * self.camera.pixel_size_mm / self.camera.focal_mm;
        if tolerance > 0.0 {
            // Repeated bays offer more than one plausible plane transfer (the true one, and one bay off), all
            // of them kept for `choose`.
            let mut remaining: Vec<usize> = (0..matches.len()).collect();
            let mut found: Vec<Hypothesis> = predicted.iter().filter_map(|h| self.guided(features, rays, other, h)).collect();
            for _ in 0..self.params.plane_hypotheses {
                let (sa, sb): (Vec<Ray>, Vec<Ray>) = remaining.iter().map(|&m| (ra[m], rb[m])).unzip();
                let plane: Vec<usize> = dominant_plane(
                    &sa,
                    &sb,
                    &Ransac {
                        threshold: tolerance,
                        ..*ransac
                    },
                )
                .into_iter()
                .map(|i| remaining[i])
                .collect();
                // The share test is for the pair; a further hypothesis needs only its minimum support.
                if plane.len() < self.params.min_inliers || (remaining.len() == matches.len() && !enough(plane.len())) {
                    break;
                }
                let Some(h) = homography(
                    &plane.iter().map(|&m| ra[m]).collect::<Vec<_>>(),
                    &plane.iter().map(|&m| rb[m]).collect::<Vec<_>>(),
                ) else {
                    break;
                };
                remaining.retain(|m| !plane.contains(m));
                found.extend(self.guided(features, rays, other, &h));
            }
            if !found.is_empty() {
                return found;
            }
        }
        let inliers = verify(&ra, &rb, ransac, self.params.min_inliers);
        let verified = self.consistent(features, other, inliers.iter().map(|&m| matches[m]).collect());
        if enough(verified.len()) {
            vec![Hypothesis {
                matches: verified,
                plane: None,
            }]
        } else {
            Vec::new()
        }
    }

    /// The pair's hypotheses and, where neither a loop through an accepted partner nor the camera's steady motion can
    /// judge them (the frame's first partner, not the previous frame), each found transfer moved by one period of the partner image's repetition
    /// and diagonally ([`lattice_steps`] of [`repetition_periods`]: the bay and the storey) where that guides more
    /// matches than any found. At the
    /// jump between two strips at different heights the second strip sees each storey as the first saw the storey
    /// below, so a transfer one storey off can be the only one the pair's mutual matches offer; shifted by the
    /// storey it becomes the true one, which guides more matches.
    fn with_lattice_shifts(&self, features: &FrameFeatures, rays: &[Ray], p: usize, mut hypotheses: Vec<Hypothesis>) -> Vec<Hypothesis> {
        if !self.params.lattice_shifts {
            return hypotheses;
        }
        let other = &self.frames[p];
        let at = other.image_plane();
        let px = self.camera.pixel_size_mm / self.camera.focal_mm;
        let steps = lattice_steps(&repetition_periods(
            &other.features,
            &at,
            LATTICE_KEYPOINTS,
            self.params.plane_tolerance_px * px,
            4.0 * self.params.plane_tolerance_px * px,
            self.params.min_inliers,
        ));
        let found: Vec<Matrix3<f64>> = hypotheses.iter().filter_map(|h| h.plane).collect();
        let found_best = hypotheses.iter().map(|h| h.matches.len()).max().unwrap_or(0);
        let shifted = found
            .iter()
            .flat_map(|h| {
                steps
                    .iter()
                    .map(move |d| Matrix3::new(1.0, 0.0, d[0], 0.0, 1.0, d[1], 0.0, 0.0, 1.0) * h)
            })
            .filter_map(|h| self.grown(features, rays, other, &h))
            .max_by_key(|g| g.matches.len());
        // Clearly more: one period off, the façade's repetition alone finds almost as many.
        if let Some(g) = shifted.filter(|g| COMPARABLE_SUPPORT * g.matches.len() as f64 > found_best as f64) {
            hypotheses.push(g);
        }
        hypotheses
    }

    /// [`guided`](Self::guided) from `h` within [`SHIFT_TOLERANCE`] times the usual distance, then again from each
    /// refitted transfer while that guides more matches: a transfer moved by a period of the image is right near the
    /// image centre only (the façade's lattice is a translation on the wall, not in the image, and a bay in one part
    /// of the image is not a bay in another), and the refit carries it to the edges.
    fn grown(&self, features: &FrameFeatures, rays: &[Ray], other: &Frame, h: &Matrix3<f64>) -> Option<Hypothesis> {
        let mut best = self.guided_within(features, rays, other, h, SHIFT_TOLERANCE * self.params.plane_tolerance_px)?;
        for _ in 0..GROWING_ROUNDS {
            let Some(plane) = best.plane else { break };
            match self.guided(features, rays, other, &plane) {
                Some(next) if next.matches.len() > best.matches.len() => best = next,
                _ => break,
            }
        }
        Some(best)
    }

    /// The matches guided by the plane transfer `h` (new frame → `other`), with `h` refitted to them.
    fn guided(&self, features: &FrameFeatures, rays: &[Ray], other: &Frame, h: &Matrix3<f64>) -> Option<Hypothesis> {
        self.guided_within(features, rays, other, h, self.params.plane_tolerance_px)
    }

    /// [`guided`](Self::guided) with candidates within `tolerance_px` of the transfer.
    fn guided_within(
        &self,
        features: &FrameFeatures,
        rays: &[Ray],
        other: &Frame,
        h: &Matrix3<f64>,
        tolerance_px: f64,
    ) -> Option<Hypothesis> {
        let tolerance = tolerance_px * self.camera.pixel_size_mm / self.camera.focal_mm;
        let at = other.image_plane();
        let predicted: Vec<Option<[f64; 2]>> = rays.iter().map(|r| transfer_point(h, r)).collect();
        let guided = guided_match(
            features,
            &other.features,
            &predicted,
            &at,
            tolerance,
            self.params.guided_ratio,
            self.params.guided_max_distance,
        );
        let matches = self.consistent(features, other, guided);
        if matches.is_empty() {
            return None;
        }
        let (a, b): (Vec<Ray>, Vec<Ray>) = matches.iter().map(|&(i, j)| (rays[i], other.rays[j])).unzip();
        let plane = homography(&a, &b).or(Some(*h));
        Some(Hypothesis { matches, plane })
    }

    /// Picks among a pair's hypotheses. A façade of identical bays can be matched one bay off as a whole,
    /// consistently enough to pass every two-view test; what tells the true transfer from the others is the loop
    /// through a third view (`H_kp ≈ H_ap · H_ka` for a partner `a` already accepted, with `H_ap` known from when
    /// the later of the two arrived), or, for the first partner, the camera's steady motion along its path (the
    /// step to the previous frame resembles the previous frame's step). Without either, the hypothesis that guides
    /// the most matches wins. A hypothesis that contradicts every loop is refused.
    fn choose(&self, new: usize, p: usize, hypotheses: Vec<Hypothesis>, accepted: &[(usize, Matrix3<f64>)], rays: &[Ray]) -> Hypothesis {
        let tolerance = 2.0 * self.params.plane_tolerance_px * self.camera.pixel_size_mm / self.camera.focal_mm;
        let gap = |h: &Hypothesis, expected: &Matrix3<f64>| -> f64 {
            let Some(plane) = h.plane else { return f64::INFINITY };
            let mut gaps: Vec<f64> = h
                .matches
                .iter()
                .filter_map(|&(i, _)| {
                    let (u, v) = (transfer_point(&plane, &rays[i])?, transfer_point(expected, &rays[i])?);
                    Some((u[0] - v[0]).hypot(u[1] - v[1]))
                })
                .collect();
            gaps.sort_by(f64::total_cmp);
            gaps.get(gaps.len() / 2).copied().unwrap_or(f64::INFINITY)
        };
        let loops: Vec<Matrix3<f64>> = accepted
            .iter()
            .filter_map(|&(a, h_ka)| Some(self.plane_between(a, p)? * h_ka))
            .collect();
        let most = |hs: Vec<Hypothesis>| hs.into_iter().max_by_key(|h| h.matches.len()).unwrap_or_default();
        if !loops.is_empty() {
            // The hypothesis closest to the loops, if it agrees with most of them.
            let agreeing = |h: &Hypothesis| loops.iter().filter(|l| gap(h, l) <= tolerance).count();
            let best = hypotheses.into_iter().max_by_key(|h| (agreeing(h), h.matches.len()));
            return best.filter(|h| 2 * agreeing(h) > loops.len()).unwrap_or_default();
        }
        // The previous frame's step to its own predecessor, when this partner is that previous frame.
        let step = (p + 1 == new).then(|| self.plane_between(p, p.checked_sub(1)?)).flatten();
        match step {
            Some(step) if hypotheses.len() > 1 => comparable_support(hypotheses)
                .into_iter()
                .min_by(|a, b| gap(a, &step).total_cmp(&gap(b, &step)).then(b.matches.len().cmp(&a.matches.len())))
                .unwrap_or_default(),
            _ => most(hypotheses),
        }
    }

    /// The plane homography from frame index `a` to `b`: the one measured between them, else composed along the
    /// path of consecutive frames (within `loop_chain` steps), else none.
    fn plane_between(&self, a: usize, b: usize) -> Option<Matrix3<f64>> {
        let direct = |a: usize, b: usize| match (self.planes.get(&(a, b)), self.planes.get(&(b, a))) {
            (Some(h), _) => Some(*h),
            (None, Some(h)) => h.try_inverse(),
            _ => None,
        };
        if let Some(h) = direct(a, b) {
            return Some(h);
        }
        if a.abs_diff(b) > self.params.loop_chain {
            return None;
        }
        let mut h = Matrix3::identity();
        let mut at = a;
        while at != b {
            let next = if b > at { at + 1 } else { at - 1 };
            h = direct(at, next)? * h;
            at = next;
        }
        Some(h)
    }

    /// The matches whose displacement agrees with their neighbours', or none when fewer than `min_inliers` do.
    fn consistent(&self, features: &FrameFeatures, other: &Frame, matches: Vec<(usize, usize)>) -> Vec<(usize, usize)> {
        let pairs: Vec<([f64; 2], [f64; 2])> = matches.iter().map(|&(i, j)| (features.px[i], other.features.px[j])).collect();
        let keep = consistent_displacements(&pairs, self.params.neighbours, self.params.displacement_tolerance_px);
        let kept: Vec<(usize, usize)> = matches.into_iter().zip(keep).filter_map(|(m, k)| k.then_some(m)).collect();
        if kept.len() < self.params.min_inliers {
            return Vec::new();
        }
        kept
    }

    /// Lets frame index `old` go: it is no partner any more ([`Matcher::partners`] looks `keep_frames` back), so
    /// its keypoints, their track links, the anchors it holds and its plane transfers are dropped. Tracks it shares
    /// with later frames go on there. Its number stays, as the frames' indices are positions.
    fn forget(&mut self, old: usize) {
        let frame = &mut self.frames[old];
        let keypoints = frame.features.px.len();
        frame.features = FrameFeatures::default();
        frame.sample = FrameFeatures::default();
        frame.rays = Vec::new();
        frame.image = None;
        for kp in 0..keypoints {
            let Some(track) = self.track_of.remove(&(old, kp)) else {
                continue;
            };
            if let Some(frames) = self.frames_of.get_mut(&track) {
                frames.retain(|&f| f != old);
                if frames.is_empty() {
                    self.frames_of.remove(&track);
                }
            }
            if self.anchors.get(&track).is_some_and(|a| a.0 == old) {
                self.anchors.remove(&track);
            }
        }
        self.planes.retain(|&(a, b), _| a != old && b != old);
    }

    fn observe(&mut self, track: u64, at: (usize, usize)) {
        self.track_of.insert(at, track);
        self.frames_of.entry(track).or_default().push(at.0);
    }

    /// Joins a verified match (`new` keypoint in the new frame, `old` in a partner) to the tracks. Tracks are never
    /// merged: two existing tracks stay apart, so every id published stays valid.
    fn link(
        &mut self,
        new: (usize, usize),
        old: (usize, usize),
        features: &FrameFeatures,
        out: &mut Vec<(Observation, usize)>,
        number: u64,
    ) {
        let has = |s: &Self, t: u64, f: usize| s.frames_of.get(&t).is_some_and(|v| v.contains(&f));
        let of_old = |s: &Self, track: u64| {
            let o = &s.frames[old.0];
            let observation = Observation {
                track,
                frame: o.number,
                px: o.features.px[old.1],
            };
            (observation, old.0)
        };
        let of_new = |track: u64| {
            let observation = Observation {
                track,
                frame: number,
                px: features.px[new.1],
            };
            (observation, new.0)
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
                let anchor = of_old(self, t);
                self.anchors.insert(t, (old.0, anchor.0.px));
                out.extend([anchor, of_new(t)]);
            }
            (Some(t), None) if !has(self, t, old.0) => {
                self.observe(t, old);
                out.push(of_old(self, t));
            }
            _ => {}
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_steady_motion_only_chooses_among_hypotheses_of_comparable_support() {
        // Frame 12 of the A55 strips at full size: the true transfer (9,306 matches), one a bay off (3,439) and a
        // small one (698) that lay closer to the previous step than the true one and was chosen.
        let of = |n: usize| Hypothesis {
            matches: vec![(0, 0); n],
            plane: None,
        };
        let kept: Vec<usize> = comparable_support(vec![of(9306), of(3439), of(698)])
            .iter()
            .map(|h| h.matches.len())
            .collect();
        assert_eq!(kept, [9306]);
        // Held-out A55 buildings at full size: one bay off at the jump between the strips (@1004, frame 9) and
        // within a strip (@1006, frame 15), each nearer the previous step than the true transfer and chosen by it.
        for (truth, bay_off) in [(2443, 1427), (2950, 1668), (905, 666)] {
            let kept: Vec<usize> = comparable_support(vec![of(bay_off), of(truth)])
                .iter()
                .map(|h| h.matches.len())
                .collect();
            assert_eq!(kept, [truth]);
        }
        // Bays so alike that both transfers find about as many matches: both stay for the steady motion to decide.
        let kept: Vec<usize> = comparable_support(vec![of(905), of(820)]).iter().map(|h| h.matches.len()).collect();
        assert_eq!(kept, [905, 820]);
    }

    #[test]
    fn the_grid_finds_the_same_nearest_neighbours_as_a_full_search() {
        let mut state = 11u64;
        let mut next = || {
            state = state.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
            (state >> 40) as f64 / (1u64 << 24) as f64
        };
        // Clustered points, duplicates (equal distances) and a far outlier.
        let mut points: Vec<[f64; 2]> = (0..400)
            .map(|_| [next() * 2000.0, next() * 300.0 + 1000.0 * (next() > 0.8) as i32 as f64])
            .collect();
        points.extend([[5.0, 5.0], [5.0, 5.0], [6.0, 5.0], [1.0e5, 3.0]]);
        for k in [1, 8, 30] {
            let brute: Vec<Vec<usize>> = (0..points.len())
                .map(|i| {
                    let mut d: Vec<(f64, usize)> = (0..points.len())
                        .filter(|&j| j != i)
                        .map(|j| ((points[j][0] - points[i][0]).powi(2) + (points[j][1] - points[i][1]).powi(2), j))
                        .collect();
                    d.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
                    let mut v: Vec<usize> = d[..k].iter().map(|x| x.1).collect();
                    v.sort_unstable();
                    v
                })
                .collect();
            let grid: Vec<Vec<usize>> = k_nearest(&points, k)
                .into_iter()
                .map(|mut v| {
                    v.sort_unstable();
                    v
                })
                .collect();
            assert_eq!(grid, brute, "k = {k}");
        }
    }
}
