//! The orientation stage between frames, as a state machine the process shell feeds: what it keeps (the block, the
//! survey until it joins, the frames waiting for it, the image names), when it publishes (after every frame, and a
//! final message after the end-of-stream adjustment) and the revisions it stamps. The shell only moves messages
//! between the ports and these methods, so the behaviour is tested here without processes.
use std::collections::BTreeMap;
use std::path::PathBuf;

use lineflow_formats::PoseRow;
use lineflow_messages::{ControlPoint, Observation, Pose as PoseElement, PosesHeader, Stamp, StampFlags, TiePoint};
use lineflow_photogrammetry::{Camera, Vec3};

use crate::{Block, Method, OrientationParams, Surveyed};

/// One `Poses` message: every oriented frame's pose as the block holds it after a change.
#[derive(Debug, Clone)]
pub struct PosesMessage {
    /// The header: the stamp of the frame that caused it (its revision the stage's count of changes), σ0, RMS.
    pub header: PosesHeader,
    /// One element per oriented frame.
    pub poses: Vec<PoseElement>,
}

/// Where the poses come from.
#[derive(Debug)]
enum Source {
    /// Oriented from the tie points (`bundle` or `essential`).
    TiePoints(Method),
    /// Given by the user (`file`): image name to its row, and the file's path for messages.
    Supplied { rows: BTreeMap<String, PoseRow>, path: PathBuf },
}

/// Why the stage cannot go on.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum OrientationError {
    /// The stream that drives the stage ended before any camera model arrived.
    #[error("the {0} ended but no camera model arrived")]
    NoCamera(&'static str),
}

/// The orientation stage's state.
pub struct OrientationStage {
    source: Source,
    params: OrientationParams,
    block: Option<Block>,
    pixel_mm: f64,
    /// The latched survey topics: `None` while awaited (tie-point orientation only waits for them when wired).
    survey: Option<BTreeMap<String, Surveyed>>,
    targets: Option<Vec<(String, u64, [f64; 2])>>,
    survey_joined: bool,
    waiting_ties: Vec<(Stamp, Vec<TiePoint>)>,
    waiting_images: Vec<(Stamp, String)>,
    names: BTreeMap<u64, String>,
    revision: u32,
    last_stamp: Stamp,
    frames: usize,
}

/// The survey, converted from its messages.
fn surveyed(points: &[ControlPoint]) -> BTreeMap<String, Surveyed> {
    points
        .iter()
        .map(|c| {
            // A missing standard deviation means "as surveyed, unknown": 5 mm, the synthetic survey's σ.
            let sigma_m = c.sigma_m.map(|s| if s.is_finite() && s > 0.0 { s } else { 0.005 });
            (
                c.id().to_owned(),
                Surveyed {
                    xyz: Vec3::from(c.xyz),
                    sigma_m,
                    control: c.role == ControlPoint::CONTROL,
                },
            )
        })
        .collect()
}

impl OrientationStage {
    /// Orientation from tie points. `control_wired` / `observations_wired`: whether those latched inputs are wired,
    /// so that the first frame waits for them.
    pub fn from_tie_points(params: OrientationParams, method: Method, control_wired: bool, observations_wired: bool) -> Self {
        let mut s = Self::new(Source::TiePoints(method), params);
        s.survey = (!control_wired).then(BTreeMap::new);
        s.targets = (!observations_wired).then(Vec::new);
        s
    }

    /// Poses supplied by the user (`impl = "file"`): `rows` from the `poses.csv` at `path`.
    pub fn from_file(rows: Vec<PoseRow>, path: PathBuf) -> Self {
        let rows = rows.into_iter().map(|r| (r.image.clone(), r)).collect();
        Self::new(Source::Supplied { rows, path }, OrientationParams::default())
    }

    fn new(source: Source, params: OrientationParams) -> Self {
        Self {
            source,
            params,
            block: None,
            pixel_mm: 1.0,
            survey: None,
            targets: None,
            survey_joined: false,
            waiting_ties: Vec::new(),
            waiting_images: Vec::new(),
            names: BTreeMap::new(),
            revision: 0,
            last_stamp: Stamp::default(),
            frames: 0,
        }
    }

    /// The camera model (latched): the block starts with the first one.
    pub fn on_camera(&mut self, camera: Camera) {
        self.pixel_mm = camera.pixel_size_mm;
        if self.block.is_none() {
            if !self.params.self_calibrate.is_empty() {
                // The camera topic is latched: the stages downstream keep the camera they were given.
                tracing::warn!(
                    "self-calibration: the poses published follow the adjusted camera, while the other stages keep the \
                     one on the camera topic; run it in a graph that stops at the orientation (launch/calibrate.toml, \
                     as `lineflow process` does) and use camera_calibrated.toml for the rest"
                );
            }
            let block = Block::new(self.params.clone(), camera);
            self.block = Some(match self.source {
                Source::TiePoints(method) => block.with_method(method),
                Source::Supplied { .. } => block,
            });
        }
    }

    /// The control and check points (latched).
    pub fn on_control_points(&mut self, points: &[ControlPoint]) {
        let s = surveyed(points);
        match (&self.source, self.block.as_mut()) {
            // Supplied poses take the survey whenever it comes: it only serves the check points at the end.
            (Source::Supplied { .. }, Some(b)) => b.set_surveyed(s),
            _ => self.survey = Some(s),
        }
    }

    /// The image measurements of those points (latched).
    pub fn on_observations(&mut self, observations: &[Observation]) {
        let targets = observations.iter().map(|o| (o.point_id().to_owned(), o.frame, [o.col, o.row]));
        match (&self.source, self.block.as_mut()) {
            (Source::Supplied { .. }, Some(b)) => targets.for_each(|(id, f, px)| b.add_target(&id, f, px)),
            _ => self.targets = Some(targets.collect()),
        }
    }

    /// An image: its name for `poses.csv`; with supplied poses, the frame to publish a pose for.
    pub fn on_image(&mut self, stamp: Stamp, name: &str) {
        match self.source {
            Source::TiePoints(_) => {
                self.names.insert(stamp.frame, name.to_owned());
            }
            Source::Supplied { .. } => self.waiting_images.push((stamp, name.to_owned())),
        }
    }

    /// A frame's tie points (ignored with supplied poses).
    pub fn on_tie_points(&mut self, stamp: Stamp, ties: &[TiePoint]) {
        if let Source::TiePoints(_) = self.source {
            self.waiting_ties.push((stamp, ties.to_vec()));
        }
    }

    /// Whether frames are still waiting to be handled.
    pub fn has_waiting(&self) -> bool {
        !self.waiting_ties.is_empty() || !self.waiting_images.is_empty()
    }

    /// Handles every frame that can be handled now and returns a message for each. `ended`: the stream that
    /// drives the stage (tie points, or the images with supplied poses) has ended, so a survey that has not come
    /// will not.
    ///
    /// # Errors
    /// The driving stream ended before any camera model arrived.
    pub fn step(&mut self, ended: bool) -> Result<Vec<PosesMessage>, OrientationError> {
        let mut out = Vec::new();
        match &self.source {
            Source::TiePoints(_) => self.step_tie_points(ended, &mut out),
            Source::Supplied { .. } => self.step_supplied(&mut out),
        }
        if ended && self.block.is_none() {
            let stream = match self.source {
                Source::TiePoints(_) => "tie points",
                Source::Supplied { .. } => "images",
            };
            return Err(OrientationError::NoCamera(stream));
        }
        Ok(out)
    }

    fn step_tie_points(&mut self, ended: bool, out: &mut Vec<PosesMessage>) {
        // The survey joins the block once, before the first frame; if it never comes, the frames go on without.
        let survey_ready = self.survey.is_some() && self.targets.is_some();
        if let (Some(b), false, true) = (self.block.as_mut(), self.survey_joined, survey_ready || ended) {
            if !survey_ready {
                tracing::warn!("the control points or their observations never arrived: orienting without them");
            }
            let s = self.survey.take().unwrap_or_default();
            let controls = s.values().filter(|p| p.control).count();
            if controls < 3 {
                tracing::warn!("{controls} control points: the block cannot be georeferenced (three are needed)");
            }
            b.set_surveyed(s);
            for (id, frame, px) in self.targets.take().unwrap_or_default() {
                b.add_target(&id, frame, px);
            }
            self.survey_joined = true;
        }
        let (Some(b), true) = (self.block.as_mut(), self.survey_joined) else {
            return;
        };
        self.waiting_ties.sort_by_key(|(s, _)| s.frame);
        for (stamp, ties) in self.waiting_ties.drain(..) {
            b.add_ties(ties.iter().map(|t| (t.track, t.frame, [t.col, t.row])));
            self.frames += 1;
            let oriented = b.orient(stamp.frame);
            if oriented {
                self.revision += 1;
            }
            tracing::info!(
                "frame {}: {} ({} of {} oriented{}, σ0 {:.2})",
                stamp.frame,
                if oriented { "oriented" } else { "not oriented yet" },
                b.poses.len(),
                self.frames,
                if b.georeferenced { ", georeferenced" } else { "" },
                b.report.sigma0
            );
            out.push(message(b, stamp, self.revision, self.pixel_mm));
            self.last_stamp = stamp;
        }
    }

    fn step_supplied(&mut self, out: &mut Vec<PosesMessage>) {
        let (Some(b), Source::Supplied { rows, path }) = (self.block.as_mut(), &self.source) else {
            return;
        };
        // A survey that came before the camera model joins as soon as the block exists.
        if let Some(s) = self.survey.take() {
            b.set_surveyed(s);
        }
        for (id, frame, px) in self.targets.take().unwrap_or_default() {
            b.add_target(&id, frame, px);
        }
        for (stamp, name) in self.waiting_images.drain(..) {
            self.names.insert(stamp.frame, name.clone());
            match rows.get(&name) {
                Some(row) => {
                    let sigmas = match (row.sigma_center_m, row.sigma_angles_deg) {
                        (None, None) => None,
                        (c, a) => Some((c.unwrap_or([f64::NAN; 3]), a.map_or([f64::NAN; 3], |a| a.map(f64::to_radians)))),
                    };
                    b.add_supplied(stamp.frame, row.pose, sigmas);
                    self.revision += 1;
                    out.push(message(b, stamp, self.revision, self.pixel_mm));
                }
                None => tracing::warn!("frame {} ({name}): no pose in {}; not oriented", stamp.frame, path.display()),
            }
            self.last_stamp = stamp;
        }
    }

    /// At end-of-stream: the final adjustment (or transformation), and the final message, flagged final, with
    /// the block to write the results from; `None` when no camera model ever arrived.
    pub fn finish(&mut self) -> Option<(PosesMessage, &Block, &BTreeMap<u64, String>)> {
        let b = self.block.as_mut()?;
        match &self.source {
            Source::TiePoints(method) => {
                b.finish();
                let missing: Vec<u64> = b.frames().filter(|f| !b.poses.contains_key(f)).collect();
                if !missing.is_empty() {
                    tracing::warn!("{} frames could not be oriented: {missing:?}", missing.len());
                }
                tracing::info!(
                    "final {}: {} frames, σ0 {:.2}, tie-point RMS {:.2} px, {} observations removed",
                    match method {
                        Method::Bundle => "adjustment",
                        Method::Essential => "transformation",
                    },
                    b.poses.len(),
                    b.report.sigma0,
                    b.report.rms_mm / self.pixel_mm,
                    b.report.removed.len()
                );
                if let Some(interior) = &b.report.interior {
                    for line in crate::calibration_report::interior_header(interior).lines().skip(1) {
                        tracing::info!("self-calibration: {}", line.trim_start_matches('#').trim());
                    }
                    if let Some(weak) = crate::calibration_report::weak_calibration(interior) {
                        tracing::warn!("{weak}");
                    }
                }
            }
            Source::Supplied { path, .. } => {
                if b.poses.is_empty() {
                    tracing::warn!("none of the {} images has a pose in {}", self.names.len(), path.display());
                }
                b.finished = true;
            }
        }
        let last = message(b, self.last_stamp, self.revision + 1, self.pixel_mm);
        Some((last, b, &self.names))
    }
}

/// Every oriented frame's pose as the block holds it now.
pub fn pose_elements(block: &Block) -> Vec<PoseElement> {
    block
        .poses
        .iter()
        .map(|(&frame, pose)| {
            let state = block.states.get(&frame).copied().unwrap_or_default();
            let mut flags = PoseElement::ORIENTED;
            if state.settled {
                flags |= PoseElement::SETTLED;
            }
            if block.finished {
                flags |= PoseElement::FINAL;
            }
            if block.georeferenced {
                flags |= PoseElement::GEOREFERENCED;
            }
            let mut p = PoseElement::from_exterior(frame, state.revision, flags, pose);
            if let Some((c, a)) = state.sigmas {
                p.sigma_center_m = c;
                p.sigma_angles_rad = a;
            }
            p
        })
        .collect()
}

fn message(block: &Block, mut stamp: Stamp, revision: u32, pixel_mm: f64) -> PosesMessage {
    stamp.revision = revision;
    if block.finished {
        stamp.flags |= StampFlags::FINAL;
    }
    PosesMessage {
        header: PosesHeader {
            stamp,
            sigma0: block.report.sigma0,
            rms_px: block.report.rms_mm / pixel_mm,
        },
        poses: pose_elements(block),
    }
}

#[cfg(test)]
mod tests {
    use lineflow_messages::fixed_str;
    use lineflow_photogrammetry::{rotation_from_opk, Pose};

    use super::*;

    fn camera() -> Camera {
        Camera::pinhole(600, 400, 0.01, 8.0)
    }

    fn stamp(frame: u64) -> Stamp {
        Stamp { frame, ..Stamp::default() }
    }

    fn row(image: &str, x: f64) -> PoseRow {
        PoseRow {
            image: image.into(),
            pose: Pose {
                center: Vec3::new(x, -20.0, 1.5),
                rotation: rotation_from_opk(90f64.to_radians(), 0.0, 0.0),
            },
            sigma_center_m: None,
            sigma_angles_deg: None,
        }
    }

    fn file_stage() -> OrientationStage {
        OrientationStage::from_file(vec![row("a.png", 0.0), row("b.png", 2.0)], "poses.csv".into())
    }

    fn control(id: &str, role: u32) -> ControlPoint {
        ControlPoint {
            id: fixed_str(id),
            xyz: [1.0, 0.0, 2.0],
            sigma_m: [f64::NAN; 3],
            role,
            reserved: 0,
        }
    }

    #[test]
    fn supplied_poses_are_published_as_their_images_arrive_and_once_more_as_final() {
        let mut s = file_stage();
        s.on_camera(camera());
        s.on_image(stamp(0), "a.png");
        let first = s.step(false).unwrap();
        assert_eq!(first.len(), 1);
        assert_eq!(first[0].header.stamp.revision, 1);
        assert_eq!(first[0].poses.len(), 1);
        let flags = first[0].poses[0].flags;
        for f in [PoseElement::ORIENTED, PoseElement::SETTLED, PoseElement::GEOREFERENCED] {
            assert_ne!(flags & f, 0, "flags {flags:b} hold {f:b}");
        }
        assert_eq!(flags & PoseElement::FINAL, 0);
        // An image the file has no pose for publishes nothing and stays unoriented.
        s.on_image(stamp(1), "unknown.png");
        s.on_image(stamp(2), "b.png");
        let next = s.step(true).unwrap();
        assert_eq!(next.len(), 1);
        assert_eq!((next[0].header.stamp.frame, next[0].header.stamp.revision), (2, 2));
        assert_eq!(next[0].poses.iter().map(|p| p.frame).collect::<Vec<_>>(), [0, 2]);
        assert!(!s.has_waiting());
        let (last, block, names) = s.finish().unwrap();
        assert_eq!((last.header.stamp.frame, last.header.stamp.revision), (2, 3));
        assert_ne!(last.header.stamp.flags & StampFlags::FINAL, 0);
        assert!(last.poses.iter().all(|p| p.flags & PoseElement::FINAL != 0));
        assert_eq!(block.poses.len(), 2);
        assert_eq!(
            names.values().map(String::as_str).collect::<Vec<_>>(),
            ["a.png", "unknown.png", "b.png"]
        );
    }

    #[test]
    fn images_wait_for_the_camera_and_a_stream_without_one_is_an_error() {
        let mut s = file_stage();
        s.on_image(stamp(0), "a.png");
        assert!(s.step(false).unwrap().is_empty());
        assert!(s.has_waiting());
        assert_eq!(s.step(true).unwrap_err(), OrientationError::NoCamera("images"));
        s.on_camera(camera());
        assert_eq!(s.step(true).unwrap().len(), 1);
        assert!(s.finish().is_some());

        let mut t = OrientationStage::from_tie_points(OrientationParams::default(), Method::Bundle, false, false);
        t.on_tie_points(stamp(0), &[]);
        assert_eq!(t.step(true).unwrap_err(), OrientationError::NoCamera("tie points"));
        assert!(t.finish().is_none());
    }

    #[test]
    fn a_survey_sent_before_the_camera_still_reaches_supplied_poses() {
        let mut s = file_stage();
        let check = control("K1", ControlPoint::CHECK);
        let observations: Vec<Observation> = [("a.png", 0.0), ("b.png", 2.0)]
            .iter()
            .enumerate()
            .map(|(frame, &(image, x))| {
                let px = row(image, x).pose.project(&camera(), &Vec3::from(check.xyz)).unwrap();
                Observation {
                    frame: frame as u64,
                    point_id: fixed_str("K1"),
                    col: px[0],
                    row: px[1],
                }
            })
            .collect();
        s.on_control_points(&[check]);
        s.on_observations(&observations);
        s.on_camera(camera());
        s.on_image(stamp(0), "a.png");
        s.on_image(stamp(1), "b.png");
        s.step(true).unwrap();
        let (_, block, _) = s.finish().unwrap();
        // The check point is intersected from the supplied poses: only if its survey and observations joined.
        let checks = block.check_points();
        assert_eq!(checks.len(), 1, "{checks:?}");
        assert!(checks[0].1.norm() < 1e-6, "{checks:?}");
    }

    #[test]
    fn frames_wait_for_a_wired_survey_and_go_on_without_it_when_the_stream_ends() {
        let mut s = OrientationStage::from_tie_points(OrientationParams::default(), Method::Bundle, true, true);
        s.on_camera(camera());
        s.on_tie_points(stamp(1), &[]);
        s.on_tie_points(stamp(0), &[]);
        assert!(s.step(false).unwrap().is_empty(), "the survey is awaited");
        s.on_control_points(&[control("C1", ControlPoint::CONTROL)]);
        assert!(s.step(false).unwrap().is_empty(), "the observations too");
        // The stream ends without them: the frames are handled, in frame order, each published even though
        // nothing could be oriented (revision unchanged).
        let out = s.step(true).unwrap();
        assert_eq!(out.iter().map(|m| m.header.stamp.frame).collect::<Vec<_>>(), [0, 1]);
        assert!(out.iter().all(|m| m.header.stamp.revision == 0 && m.poses.is_empty()));
        let (last, _, _) = s.finish().unwrap();
        assert_eq!((last.header.stamp.frame, last.header.stamp.revision), (1, 1));
    }

    #[test]
    fn an_unwired_survey_is_not_awaited() {
        let mut s = OrientationStage::from_tie_points(OrientationParams::default(), Method::Essential, false, false);
        s.on_camera(camera());
        s.on_image(stamp(0), "a.png");
        s.on_tie_points(stamp(0), &[]);
        assert_eq!(s.step(false).unwrap().len(), 1);
        let (_, _, names) = s.finish().unwrap();
        assert_eq!(names[&0], "a.png");
    }
}
