//! The orientation stage: exterior orientations from tie points as frames arrive. Implementation `bundle` below;
//! `essential` (seed 001) in [`essential`]'s terms, on the same block.
//!
//! The first pair with enough verified common tracks starts the block: the second camera is placed against the
//! image flow with the first as datum and the pair is adjusted (a façade is nearly a plane, where the linear
//! essential matrix is ill-conditioned but the collinearity adjustment is not). Each later frame is resected from
//! the tracks already intersected, starting at the nearest oriented frame or its extrapolation along the path; new
//! tracks are intersected; the latest `window` frames are adjusted (the sliding window), the earlier ones held. As
//! soon as three control points are intersected the block is moved into the control frame by a similarity and the
//! control points join the adjustment with their a-priori standard deviations. From then on a resected frame must
//! agree with the control points it measures, or is resected from them (`control_veto`: ties matched a storey or
//! a bay off). At the end a full adjustment removes outliers and solves again, and the check points are intersected
//! for `checkpoints.csv`.
#![warn(missing_docs)]
pub mod calibration_report;
pub mod colmap;
mod control_veto;
mod essential;
pub mod results;
pub mod stage;

use std::collections::{BTreeMap, BTreeSet};

use lineflow_photogrammetry::bundle::{adjust, resect, BundleOptions, BundleProblem, BundleReport, ImageObservation, PointPrior};
use lineflow_photogrammetry::epipolar::{verify, Ransac, Ray};
use lineflow_photogrammetry::interior::parse_interior;
use lineflow_photogrammetry::intersect::{intersect_rays, similarity};
use lineflow_photogrammetry::{Camera, Interior, Mat3, Pose, SelfCalibration, Vec3};

/// Appends observations and their measured pixels.
fn extend(observations: &mut Vec<ImageObservation>, pixels: &mut Vec<[f64; 2]>, obs: Vec<(ImageObservation, [f64; 2])>) {
    for (o, px) in obs {
        observations.push(o);
        pixels.push(px);
    }
}

/// A frame oriented only at the end of the stream must lie within this many median frame spacings of a frame
/// beside it in the sequence ([`Block::near_a_neighbour`]); a hand-held strip varies its spacing by less.
const MAX_NEIGHBOUR_SPACINGS: f64 = 2.5;

/// Settings.
#[derive(Debug, Clone, serde::Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct OrientationParams {
    /// A-priori standard deviation of a tie-point measurement, pixels.
    pub tie_sigma_px: f64,
    /// A-priori standard deviation of a target measurement, pixels.
    pub target_sigma_px: f64,
    /// Common tracks needed to start from a pair.
    pub min_init_tracks: usize,
    /// Intersected tracks needed to resect a frame.
    pub min_resect_points: usize,
    /// Smallest angle between rays for a new point, degrees.
    pub min_angle_deg: f64,
    /// Frames adjusted as each new one arrives (the sliding window); earlier frames are held and settled.
    pub window: usize,
    /// `essential`: polish each linear relative orientation by minimising the Sampson distances (from the linear
    /// solution and from the strip's motion, keeping the better); `false` is the seed's linear method alone.
    pub refine_relative: bool,
    /// `bundle`: the check points' image measurements take part in the adjustment as tie points (their surveyed
    /// coordinates never do), as in classical aerial triangulation: long, precise tracks.
    pub check_points_as_ties: bool,
    /// `bundle`: at the end, the tie points' standard deviation is estimated from the adjustment (their variance
    /// component, the targets' `target_sigma_px` held), so that ties and targets are weighted as precise as they
    /// are; `tie_sigma_px` is then only the start.
    pub estimate_tie_sigma: bool,
    /// `bundle`: once georeferenced, the whole block is moved into the control frame again whenever its
    /// intersected control points lie this far off (RMS, metres).
    pub regeoreference_m: f64,
    /// `bundle`: interior parameters estimated in the adjustments (self-calibration: any of `f`, `x0`, `y0`, `k1`,
    /// `k2`, `k3`, `p1`, `p2`, or `["all"]`); empty (the default) holds the camera model as given.
    pub self_calibrate: Vec<String>,
    /// `bundle`: oriented frames before the interior joins the adjustments (a pair or three frames of a façade
    /// cannot tell the principal distance from the distance to the wall).
    pub self_calibrate_min_frames: usize,
    /// `bundle`: standard deviation of the camera model's principal distance as an observation when f is
    /// self-calibrated, relative (0.01: a lens's marked focal length within 1 %); 0 leaves f to the images alone.
    /// Where the block cannot tell f from the distance to the wall (one or two strips of a façade, square on), it
    /// keeps f near the marked value instead of letting it wander.
    pub focal_sigma: f64,
}

impl OrientationParams {
    /// The interior parameters to estimate.
    ///
    /// # Errors
    /// An unknown name.
    pub fn interior(&self) -> Result<Vec<Interior>, String> {
        if self.self_calibrate.iter().any(|n| n == "all") {
            return Ok(Interior::ALL.to_vec());
        }
        parse_interior(&self.self_calibrate)
    }
}

impl lineflow_runtime::StageParams for OrientationParams {
    fn validate(&self) -> Result<(), lineflow_runtime::ParamError> {
        use lineflow_runtime::params::{at_least, in_half_open, positive};
        positive("tie_sigma_px", self.tie_sigma_px)?;
        positive("target_sigma_px", self.target_sigma_px)?;
        at_least("min_init_tracks", self.min_init_tracks, 8)?;
        at_least("min_resect_points", self.min_resect_points, 6)?;
        in_half_open("min_angle_deg", self.min_angle_deg, 0.0, 90.0)?;
        positive("regeoreference_m", self.regeoreference_m)?;
        at_least("self_calibrate_min_frames", self.self_calibrate_min_frames, 3)?;
        lineflow_runtime::params::non_negative("focal_sigma", self.focal_sigma)?;
        if let Err(e) = self.interior() {
            return Err(lineflow_runtime::ParamError::new(
                "self_calibrate",
                e,
                format!("{:?}", self.self_calibrate),
            ));
        }
        at_least("window", self.window, 2)
    }
}

impl Default for OrientationParams {
    fn default() -> Self {
        Self {
            tie_sigma_px: 0.5,
            target_sigma_px: 0.3,
            min_init_tracks: 25,
            min_resect_points: 8,
            min_angle_deg: 1.0,
            window: 10,
            refine_relative: true,
            check_points_as_ties: true,
            estimate_tie_sigma: true,
            regeoreference_m: 0.25,
            self_calibrate: Vec::new(),
            self_calibrate_min_frames: 5,
            focal_sigma: 0.01,
        }
    }
}

/// How frames are oriented: the launch file's `impl`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Method {
    /// Resection, intersection and the sliding-window and final bundle adjustments with control points.
    Bundle,
    /// Chained essential-matrix relative orientations and a transformation into the control frame (seed 001).
    Essential,
}

/// A surveyed point.
#[derive(Debug, Clone)]
pub struct Surveyed {
    /// Coordinates, metres.
    pub xyz: Vec3,
    /// Standard deviations, metres.
    pub sigma_m: [f64; 3],
    /// Control (in the adjustment) or check point.
    pub control: bool,
}

#[derive(Debug, Clone, Default)]
struct Track {
    /// (frame, ideal photo coordinates).
    obs: Vec<(u64, [f64; 2])>,
    /// The measured pixel of each observation, in the order of `obs`.
    measured: Vec<[f64; 2]>,
    point: Option<Vec3>,
}

/// Two frames' common tracks (ideal coordinates in the partner, in the new frame, track id), their rays, and the
/// essential-matrix inliers among them.
struct VerifiedPair {
    partner: u64,
    common: Vec<([f64; 2], [f64; 2], u64)>,
    a: Vec<Ray>,
    b: Vec<Ray>,
    inliers: Vec<usize>,
}

/// The block being oriented.
pub struct Block {
    params: OrientationParams,
    method: Method,
    /// Control points of the last move into the control frame (`essential`).
    georeferenced_with: usize,
    camera: Camera,
    /// Oriented frames.
    pub poses: BTreeMap<u64, Pose>,
    tracks: BTreeMap<u64, Track>,
    targets: BTreeMap<String, Track>,
    surveyed: BTreeMap<String, Surveyed>,
    /// Whether the block is in the control frame.
    pub georeferenced: bool,
    frames: BTreeSet<u64>,
    /// The last adjustment's report.
    pub report: BundleReport,
    /// The initial pair, held fixed (the datum) until the block is georeferenced.
    pair: Vec<u64>,
    /// Frames in the order they were oriented.
    order: Vec<u64>,
    /// Per frame: how often its pose changed, and its standard deviations (centre m, angles rad) from the last
    /// adjustment that moved it.
    pub states: BTreeMap<u64, FrameState>,
    /// Whether the end-of-stream adjustment has run.
    pub finished: bool,
    /// The tie points' a-priori standard deviation in the adjustments, pixels: `tie_sigma_px`, or its estimate.
    pub tie_sigma_px: f64,
    /// The interior parameters the adjustments estimate (`self_calibrate`).
    interior: Vec<Interior>,
    /// The principal distance of the camera the block was made for, mm (the prior of a self-calibrated f).
    nominal_focal_mm: f64,
    /// Tracks whose observations in some frame disagreed with that frame's control points, and the track those
    /// observations were moved to (`control_veto`).
    split: BTreeMap<u64, u64>,
    /// Frames whose ties their control points vetoed, placed by those control points instead.
    vetoed: BTreeSet<u64>,
}

/// What is known about one oriented frame besides its pose.
#[derive(Debug, Clone, Copy, Default)]
pub struct FrameState {
    /// Adjustments that changed the pose.
    pub revision: u32,
    /// Outside the sliding window: held until the end-of-stream adjustment.
    pub settled: bool,
    /// Standard deviations of the centre (m) and angles (rad); NaN where not estimated.
    pub sigmas: Option<([f64; 3], [f64; 3])>,
}

impl Block {
    /// An empty block for images of `camera`.
    pub fn new(params: OrientationParams, camera: Camera) -> Self {
        Self {
            tie_sigma_px: params.tie_sigma_px,
            interior: params.interior().unwrap_or_default(),
            nominal_focal_mm: camera.focal_mm,
            params,
            method: Method::Bundle,
            georeferenced_with: 0,
            camera,
            poses: BTreeMap::new(),
            tracks: BTreeMap::new(),
            targets: BTreeMap::new(),
            surveyed: BTreeMap::new(),
            georeferenced: false,
            frames: BTreeSet::new(),
            report: BundleReport::default(),
            pair: Vec::new(),
            order: Vec::new(),
            states: BTreeMap::new(),
            finished: false,
            split: BTreeMap::new(),
            vetoed: BTreeSet::new(),
        }
    }

    /// The same block oriented by `method`.
    pub fn with_method(self, method: Method) -> Self {
        Self { method, ..self }
    }

    fn ideal(&self, px: [f64; 2]) -> [f64; 2] {
        self.camera.pixel_to_ideal(px)
    }

    fn ray(&self, ideal: [f64; 2]) -> Ray {
        Ray::new(ideal[0] / self.camera.focal_mm, ideal[1] / self.camera.focal_mm, -1.0)
    }

    /// Adds tie-point observations (track, frame, measured pixel).
    pub fn add_ties(&mut self, ties: impl IntoIterator<Item = (u64, u64, [f64; 2])>) {
        for (track, frame, px) in ties {
            let ideal = self.ideal(px);
            let t = self.tracks.entry(track).or_default();
            t.obs.push((frame, ideal));
            t.measured.push(px);
        }
    }

    /// The camera of the block: the one it was made for, or its self-calibrated refinement.
    pub fn camera(&self) -> &Camera {
        &self.camera
    }

    /// Whether the adjustments estimate the interior orientation now.
    fn calibrating(&self) -> bool {
        self.method == Method::Bundle && !self.interior.is_empty() && self.poses.len() >= self.params.self_calibrate_min_frames
    }

    /// A new camera for the block: every measurement's ideal coordinates follow it.
    fn set_camera(&mut self, camera: Camera) {
        self.camera = camera;
        for t in self.tracks.values_mut().chain(self.targets.values_mut()) {
            for ((_, ideal), px) in t.obs.iter_mut().zip(&t.measured) {
                *ideal = camera.pixel_to_ideal(*px);
            }
        }
    }

    /// Every intersected tie point with its (frame, measured pixel) observations in oriented frames.
    pub fn points(&self) -> Vec<colmap::TrackPoint> {
        self.tracks
            .values()
            .filter_map(|t| {
                let obs: Vec<(u64, [f64; 2])> = t
                    .obs
                    .iter()
                    .zip(&t.measured)
                    .filter(|((f, _), _)| self.poses.contains_key(f))
                    .map(|((f, _), px)| (*f, *px))
                    .collect();
                (obs.len() >= 2).then_some((t.point?, obs))
            })
            .collect()
    }

    /// Every frame seen so far, oriented or not.
    pub fn frames(&self) -> impl Iterator<Item = u64> + '_ {
        self.frames.iter().copied()
    }

    /// Sets the surveyed points.
    pub fn set_surveyed(&mut self, points: BTreeMap<String, Surveyed>) {
        self.surveyed = points;
    }

    /// Adds a measurement of a surveyed point in a frame.
    pub fn add_target(&mut self, id: &str, frame: u64, px: [f64; 2]) {
        let ideal = self.ideal(px);
        let t = self.targets.entry(id.to_owned()).or_default();
        t.obs.push((frame, ideal));
        t.measured.push(px);
    }

    fn common(&self, a: u64, b: u64) -> Vec<([f64; 2], [f64; 2], u64)> {
        self.tracks
            .iter()
            .filter_map(|(&id, t)| {
                let pa = t.obs.iter().find(|o| o.0 == a)?.1;
                let pb = t.obs.iter().find(|o| o.0 == b)?.1;
                Some((pa, pb, id))
            })
            .collect()
    }

    /// Orients frame `k` if it can; returns whether it is oriented now.
    pub fn orient(&mut self, k: u64) -> bool {
        self.frames.insert(k);
        if self.poses.contains_key(&k) {
            return true;
        }
        let first = self.poses.is_empty();
        let ok = match (self.method, first) {
            (Method::Essential, _) => self.orient_relative(k),
            (Method::Bundle, true) => self.initialise(k),
            (Method::Bundle, false) => self.resect_frame(k),
        };
        if ok {
            self.order
                .extend(self.poses.keys().filter(|f| !self.order.contains(f)).copied().collect::<Vec<_>>());
            self.intersect_new();
            match self.method {
                Method::Bundle => {
                    self.georeference();
                    self.adjust_block(false);
                    // The adjustment can leave a young block off its control points by metres (its first
                    // frames a step apart, thousands of ties against four targets): moved back at once.
                    self.georeference();
                    if first {
                        self.pair.truncate(1);
                    }
                }
                Method::Essential => {
                    self.georeference_model(false);
                    self.report_chain();
                }
            }
        }
        ok
    }

    /// Every frame seen except `k`.
    fn frames_but(&self, k: u64) -> Vec<u64> {
        self.frames.iter().copied().filter(|&j| j != k).collect()
    }

    /// The frame among `partners` that shares most tracks with `k`, with the common tracks, their rays in both and
    /// the essential-matrix RANSAC inliers among them (empty when too few agree); `None` when too few tracks are
    /// shared.
    fn verified_pair(&self, k: u64, partners: Vec<u64>, seed: u64) -> Option<VerifiedPair> {
        let (partner, common) = partners
            .into_iter()
            .map(|j| (j, self.common(j, k)))
            .max_by_key(|(j, c)| (c.len(), *j))?;
        if common.len() < self.params.min_init_tracks {
            return None;
        }
        let a: Vec<Ray> = common.iter().map(|c| self.ray(c.0)).collect();
        let b: Vec<Ray> = common.iter().map(|c| self.ray(c.1)).collect();
        let ransac = Ransac {
            threshold: 2.0 * self.params.tie_sigma_px * self.camera.pixel_size_mm / self.camera.focal_mm,
            iterations: 2000,
            seed,
        };
        let inliers = verify(&a, &b, &ransac, self.params.min_init_tracks);
        Some(VerifiedPair {
            partner,
            common,
            a,
            b,
            inliers,
        })
    }

    fn initialise(&mut self, k: u64) -> bool {
        let Some(VerifiedPair {
            partner: j,
            common,
            inliers,
            ..
        }) = self.verified_pair(k, self.frames_but(k), 0x0E1E)
        else {
            return false;
        };
        if inliers.is_empty() {
            return false;
        }
        // A façade is nearly planar, which leaves the linear essential matrix ill-conditioned (seed 001's
        // warning): start instead from what a strip gives, the second camera turned like the first and moved against
        // the image flow, and let the adjustment (after the intersection in `orient`) find the relative orientation;
        // collinearity is well posed for a plane, only its linear solution is not.
        let flow = inliers.iter().fold([0.0f64; 2], |acc, &i| {
            let (p, q) = (common[i].0, common[i].1);
            [acc[0] + q[0] - p[0], acc[1] + q[1] - p[1]]
        });
        let away = Vec3::new(-flow[0], -flow[1], 0.0);
        if away.norm() == 0.0 {
            return false;
        }
        let rel = Pose {
            center: away.normalize(),
            rotation: lineflow_photogrammetry::Mat3::identity(),
        };
        self.poses.insert(
            j,
            Pose {
                center: Vec3::zeros(),
                rotation: lineflow_photogrammetry::Mat3::identity(),
            },
        );
        self.poses.insert(k, rel);
        // The pair is adjusted once with its first camera fixed, then both are held as the datum.
        self.pair = vec![j.min(k)];
        tracing::info!(
            "initial pair: frames {j} and {k}, {} of {} common tracks verified",
            inliers.len(),
            common.len()
        );
        true
    }

    fn resect_frame(&mut self, k: u64) -> bool {
        let ties = control_veto::Resection::of_frame(&self.tracks, k);
        let (xyz, obs) = (&ties.xyz, &ties.ideal);
        if xyz.len() < self.params.min_resect_points {
            tracing::warn!("frame {k}: only {} intersected tie points, not oriented yet", xyz.len());
            return false;
        }
        let sigma = self.params.tie_sigma_px * self.camera.pixel_size_mm;
        // Starts: the nearest oriented frame, and the two nearest extrapolated (a strip moves steadily).
        let mut near: Vec<u64> = self.poses.keys().copied().collect();
        near.sort_by_key(|&f| (f.abs_diff(k), f));
        let mut starts = vec![self.poses[&near[0]]];
        if near.len() >= 2 {
            let (a, b) = (&self.poses[&near[0]], &self.poses[&near[1]]);
            let steps = (k as f64 - near[0] as f64) / (near[0] as f64 - near[1] as f64);
            starts.push(Pose {
                center: a.center + (a.center - b.center) * steps,
                rotation: a.rotation,
            });
        }
        let best = starts
            .iter()
            .filter_map(|s| resect(self.camera.focal_mm, s, xyz, obs, sigma))
            .min_by(|x, y| x.1.total_cmp(&y.1));
        match best {
            Some((pose, median)) if median < 3.0 * sigma => match self.checked_by_controls(k, pose, &ties) {
                Some(pose) => {
                    self.split_disagreeing(k, &pose, &ties);
                    self.poses.insert(k, pose);
                    true
                }
                None => false,
            },
            Some((_, median)) => {
                tracing::warn!(
                    "frame {k}: resection failed: median residual {:.1} px of {} tie points (at most {:.1} px), \
                     not oriented yet",
                    median / self.camera.pixel_size_mm,
                    xyz.len(),
                    3.0 * self.params.tie_sigma_px
                );
                false
            }
            None => {
                tracing::warn!("frame {k}: resection did not converge, not oriented yet");
                false
            }
        }
    }

    /// The track's rays (centre, unit direction) from its oriented frames.
    fn rays(&self, t: &Track) -> Vec<(Vec3, Vec3)> {
        t.obs
            .iter()
            .filter_map(|(f, ideal)| self.poses.get(f).map(|p| (p.center, p.ray_of_ideal(&self.camera, *ideal))))
            .collect()
    }

    /// The rays' intersection, where they meet at `min_angle_deg` or more, in front of every camera.
    fn intersect(&self, rays: &[(Vec3, Vec3)]) -> Option<Vec3> {
        let (x, angle) = intersect_rays(rays)?;
        (angle.to_degrees() >= self.params.min_angle_deg && rays.iter().all(|(c, d)| (x - c).dot(d) > 0.0)).then_some(x)
    }

    fn triangulate(&self, t: &Track) -> Option<Vec3> {
        self.intersect(&self.rays(t))
    }

    fn intersect_new(&mut self) {
        let updates: Vec<(u64, Vec3)> = self
            .tracks
            .iter()
            .filter(|(_, t)| t.point.is_none())
            .filter_map(|(&id, t)| {
                let rays = self.rays(t);
                self.intersect(&rays).filter(|x| self.rays_meet(&rays, x)).map(|x| (id, x))
            })
            .collect();
        for (id, x) in updates {
            if let Some(t) = self.tracks.get_mut(&id) {
                t.point = Some(x);
            }
        }
    }

    /// Every control point intersected from the oriented frames, with its surveyed coordinates.
    fn control_pairs(&self) -> Vec<(Vec3, Vec3)> {
        self.targets
            .iter()
            .filter_map(|(id, t)| {
                let s = self.surveyed.get(id).filter(|s| s.control)?;
                Some((self.triangulate(t)?, s.xyz))
            })
            .collect()
    }

    /// Moves every pose and intersected point: centres and points by `point`, rotations by `rotation`.
    fn move_block(&mut self, point: impl Fn(&Vec3) -> Vec3, rotation: impl Fn(&Mat3) -> Mat3) {
        for p in self.poses.values_mut() {
            p.center = point(&p.center);
            p.rotation = rotation(&p.rotation);
        }
        for t in self.tracks.values_mut() {
            if let Some(x) = &mut t.point {
                *x = point(x);
            }
        }
    }

    /// Moves the block into the control frame once three control points are intersected, and again whenever the
    /// intersected control points lie `regeoreference_m` (RMS) or more off their surveyed places. The first move
    /// rests on targets triangulated from a pair a step apart; on full-size images it left a block metres off,
    /// which the adjustments then pulled over only slowly, frame by frame (the live poses and lines were metres
    /// off until the end-of-stream adjustment), and the frames of a second strip failed their resection.
    fn georeference(&mut self) {
        let pairs = self.control_pairs();
        if pairs.len() < 3 {
            return;
        }
        let (from, to): (Vec<Vec3>, Vec<Vec3>) = pairs.into_iter().unzip();
        let Some(s) = similarity(&from, &to) else {
            return;
        };
        let rms = |moved: &dyn Fn(&Vec3) -> Vec3| {
            (from.iter().zip(&to).map(|(a, b)| (moved(a) - b).norm_squared()).sum::<f64>() / from.len() as f64).sqrt()
        };
        let (before, after) = (rms(&|x| *x), rms(&|x| s.apply(x)));
        if self.georeferenced {
            if before < self.params.regeoreference_m || after > 0.5 * before {
                return;
            }
            tracing::info!(
                "moved into the control frame again with {} control points: they lay {before:.3} m (RMS) off, now {after:.3} m",
                from.len()
            );
        } else {
            tracing::info!("georeferenced with {} control points (scale {:.4})", from.len(), s.scale);
        }
        self.move_block(|x| s.apply(x), |m| m * s.rotation.transpose());
        self.georeferenced = true;
    }

    /// The adjustment problem of the oriented frames, and the track id of each point.
    fn problem(&self, window: Option<&BTreeSet<u64>>) -> (BundleProblem, Vec<Option<u64>>, Vec<u64>) {
        let frames: Vec<u64> = self.poses.keys().copied().collect();
        let in_window = |f: &u64| window.is_none_or(|w| w.contains(f));
        let index: BTreeMap<u64, usize> = frames.iter().enumerate().map(|(i, f)| (*f, i)).collect();
        let tie_sigma = self.tie_sigma_px * self.camera.pixel_size_mm;
        let target_sigma = self.params.target_sigma_px * self.camera.pixel_size_mm;
        let mut points = Vec::new();
        let mut ids = Vec::new();
        let mut observations = Vec::new();
        let mut pixels = Vec::new();
        let mut priors = Vec::new();
        // A track's observations in the adjusted frames, as observations of point `point`, with their pixels.
        let observed = |t: &Track, point: usize, sigma_mm: f64| -> Vec<(ImageObservation, [f64; 2])> {
            t.obs
                .iter()
                .zip(&t.measured)
                .filter_map(|((f, ideal), px)| {
                    index.get(f).map(|&camera| {
                        let o = ImageObservation {
                            camera,
                            point,
                            ideal: *ideal,
                            sigma_mm,
                        };
                        (o, *px)
                    })
                })
                .collect()
        };
        for (&id, t) in &self.tracks {
            let Some(x) = t.point else { continue };
            let obs = observed(t, points.len(), tie_sigma);
            if obs.len() < 2 || !t.obs.iter().any(|(f, _)| in_window(f)) {
                continue;
            }
            extend(&mut observations, &mut pixels, obs);
            points.push(x);
            ids.push(Some(id));
        }
        if self.georeferenced {
            for (id, t) in &self.targets {
                let Some(s) = self.surveyed.get(id) else {
                    continue;
                };
                if !s.control {
                    // A check point: its measurements as a tie point's, its coordinates left free.
                    if !self.params.check_points_as_ties || !t.obs.iter().any(|(f, _)| in_window(f)) {
                        continue;
                    }
                    let obs = observed(t, points.len(), target_sigma);
                    if let (true, Some(x)) = (obs.len() >= 2, self.triangulate(t)) {
                        extend(&mut observations, &mut pixels, obs);
                        points.push(x);
                        ids.push(None);
                    }
                    continue;
                }
                let obs = observed(t, points.len(), target_sigma);
                if obs.is_empty() {
                    continue;
                }
                extend(&mut observations, &mut pixels, obs);
                priors.push(PointPrior {
                    point: points.len(),
                    xyz: s.xyz,
                    sigma_m: s.sigma_m,
                });
                points.push(s.xyz);
                ids.push(None);
            }
        }
        let mut fixed: Vec<usize> = frames
            .iter()
            .enumerate()
            .filter(|(_, f)| !in_window(f) || (!self.georeferenced && self.pair.contains(f)))
            .map(|(i, _)| i)
            .collect();
        fixed.dedup();
        let poses = frames.iter().map(|f| self.poses[f]).collect();
        (
            BundleProblem {
                focal_mm: self.camera.focal_mm,
                poses,
                points,
                observations,
                priors,
                fixed,
                calibration: self.calibrating().then(|| SelfCalibration {
                    camera: self.camera,
                    free: self.interior.clone(),
                    pixels,
                    priors: vec![(
                        Interior::Focal,
                        self.nominal_focal_mm,
                        self.params.focal_sigma * self.nominal_focal_mm,
                    )],
                }),
            },
            ids,
            frames,
        )
    }

    /// Adjusts the block: the sliding window of the latest frames, or, with `last`, every frame, removing
    /// outliers and solving again.
    pub fn adjust_block(&mut self, last: bool) {
        let window: Option<BTreeSet<u64>> = (!last).then(|| self.order.iter().rev().take(self.params.window).copied().collect());
        let (mut p, ids, frames) = self.problem(window.as_ref());
        let options = if last {
            BundleOptions::default()
        } else {
            BundleOptions {
                max_iterations: 15,
                outlier_rounds: 1,
                ..Default::default()
            }
        };
        self.report = adjust(&mut p, &options);
        if let Some(interior) = &self.report.interior {
            self.set_camera(interior.camera);
        }
        for (i, (f, pose)) in frames.iter().zip(&p.poses).enumerate() {
            let state = self.states.entry(*f).or_default();
            if p.fixed.contains(&i) {
                state.settled = window.as_ref().is_some_and(|w| !w.contains(f));
                continue;
            }
            state.revision += 1;
            state.settled = false;
            state.sigmas = self.report.pose_sigmas.get(i).copied();
            self.poses.insert(*f, *pose);
        }
        for (id, x) in ids.iter().zip(&p.points) {
            if let Some(t) = id.and_then(|id| self.tracks.get_mut(&id)) {
                t.point = Some(*x);
            }
        }
    }

    /// Orients what is still unoriented now that the block is complete, then the final adjustment.
    pub fn finish(&mut self) {
        let pending: Vec<u64> = self.frames.iter().filter(|f| !self.poses.contains_key(f)).copied().collect();
        let spacing = self.median_spacing();
        for f in pending {
            let oriented = match self.method {
                Method::Bundle => self.resect_frame(f),
                Method::Essential => self.orient_relative(f),
            };
            if !oriented {
                continue;
            }
            if let (false, Some(spacing)) = (self.near_a_neighbour(f, spacing), spacing) {
                // Not near one: there is a neighbour, and it is far.
                let (n, d) = self.neighbour_distances(f)[0];
                tracing::warn!(
                    "frame {f}: resected {d:.2} m from frame {n} beside it in the sequence, {:.1} times the median \
                     spacing of {spacing:.2} m (repeated façade structure matched a bay off?); left unoriented",
                    d / spacing
                );
                self.poses.remove(&f);
                self.states.remove(&f);
                continue;
            }
            self.intersect_new();
        }
        if !self.vetoed.is_empty() {
            tracing::warn!(
                "{} frames were placed by their control points, their tie points vetoed (repeated façade structure \
                 matched a storey or bay off?): {:?}",
                self.vetoed.len(),
                self.vetoed
            );
        }
        match self.method {
            Method::Bundle => {
                self.georeference();
                self.adjust_block(true);
                if self.params.estimate_tie_sigma {
                    self.estimate_tie_sigma();
                }
            }
            Method::Essential => {
                self.georeference_model(true);
                self.report_chain();
            }
        }
        self.finished = true;
    }

    /// The median distance between the centres of consecutive oriented frames (`None` for fewer than three).
    fn median_spacing(&self) -> Option<f64> {
        let mut d: Vec<f64> = self
            .poses
            .iter()
            .zip(self.poses.iter().skip(1))
            .filter(|((a, _), (b, _))| *b - *a == 1)
            .map(|((_, p), (_, q))| (p.center - q.center).norm())
            .collect();
        if d.len() < 2 {
            return None;
        }
        d.sort_by(f64::total_cmp);
        Some(d[d.len() / 2])
    }

    /// Whether frame `f`, oriented only when the block was complete (it matched no neighbour while the photos
    /// arrived), lies within [`MAX_NEIGHBOUR_SPACINGS`] median spacings of an oriented frame next to it in the
    /// sequence. A façade's repeated bays can be matched one bay off as consistently as in truth, and a frame
    /// resected from such tie points fits them well but lies metres away, spoiling every point it observes; a
    /// frame with no oriented sequence neighbour, or a block too small for a spacing, is not judged.
    fn near_a_neighbour(&self, f: u64, spacing: Option<f64>) -> bool {
        let Some(spacing) = spacing else { return true };
        let neighbours = self.neighbour_distances(f);
        neighbours.is_empty() || neighbours.iter().any(|(_, d)| *d <= MAX_NEIGHBOUR_SPACINGS * spacing)
    }

    /// The oriented frames beside `f` in the sequence (before, then after), with their distances from it, metres;
    /// none when `f` itself is not oriented.
    fn neighbour_distances(&self, f: u64) -> Vec<(u64, f64)> {
        let Some(pose) = self.poses.get(&f) else { return Vec::new() };
        [f.checked_sub(1), f.checked_add(1)]
            .into_iter()
            .flatten()
            .filter_map(|n| self.poses.get(&n).map(|q| (n, (q.center - pose.center).norm())))
            .collect()
    }

    /// The tie points' variance component: their a-priori σ scaled by the adjustment's σ̂0 (which the thousands of
    /// tie observations dominate) and the block adjusted again, until σ̂0 is within 5 % of 1. The targets keep
    /// theirs, so the ties' weight against the control and check targets becomes what their residuals say: with
    /// least-squares matched ties of 0.15 px and 0.3 px targets, the 0.5 px default weighted a target as about
    /// three ties, where a tie in fact deserves about four times a target's weight.
    fn estimate_tie_sigma(&mut self) {
        for _ in 0..3 {
            let s0 = self.report.sigma0;
            if !(s0.is_finite() && s0 > 0.0) || (s0 - 1.0).abs() < 0.05 {
                break;
            }
            self.tie_sigma_px = (self.tie_sigma_px * s0).clamp(0.02, 10.0);
            self.adjust_block(true);
        }
        tracing::info!(
            "tie points' standard deviation estimated: {:.3} px (a priori {:.3} px), σ0 {:.2}",
            self.tie_sigma_px,
            self.params.tie_sigma_px,
            self.report.sigma0
        );
    }

    /// Adds a frame whose pose comes from elsewhere (the user's `poses.csv` in place of this stage): oriented,
    /// settled and in the control frame as given; nothing is adjusted, and check points are intersected from the
    /// given poses.
    pub fn add_supplied(&mut self, frame: u64, pose: Pose, sigmas: Option<([f64; 3], [f64; 3])>) {
        self.frames.insert(frame);
        self.poses.insert(frame, pose);
        self.states.insert(
            frame,
            FrameState {
                revision: 1,
                settled: true,
                sigmas,
            },
        );
        self.georeferenced = true;
    }

    /// The ground sample distance at the check points: at the median distance from the oriented frames' centres to
    /// the surveyed check points, metres.
    pub fn check_point_gsd_m(&self) -> Option<f64> {
        let mut d: Vec<f64> = self
            .surveyed
            .values()
            .filter(|s| !s.control)
            .flat_map(|s| self.poses.values().map(move |p| (s.xyz - p.center).norm()))
            .collect();
        d.sort_by(f64::total_cmp);
        d.get(d.len() / 2).map(|&m| self.camera().gsd_m(m))
    }

    /// Check points intersected from the oriented frames: (id, estimated − surveyed).
    pub fn check_points(&self) -> Vec<(String, Vec3)> {
        self.targets
            .iter()
            .filter_map(|(id, t)| {
                let s = self.surveyed.get(id).filter(|s| !s.control)?;
                Some((id.clone(), self.triangulate(t)? - s.xyz))
            })
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use lineflow_photogrammetry::look_at;

    /// Two frames in the control frame facing a wall, each measuring a control and a check target.
    fn two_frames(check_points_as_ties: bool) -> Block {
        let params = OrientationParams {
            check_points_as_ties,
            ..OrientationParams::default()
        };
        let targets = [("C1", Vec3::new(0.5, 0.0, 1.0), true), ("K1", Vec3::new(1.5, 0.0, 1.8), false)];
        two_frames_seeing(params, &targets, 2.0, Vec3::new(1.0, 0.0, 1.5))
    }

    /// Frames 0 and 1, at x = 0 and `x1`, 10 m in front of the wall y = 0 and aimed at `aim`, with their poses
    /// supplied, each measuring every target (id, surveyed coordinates, control).
    fn two_frames_seeing(params: OrientationParams, targets: &[(&str, Vec3, bool)], x1: f64, aim: Vec3) -> Block {
        let camera = Camera::pinhole(1000, 800, 0.01, 20.0);
        let mut block = Block::new(params, camera);
        block.set_surveyed(
            targets
                .iter()
                .map(|&(id, xyz, control)| {
                    let s = Surveyed {
                        xyz,
                        sigma_m: [0.002; 3],
                        control,
                    };
                    (id.to_owned(), s)
                })
                .collect(),
        );
        for (frame, x) in [(0u64, 0.0), (1, x1)] {
            let center = Vec3::new(x, -10.0, 1.5);
            let pose = Pose {
                center,
                rotation: look_at(&center, &aim, &Vec3::z()),
            };
            block.add_supplied(frame, pose, None);
            for (id, xyz, _) in targets {
                block.add_target(id, frame, pose.project(&camera, xyz).expect("in view"));
            }
        }
        block
    }

    #[test]
    fn check_points_join_the_adjustment_as_tie_points_and_their_coordinates_never_do() {
        for ties in [true, false] {
            let (p, _, _) = two_frames(ties).problem(None);
            // The control point with its prior; the check point, with `ties`, as a free point of two observations.
            assert_eq!(p.priors.len(), 1, "ties {ties}");
            assert_eq!(p.points.len(), 1 + usize::from(ties), "ties {ties}");
            assert_eq!(p.observations.len(), 2 + 2 * usize::from(ties), "ties {ties}");
            assert!(p.priors.iter().all(|prior| (prior.xyz - Vec3::new(0.5, 0.0, 1.0)).norm() < 1e-12));
        }
    }

    #[test]
    fn a_georeferenced_block_found_metres_off_its_control_points_is_moved_back_and_one_centimetres_off_is_not() {
        let targets = [
            ("C1", Vec3::new(0.5, 0.0, 1.0), true),
            ("C2", Vec3::new(2.5, 0.0, 1.2), true),
            ("C3", Vec3::new(1.2, 0.0, 2.6), true),
        ];
        let mut block = two_frames_seeing(OrientationParams::default(), &targets, 3.0, Vec3::new(1.5, 0.0, 1.5));
        let truth = block.poses.clone();
        let off_by = |block: &Block| (block.poses[&0].center - truth[&0].center).norm();
        // A datum a few centimetres off is the adjustment's to mend, not a jump's.
        block.move_block(|x| x + Vec3::new(0.03, 0.0, 0.0), |m| *m);
        block.georeference();
        assert!((off_by(&block) - 0.03).abs() < 1e-9, "moved at {} m", off_by(&block));
        // Metres off, turned and scaled: moved back onto the control points.
        let turn = lineflow_photogrammetry::rotation_from_opk(0.0, 0.0, 0.05);
        block.move_block(|x| turn * (x * 1.2) + Vec3::new(2.0, -0.5, 3.0), |m| m * turn.transpose());
        assert!(off_by(&block) > 2.0);
        block.georeference();
        assert!(off_by(&block) < 1e-6, "still {} m off", off_by(&block));
    }

    #[test]
    fn a_frame_resected_a_bay_off_its_sequence_is_left_unoriented() {
        let camera = Camera::pinhole(1000, 800, 0.01, 20.0);
        let mut block = Block::new(OrientationParams::default(), camera);
        let at = |x: f64| {
            let center = Vec3::new(x, -10.0, 1.5);
            Pose {
                center,
                rotation: look_at(&center, &Vec3::new(x, 0.0, 1.5), &Vec3::z()),
            }
        };
        // A strip at 2 m spacing, its first frame (0) not yet oriented.
        for frame in 1..=5u64 {
            block.add_supplied(frame, at(2.0 * frame as f64), None);
        }
        let spacing = block.median_spacing();
        assert!((spacing.unwrap() - 2.0).abs() < 1e-12);
        // Where it belongs, and one spacing off: kept.
        for x in [0.0, 4.0] {
            block.poses.insert(0, at(x));
            assert!(block.near_a_neighbour(0, spacing), "x {x}");
        }
        // Between frames 3 and 4, as repeated bays matched one bay off put it: refused.
        block.poses.insert(0, at(7.5));
        assert!(!block.near_a_neighbour(0, spacing));
        // A strip too short for a spacing judges nothing.
        assert!(block.near_a_neighbour(0, None));
    }
}
