//! A new frame's resection checked against the control points it measures.
//!
//! A façade of one repeated window lets the matcher tie the frames of a second strip to the first one storey or
//! one bay off, as consistently as the true ties: a frame resected from them fits them well (σ0 0.3–0.56) yet lies
//! metres from where it was taken (@3003: a storey, 3.2 m; @3004: a bay, 2.3 m; check points 19 m and 7.6 m off at
//! the end). Its viewing rays of the control points show it at once: they pass metres from the surveyed points,
//! where a frame resected from true ties passes within the block's own georeferencing error. Such a frame is
//! resected again from its control points, joined by the ties that agree with them, and its disagreeing tie
//! observations are split into tracks of their own (they are true correspondences of some other point among
//! the frames that share them, not of the point their track was intersected at).

use lineflow_photogrammetry::bundle::resect;
use lineflow_photogrammetry::intersect::intersect_rays;
use lineflow_photogrammetry::median;
use lineflow_photogrammetry::{Camera, Pose, Vec3};

use std::collections::BTreeMap;

use crate::{Block, Track};

/// Track ids of split-off observations start here, far above the ids the `matcher` stage gives (it counts from 1);
/// a tie-point source of its own numbering must stay below it.
const SPLIT_TRACKS_FROM: u64 = 1 << 62;

/// Control points needed to place a frame whose ties they veto: two, with the ties' rotation held, give its centre
/// with one redundancy; four or more are resected from.
const MIN_CONTROLS: usize = 2;

/// Control points (and agreeing ties) from which a frame is resected in all six elements.
const MIN_POINTS_TO_RESECT: usize = 4;

/// How far (metres) the ray from `center` along the unit `direction` passes from `x`.
fn miss(center: &Vec3, direction: &Vec3, x: &Vec3) -> f64 {
    (x - center).cross(direction).norm()
}

/// How far (metres) the viewing ray of a measured pixel passes from the object point.
fn ray_miss(camera: &Camera, pose: &Pose, ideal: [f64; 2], x: &Vec3) -> f64 {
    miss(&pose.center, &pose.ray_of_ideal(camera, ideal), x)
}

/// Tie points for a resection: intersected object points, the new frame's ideal coordinates of them, their tracks.
pub(crate) struct Resection {
    pub xyz: Vec<Vec3>,
    pub ideal: Vec<[f64; 2]>,
    pub tracks: Vec<u64>,
}

impl Resection {
    /// The intersected tracks frame `k` observes.
    pub(crate) fn of_frame(tracks: &BTreeMap<u64, Track>, k: u64) -> Self {
        let mut ties = Resection {
            xyz: Vec::new(),
            ideal: Vec::new(),
            tracks: Vec::new(),
        };
        for (&id, t) in tracks {
            if let (Some(x), Some(o)) = (t.point, t.obs.iter().find(|o| o.0 == k)) {
                ties.xyz.push(x);
                ties.ideal.push(o.1);
                ties.tracks.push(id);
            }
        }
        ties
    }
}

impl Block {
    /// Farthest (metres, median over the frame's control points) a frame's rays may pass from its control points:
    /// twice what the block itself may lie off them before it is moved back (`regeoreference_m`), far below a
    /// storey or a bay.
    fn control_gate_m(&self) -> f64 {
        2.0 * self.params.regeoreference_m
    }

    /// The control points frame `k` measures, once the block is in the control frame: (surveyed, ideal).
    fn controls_seen(&self, k: u64) -> Vec<(Vec3, [f64; 2])> {
        if !self.georeferenced {
            return Vec::new();
        }
        self.targets
            .iter()
            .filter_map(|(id, t)| {
                let s = self.surveyed.get(id).filter(|s| s.control)?;
                Some((s.xyz, t.obs.iter().find(|o| o.0 == k)?.1))
            })
            .collect()
    }

    /// Where the control points place a frame whose ties put it at `pose`: ties matched a storey or a bay off
    /// move the centre by that step and keep the rotation, so the centre is first found with the rotation held
    /// (the point nearest the rays cast back from the surveyed points along their measured directions), then, with
    /// four control points or more, all six elements are resected. `None` when the result leaves the control
    /// points' rays off them by more than the gate.
    fn placed_by_controls(&self, pose: &Pose, controls: &[(Vec3, [f64; 2])]) -> Option<Pose> {
        let back: Vec<(Vec3, Vec3)> = controls.iter().map(|(x, o)| (*x, -pose.ray_of_ideal(&self.camera, *o))).collect();
        let (center, _) = intersect_rays(&back)?;
        let mut placed = Pose { center, ..*pose };
        if controls.len() >= MIN_POINTS_TO_RESECT {
            let sigma = self.params.target_sigma_px * self.camera.pixel_size_mm;
            let (cx, co): (Vec<Vec3>, Vec<[f64; 2]>) = controls.iter().copied().unzip();
            placed = resect(self.camera.focal_mm, &placed, &cx, &co, sigma)?.0;
        }
        self.control_miss(&placed, controls)
            .is_some_and(|m| m <= self.control_gate_m())
            .then_some(placed)
    }

    /// Median distance (metres) of frame `k`'s control rays under `pose` from the surveyed points.
    fn control_miss(&self, pose: &Pose, controls: &[(Vec3, [f64; 2])]) -> Option<f64> {
        median(controls.iter().map(|(x, o)| ray_miss(&self.camera, pose, *o, x)).collect())
    }

    /// `pose`, resected for frame `k` from `ties`, if the control points the frame measures agree with it;
    /// otherwise the pose the control points place it at, resected again with the ties that agree with it. `None`
    /// (with a warning) when the control points disagree and fewer than two, or no pose fits them.
    pub(crate) fn checked_by_controls(&mut self, k: u64, pose: Pose, ties: &Resection) -> Option<Pose> {
        let controls = self.controls_seen(k);
        let gate = self.control_gate_m();
        let Some(miss) = self.control_miss(&pose, &controls).filter(|&m| m > gate) else {
            return Some(pose);
        };
        if controls.len() < MIN_CONTROLS {
            tracing::warn!(
                "frame {k}: its tie points put it where its {} control point's ray passes {miss:.2} m from it \
                 (repeated façade structure matched a storey or bay off?), and {MIN_CONTROLS} are needed to place \
                 it by them; not oriented",
                controls.len()
            );
            return None;
        }
        let Some(from_controls) = self.placed_by_controls(&pose, &controls) else {
            tracing::warn!(
                "frame {k}: its {} control points' rays pass {miss:.2} m from them and no pose fits the control \
                 points; not oriented",
                controls.len()
            );
            return None;
        };
        let agrees = |p: &Pose, i: usize| ray_miss(&self.camera, p, ties.ideal[i], &ties.xyz[i]) <= gate;
        let agreeing: Vec<usize> = (0..ties.xyz.len()).filter(|&i| agrees(&from_controls, i)).collect();
        let (mut xyz, mut ideal): (Vec<Vec3>, Vec<[f64; 2]>) = controls.iter().copied().unzip();
        xyz.extend(agreeing.iter().map(|&i| ties.xyz[i]));
        ideal.extend(agreeing.iter().map(|&i| ties.ideal[i]));
        let tie_sigma = self.tie_sigma_px * self.camera.pixel_size_mm;
        let joint = (xyz.len() >= MIN_POINTS_TO_RESECT)
            .then(|| resect(self.camera.focal_mm, &from_controls, &xyz, &ideal, tie_sigma))
            .flatten()
            .map(|(p, _)| p)
            .filter(|p| self.control_miss(p, &controls).is_some_and(|m| m <= gate))
            .unwrap_or(from_controls);
        tracing::warn!(
            "frame {k}: its tie points put it where its {} control points' rays pass {miss:.2} m from them \
             (repeated façade structure matched a storey or bay off?); placed by the control points and the {} of \
             {} tie points that agree with them",
            controls.len(),
            agreeing.len(),
            ties.xyz.len(),
        );
        self.vetoed.insert(k);
        Some(joint)
    }

    /// Splits off their tracks frame `k`'s tie observations whose rays under `pose` pass farther from their
    /// tracks' points than the control gate, once the block is in the control frame (before, its scale is the
    /// first pair's). The resection trims them, but left in their tracks they pull the sliding-window adjustment
    /// toward the wrong storey (on @3003 the block was moved 12 m afterwards).
    pub(crate) fn split_disagreeing(&mut self, k: u64, pose: &Pose, ties: &Resection) {
        if !self.georeferenced {
            return;
        }
        let gate = self.control_gate_m();
        let wrong: Vec<u64> = (0..ties.xyz.len())
            .filter(|&i| ray_miss(&self.camera, pose, ties.ideal[i], &ties.xyz[i]) > gate)
            .map(|i| ties.tracks[i])
            .collect();
        if !wrong.is_empty() {
            tracing::info!(
                "frame {k}: {} of {} tie observations pass more than {gate:.2} m from their tracks' points: split off",
                wrong.len(),
                ties.xyz.len()
            );
            self.split_off(k, &wrong);
        }
    }

    /// Whether every one of a track's `rays` passes within the control gate of their intersection `x`, once the
    /// block is in the control frame. A track first seen in one frame of each strip, matched a storey off, is
    /// intersected where its two skew rays pass closest; its point is left out (a frame resected later splits the
    /// observation off), as the adjustments cannot tell which of two rays is wrong.
    pub(crate) fn rays_meet(&self, rays: &[(Vec3, Vec3)], x: &Vec3) -> bool {
        !self.georeferenced || rays.iter().all(|(c, d)| miss(c, d, x) <= self.control_gate_m())
    }

    /// Moves frame `k`'s observations of `tracks` into tracks of their own (one per original track, shared by
    /// every frame split off it).
    fn split_off(&mut self, k: u64, tracks: &[u64]) {
        for id in tracks {
            let Some(t) = self.tracks.get_mut(id) else { continue };
            let Some(i) = t.obs.iter().position(|o| o.0 == k) else { continue };
            let obs = t.obs.remove(i);
            let px = t.measured.remove(i);
            let next = SPLIT_TRACKS_FROM + self.split.len() as u64;
            let new = *self.split.entry(*id).or_insert(next);
            let t = self.tracks.entry(new).or_default();
            t.obs.push(obs);
            t.measured.push(px);
        }
    }
}

#[cfg(test)]
mod tests {
    use lineflow_photogrammetry::look_at;

    use super::*;
    use crate::{OrientationParams, Surveyed};

    const STOREY: f64 = 3.0;

    fn camera() -> Camera {
        Camera::pinhole(1000, 800, 0.01, 20.0)
    }

    /// A camera 10 m in front of the wall y = 0 at (x, z), looking square on.
    fn at(x: f64, z: f64) -> Pose {
        let center = Vec3::new(x, -10.0, z);
        Pose {
            center,
            rotation: look_at(&center, &Vec3::new(x, 0.0, z), &Vec3::z()),
        }
    }

    fn pixel(pose: &Pose, x: &Vec3) -> Option<[f64; 2]> {
        let px = pose.project(&camera(), x)?;
        (px[0] >= 0.0 && px[1] >= 0.0 && px[0] < 1000.0 && px[1] < 800.0).then_some(px)
    }

    /// Frames 0 and 1 of a first strip (supplied, in the control frame) with tie tracks on a 0.25 m grid of the
    /// wall's lower storey intersected; frame 2, of a second strip one storey up, measures `controls` of the four
    /// control points and every track: those whose point lies above `true_above` where they are, the others where
    /// the same point one storey up is (a repeated façade matched a storey off). Returns the block and frame 2's
    /// true pose.
    fn second_strip(controls: usize, true_above: f64) -> (Block, Pose) {
        let mut block = Block::new(OrientationParams::default(), camera());
        let survey = [(-0.5, 3.0), (2.5, 3.2), (0.0, 5.8), (2.0, 6.0)];
        block.set_surveyed(
            survey
                .iter()
                .enumerate()
                .map(|(i, &(x, z))| {
                    let s = Surveyed {
                        xyz: Vec3::new(x, 0.0, z),
                        sigma_m: [0.002; 3],
                        control: true,
                    };
                    (format!("C{i}"), s)
                })
                .collect(),
        );
        let frames = [(0u64, at(0.0, 1.5)), (1, at(2.0, 1.5))];
        let truth = at(1.0, 1.5 + STOREY);
        for (f, pose) in frames {
            block.add_supplied(f, pose, None);
        }
        for (i, &(x, z)) in survey.iter().enumerate() {
            let xyz = Vec3::new(x, 0.0, z);
            for (f, pose) in frames.iter().copied().chain([(2, truth)]) {
                let seen = f < 2 || i < controls;
                if let (true, Some(px)) = (seen, pixel(&pose, &xyz)) {
                    block.add_target(&format!("C{i}"), f, px);
                }
            }
        }
        let mut track = 0;
        for ix in 0..=16 {
            for iz in 0..=14 {
                let x = Vec3::new(-1.0 + 0.25 * f64::from(ix), 0.0, 0.25 * f64::from(iz));
                let seen = if x.z > true_above { x } else { x + Vec3::z() * STOREY };
                let obs = [
                    (0, pixel(&frames[0].1, &x)),
                    (1, pixel(&frames[1].1, &x)),
                    (2, pixel(&truth, &seen)),
                ];
                if obs.iter().all(|o| o.1.is_some()) {
                    block.add_ties(obs.iter().map(|&(f, px)| (track, f, px.expect("in view"))));
                    track += 1;
                }
            }
        }
        block.intersect_new();
        (block, truth)
    }

    fn observed_in(block: &Block, track: u64, frame: u64) -> bool {
        block.tracks[&track].obs.iter().any(|o| o.0 == frame)
    }

    #[test]
    fn a_frame_tied_a_storey_off_is_resected_from_its_control_points_and_its_wrong_ties_split_off() {
        let (mut block, truth) = second_strip(4, 2.6);
        let tracks: Vec<u64> = block.tracks.keys().copied().collect();
        let kept = |b: &Block| tracks.iter().filter(|&&t| observed_in(b, t, 2)).count();
        assert!(block.resect_frame(2));
        let pose = block.poses[&2];
        assert!((pose.center - truth.center).norm() < 1e-3, "at {:?}", pose.center);
        // The ties above 2.6 m were measured where their points are: they stay; the others moved to tracks of
        // their own, above the matcher's ids.
        let true_ties = tracks.iter().filter(|t| block.tracks[t].point.is_some_and(|x| x.z > 2.6)).count();
        assert!(true_ties > 0);
        assert_eq!(kept(&block), true_ties);
        let split: Vec<&u64> = block.tracks.keys().filter(|&&t| t >= SPLIT_TRACKS_FROM).collect();
        assert_eq!(split.len(), tracks.len() - true_ties);
        assert!(split
            .iter()
            .all(|t| block.tracks[t].obs.len() == 1 && block.tracks[t].point.is_none()));
        assert_eq!(block.vetoed.iter().copied().collect::<Vec<_>>(), [2]);
    }

    #[test]
    fn with_two_or_three_control_points_the_rotation_of_the_ties_is_held_and_with_one_the_frame_is_left_out() {
        for controls in [2, 3] {
            let (mut block, truth) = second_strip(controls, f64::INFINITY);
            assert!(block.resect_frame(2), "{controls} control points");
            let pose = block.poses[&2];
            assert!((pose.center - truth.center).norm() < 1e-3, "{controls}: at {:?}", pose.center);
        }
        let (mut block, _) = second_strip(1, f64::INFINITY);
        assert!(!block.resect_frame(2));
        assert!(!block.poses.contains_key(&2));
    }

    #[test]
    fn a_frame_whose_ties_agree_with_its_control_points_keeps_its_pose_and_its_ties() {
        let (mut block, truth) = second_strip(4, f64::NEG_INFINITY);
        let before = block.tracks.len();
        assert!(block.resect_frame(2));
        assert!((block.poses[&2].center - truth.center).norm() < 1e-6);
        assert_eq!(block.tracks.len(), before);
        assert!(block.split.is_empty());
        assert!(block.vetoed.is_empty());
    }

    #[test]
    fn a_track_whose_rays_pass_a_storey_apart_is_not_intersected() {
        let (mut block, truth) = second_strip(4, f64::INFINITY);
        block.poses.insert(2, truth);
        let x = Vec3::new(1.0, 0.0, 2.0);
        let a = pixel(&block.poses[&0], &x).expect("in view");
        let b = pixel(&truth, &(x + Vec3::z() * STOREY)).expect("in view");
        block.add_ties([(9_999, 0, a), (9_999, 2, b)]);
        block.add_ties([(9_998, 0, a), (9_998, 1, pixel(&block.poses[&1], &x).expect("in view"))]);
        block.intersect_new();
        assert!(block.tracks[&9_999].point.is_none());
        assert!(block.tracks[&9_998].point.is_some_and(|p| (p - x).norm() < 1e-6));
    }
}
