//! `lineflow-linematch`: the linematch stage. Collects grey images, 2-D lines and poses; matches each master's
//! lines once the poses of the master and its slaves are settled (or final, at the end of the stream), and
//! publishes one `Points3D` message per master. When the final adjustment moves the poses, every matched point is
//! re-computed from its pixel and depth with the final pose and the masters are published again, so that the
//! lines fitted downstream agree with `poses.csv`.
use std::collections::BTreeMap;

use anyhow::Result;
use lineflow_linematch::{
    choose_slaves, fit_walls, match_master_with_lines, DistortionLut, FrameSegments, MasterMatch, MatchParams, NoWall, SegmentInput,
    SegmentMatch, SlaveSegments, View, WallPlane, WALL_MIN_POINTS,
};
use lineflow_messages::{kinds, Point3, PointGroup, Points3DHeader, Pose as PoseMsg, Segment2, Stamp, StampFlags};
use lineflow_photogrammetry::intersect::intersect_rays;
use lineflow_photogrammetry::{Camera, Pose, Vec3};
use lineflow_runtime::{Flow, NodeContext, Output};

/// One frame's 2-D lines.
struct FrameLines {
    segments: Vec<Segment2>,
    chain: Vec<[u16; 2]>,
}

/// The latest pose of a frame with its flags.
#[derive(Clone, Copy)]
struct PoseState {
    pose: Pose,
    flags: u32,
}

#[derive(Default)]
struct State {
    camera: Option<(Camera, DistortionLut)>,
    grays: BTreeMap<u64, Vec<u8>>,
    stamps: BTreeMap<u64, Stamp>,
    lines: BTreeMap<u64, FrameLines>,
    /// Frames' segments in ideal coordinates, built when a frame first serves as a slave.
    frame_segments: BTreeMap<u64, FrameSegments>,
    poses: BTreeMap<u64, PoseState>,
    /// Walls from the site model; `None` until it arrives (or it is known not to come).
    site: Option<Vec<WallPlane>>,
    /// Tie points (track → observations), for walls fitted when there is no site model.
    ties: BTreeMap<u64, Vec<(u64, [f64; 2])>>,
    fitted: Option<Vec<WallPlane>>,
    /// The fitted walls are in the survey's frame (fitted from georeferenced poses).
    fitted_georeferenced: bool,
    /// Why no wall could be fitted yet, and whether that was warned (once; again at the end if it stays so).
    no_walls: Option<(bool, String)>,
    /// The site topic said there is no site model.
    site_absent: bool,
    /// Matched masters, kept for re-estimation with the final poses.
    matched: BTreeMap<u64, Vec<SegmentMatch>>,
    /// Masters that cannot be matched (reported once).
    skipped: BTreeMap<u64, String>,
    /// Pose messages not yet taken, in arrival order.
    snapshots: std::collections::VecDeque<(Stamp, BTreeMap<u64, PoseState>)>,
    /// Frame of the snapshot in use.
    snapshot_frame: u64,
    /// Highest frame whose tie points have arrived.
    ties_through: Option<u64>,
    final_poses: bool,
    revision: u32,
}

fn settled(s: &PoseState) -> bool {
    s.flags & PoseMsg::ORIENTED != 0 && s.flags & (PoseMsg::SETTLED | PoseMsg::FINAL) != 0
}

impl State {
    /// Lets go of the images, 2-D lines and segments of frames no pending master can use (`window`); what was
    /// matched stays for the final re-estimate.
    fn forget_old_frames(&mut self, params: &MatchParams) {
        let first = lineflow_linematch::first_needed_frame(
            self.stamps.keys().chain(self.lines.keys()).copied(),
            |f| self.matched.contains_key(&f) || self.skipped.contains_key(&f),
            params.master_every,
            params.window,
        );
        self.grays.retain(|f, _| *f >= first);
        self.lines.retain(|f, _| *f >= first);
        self.frame_segments.retain(|f, _| *f >= first);
    }

    /// Walls to search: the site model's, else planes fitted to the intersected tie points.
    fn walls(&self) -> Option<Vec<WallPlane>> {
        self.site.clone().or_else(|| self.fitted.clone())
    }

    /// Why not one master was matched, for the warning at the end.
    fn why_no_master(&self) -> String {
        let oriented = self.poses.values().filter(|s| settled(s)).count();
        let georeferenced = self
            .poses
            .values()
            .filter(|s| settled(s) && s.flags & PoseMsg::GEOREFERENCED != 0)
            .count();
        if self.lines.is_empty() {
            "no 2-D lines arrived".into()
        } else if oriented == 0 {
            format!("none of the {} frames with 2-D lines was oriented", self.lines.len())
        } else if self.site.is_some() && georeferenced == 0 {
            format!("{oriented} frames were oriented but none georeferenced, and the site model needs the survey's frame (control points)")
        } else if let (None, Some((_, why))) = (self.walls(), &self.no_walls) {
            why.clone()
        } else if !self.skipped.is_empty() {
            "every master was skipped (above)".into()
        } else {
            format!("{oriented} frames were oriented, but no master had its slaves")
        }
    }

    /// Walls fitted to the tie points intersected from the settled (and, with `georeferenced`, georeferenced) poses
    /// ([`fit_walls`]).
    fn walls_from_ties(&self, georeferenced: bool) -> Result<Vec<WallPlane>, NoWall> {
        let usable = |s: &PoseState| settled(s) && (!georeferenced || s.flags & PoseMsg::GEOREFERENCED != 0);
        let Some((camera, _)) = self.camera.as_ref() else {
            return Err(NoWall { intersected: 0 });
        };
        let points: Vec<Vec3> = self
            .ties
            .values()
            .filter_map(|obs| {
                let rays: Vec<(Vec3, Vec3)> = obs
                    .iter()
                    .filter(|(f, _)| *f <= self.snapshot_frame)
                    .filter_map(|(f, px)| {
                        self.poses
                            .get(f)
                            .filter(|s| usable(s))
                            .map(|s| (s.pose.center, s.pose.ray_of_pixel(camera, *px)))
                    })
                    .collect();
                (rays.len() >= 2).then(|| intersect_rays(&rays)).flatten().map(|(x, _)| x)
            })
            .collect();
        let Some(viewpoint) = self.poses.values().find(|s| usable(s)).map(|s| s.pose.center) else {
            return Err(NoWall { intersected: 0 });
        };
        fit_walls(&points, &viewpoint)
    }
}

fn main() -> std::process::ExitCode {
    lineflow_runtime::run_stage("linematch", "sncc", &[("sncc", run)])
}

fn run(ctx: NodeContext) -> Result<()> {
    let params: MatchParams = ctx.stage_params()?;
    let images = ctx.input::<kinds::Image>("images")?;
    let lines_in = ctx.input::<kinds::Lines2D>("lines2d")?;
    let poses_in = ctx.input::<kinds::Poses>("poses")?;
    let camera_in = ctx.input::<kinds::CameraModel>("camera")?;
    let site_in = ctx.optional_input::<kinds::Site>("site")?;
    let ties_in = ctx.optional_input::<kinds::TiePoints>("tiepoints")?;
    let output = ctx.output::<kinds::Points3D>("points3d")?;
    ctx.connect()?;

    let mut st = State::default();
    let mut gray = Vec::new();
    ctx.run(|| {
        while let Some(m) = camera_in.receive()? {
            let cam = m.user_header().camera();
            st.camera = Some((cam, DistortionLut::new(&cam)));
        }
        if let Some(input) = &site_in {
            while let Some(m) = input.receive()? {
                let walls: Vec<WallPlane> = m
                    .payload()
                    .iter()
                    .filter_map(|w| WallPlane::from_corners(w.name(), &w.corners().iter().map(|&c| Vec3::from(c)).collect::<Vec<_>>()))
                    .collect();
                if walls.is_empty() {
                    tracing::info!("no site model: walls will be fitted to the tie points");
                    st.site = None;
                    st.site_absent = true;
                } else {
                    tracing::info!("site model: {} walls", walls.len());
                    st.site = Some(walls);
                }
            }
        }
        if let Some(input) = &ties_in {
            while let Some(m) = input.receive()? {
                st.ties_through = st.ties_through.max(Some(m.user_header().stamp.frame));
                for t in m.payload() {
                    st.ties.entry(t.track).or_default().push((t.frame, [t.col, t.row]));
                }
            }
        }
        // Twice the window of images at most: every slave of the earliest pending master is among them, and the
        // images a slower stage has not taken wait in the edge (back-pressure) instead of in this stage's memory.
        let room = match params.window {
            0 => usize::MAX,
            w => (2 * w as usize).saturating_sub(st.grays.len()),
        };
        lineflow_imaging::for_each_gray_up_to(&images, &mut gray, room, |h, g| {
            st.grays.insert(h.stamp.frame, g.to_vec());
            st.stamps.insert(h.stamp.frame, h.stamp);
            Ok(())
        })?;
        lines_in.for_each_segments(|h, segs, chain| {
            st.lines.insert(
                h.stamp.frame,
                FrameLines {
                    segments: segs.to_vec(),
                    chain: chain.to_vec(),
                },
            );
            Ok(())
        })?;
        while let Some(m) = poses_in.receive()? {
            let snapshot = m
                .payload()
                .iter()
                .map(|p| {
                    (
                        p.frame,
                        PoseState {
                            pose: p.exterior(),
                            flags: p.flags,
                        },
                    )
                })
                .collect();
            st.snapshots.push_back((m.user_header().stamp, snapshot));
        }
        let site_known = site_in.as_ref().is_none_or(|i| st.site.is_some() || st.site_absent || i.is_ended());
        if st.camera.is_none() || !site_known {
            return Ok(if images.is_ended() && lines_in.is_ended() && poses_in.is_ended() {
                Flow::Stop
            } else {
                Flow::Continue
            });
        }
        let ended = Ended {
            images: images.is_ended(),
            lines: lines_in.is_ended(),
            ties: ties_in.as_ref().is_none_or(|i| i.is_ended()),
        };
        // Pose snapshots are taken one by one, in order, and every master that becomes ready under one is matched
        // with exactly that snapshot, waiting for its images and lines if need be: the result does not depend on
        // how messages happened to interleave. At most one master per wake, so that inputs keep being drained.
        loop {
            let at_end = poses_in.is_ended() && st.snapshots.is_empty();
            match step(&mut st, &params, &ended, at_end) {
                Step::Match(master, slaves, line_frames) => {
                    match_and_publish(&mut st, &params, (master, slaves, line_frames), &output)?;
                    st.forget_old_frames(&params);
                    return Ok(Flow::Continue);
                }
                Step::Pass(frame) => {
                    st.matched.insert(frame, Vec::new());
                    st.revision += 1;
                    let stamp = st.stamps.get(&frame).copied().unwrap_or_default();
                    publish(&output, stamp, frame, st.revision, &[])?;
                }
                Step::Wait => return Ok(Flow::Continue),
                Step::NextSnapshot => match st.snapshots.pop_front() {
                    Some((stamp, snapshot)) => {
                        st.poses = snapshot;
                        st.snapshot_frame = stamp.frame;
                        if stamp.flags & StampFlags::FINAL != 0 {
                            st.final_poses = true;
                        }
                    }
                    None => return Ok(if poses_in.is_ended() { Flow::Stop } else { Flow::Continue }),
                },
                Step::Done => return Ok(Flow::Stop),
            }
        }
    })?;
    if st.final_poses {
        reestimate_and_publish(&mut st, &output)?;
    }
    let groups: usize = st.matched.values().map(Vec::len).sum();
    let points: usize = st.matched.values().flatten().map(|m| m.points.len()).sum();
    let masters = st.matched.keys().filter(|f| *f % params.master_every == 0).count();
    tracing::info!("{masters} masters matched: {groups} point groups, {points} points");
    for (frame, why) in &st.skipped {
        tracing::warn!("frame {frame} was not matched: {why}");
    }
    if masters == 0 {
        tracing::warn!("no 3-D lines: {}", st.why_no_master());
    }
    output.end_of_stream()?;
    ctx.finish();
    Ok(())
}

/// Which inputs have ended.
struct Ended {
    images: bool,
    lines: bool,
    ties: bool,
}

/// What the scheduler does next.
enum Step {
    /// Match this master against these slaves, with the 2-D lines of the last frames placing depths.
    Match(u64, Vec<u64>, Vec<u64>),
    /// A frame that is no master (`master_every`) is passed on without points.
    Pass(u64),
    /// A ready master waits for its images or lines (or the tie points for a wall fit).
    Wait,
    /// Nothing more is ready under the current snapshot.
    NextSnapshot,
    /// The last snapshot has been used up.
    Done,
}

/// The next master ready under the current pose snapshot: oriented, settled and (with a site model) georeferenced,
/// with `max_slaves` such frames overlapping it — or, after the last snapshot (`at_end`), with any.
fn step(st: &mut State, params: &MatchParams, ended: &Ended, at_end: bool) -> Step {
    let Some((camera, _)) = st.camera.as_ref() else { return Step::Wait };
    let georeferenced_seen = st.poses.values().any(|s| s.flags & PoseMsg::GEOREFERENCED != 0);
    // Without a site model the walls are fitted in whatever frame the poses are in. When the orientation
    // georeferences the block, that frame changes (scale, rotation, shift): walls fitted before, and the depths
    // searched against them in unscaled units, are void.
    if st.site.is_none() && georeferenced_seen && st.fitted.is_some() && !st.fitted_georeferenced {
        tracing::info!(
            "the poses are georeferenced now: walls fitted again in the survey's frame, the {} frames matched before matched again",
            st.matched.len()
        );
        st.fitted = None;
        st.matched.clear();
    }
    let georeferenced_needed = st.site.is_some() || georeferenced_seen;
    let candidates: Vec<(u64, Pose)> = st
        .poses
        .iter()
        .filter(|(_, s)| settled(s) && (!georeferenced_needed || s.flags & PoseMsg::GEOREFERENCED != 0))
        .map(|(&f, s)| (f, s.pose))
        .collect();
    if candidates.is_empty() {
        return if at_end { Step::Done } else { Step::NextSnapshot };
    }
    if st.site.is_none() && st.fitted.is_none() {
        // Walls from the tie points of the frames this snapshot covers, once they have all arrived.
        if !ended.ties && st.ties_through.is_none_or(|f| f < st.snapshot_frame) {
            return Step::Wait;
        }
        match st.walls_from_ties(georeferenced_needed) {
            Ok(walls) => {
                tracing::info!("{} walls fitted to the tie points", walls.len());
                st.fitted = Some(walls);
                st.fitted_georeferenced = georeferenced_needed;
                st.no_walls = None;
            }
            Err(e) => {
                // Too few tie points is the normal start of a stream; enough of them on no plane is news.
                let warned = st.no_walls.as_ref().is_some_and(|(w, _)| *w);
                let warn = !warned && e.intersected >= WALL_MIN_POINTS;
                if warn {
                    tracing::warn!("{e}; trying again as frames arrive");
                } else {
                    tracing::debug!("{e}");
                }
                st.no_walls = Some((warned || warn, e.to_string()));
            }
        }
    }
    let Some(walls) = st.walls() else {
        return if at_end { Step::Done } else { Step::NextSnapshot };
    };
    let camera = *camera;
    // A master before this frame is still to be matched.
    let mut earlier_pending = false;
    for &(frame, pose) in &candidates {
        if st.matched.contains_key(&frame) || st.skipped.contains_key(&frame) {
            continue;
        }
        if frame % params.master_every != 0 {
            // A slave only: its empty message, in frame order, keeps the sequence whole downstream (no "missed"
            // frame).
            if !earlier_pending && (st.stamps.contains_key(&frame) || ended.images) {
                return Step::Pass(frame);
            }
            continue;
        }
        let near: Vec<(u64, Pose)> = candidates
            .iter()
            .filter(|(f, _)| params.window == 0 || f.abs_diff(frame) < params.window)
            .copied()
            .collect();
        let slaves = choose_slaves(&camera, (frame, &pose), &near, &walls, params.max_slaves, params.min_overlap);
        // Frames settle in order, so the first six to overlap a master are all behind it: waiting until half as
        // many frames past it are settled lets the slaves lie on both sides, as the thesis's triplets did. Seen
        // from one side only, an inner edge of a reveal is hidden behind the outer one in every slave, and they all
        // agree on the wrong edge.
        let ahead = candidates.iter().any(|(f, _)| *f >= frame + (params.max_slaves / 2) as u64);
        let ready = (slaves.len() >= params.max_slaves && ahead) || (at_end && !slaves.is_empty());
        if !ready {
            if at_end {
                st.skipped.insert(frame, "no neighbour overlaps it".into());
            } else {
                earlier_pending = true;
            }
            continue;
        }
        let missing_image = std::iter::once(frame)
            .chain(slaves.iter().copied())
            .find(|f| !st.grays.contains_key(f));
        let master_lines = st.lines.contains_key(&frame);
        let line_frames = if params.line_depth && params.line_only_min_slaves > 0 {
            let mut more = choose_slaves(&camera, (frame, &pose), &near, &walls, params.line_views, params.min_overlap);
            more.retain(|f| !slaves.contains(f));
            slaves.iter().copied().chain(more).collect()
        } else if params.line_depth {
            slaves.clone()
        } else {
            Vec::new()
        };
        // The other frames' lines refine the depths: waiting for them keeps the result independent of message
        // timing.
        let slave_lines_pending = !ended.lines && line_frames.iter().any(|f| !st.lines.contains_key(f));
        match (missing_image, master_lines, slave_lines_pending) {
            (None, true, false) => return Step::Match(frame, slaves, line_frames),
            (Some(f), _, _) if ended.images => {
                st.skipped.insert(frame, format!("the image of frame {f} never arrived"));
            }
            (_, false, _) if ended.lines => {
                st.skipped.insert(frame, "its 2-D lines never arrived".into());
            }
            _ => return Step::Wait,
        }
    }
    if at_end {
        Step::Done
    } else {
        Step::NextSnapshot
    }
}

fn match_and_publish(
    st: &mut State,
    params: &MatchParams,
    (master, slaves, line_frames): (u64, Vec<u64>, Vec<u64>),
    output: &Output<kinds::Points3D>,
) -> Result<()> {
    let walls = st.walls().unwrap_or_default();
    let Some((camera, lut)) = &st.camera else { return Ok(()) };
    if params.line_depth {
        for f in &line_frames {
            if let (false, Some(lines)) = (st.frame_segments.contains_key(f), st.lines.get(f)) {
                let segments = FrameSegments::new(camera, &lines.segments, params.line_min_length_px);
                st.frame_segments.insert(*f, segments);
            }
        }
    }
    let view = |f: u64| View {
        frame: f,
        pose: st.poses[&f].pose,
        camera: *camera,
        lut,
        gray: &st.grays[&f],
        segments: st.frame_segments.get(&f),
    };
    let lines = &st.lines[&master];
    let segments: Vec<SegmentInput> = lines
        .segments
        .iter()
        .filter_map(|s| {
            let chain = lines.chain.get(s.chain_start as usize..(s.chain_start + s.chain_len) as usize)?;
            Some(SegmentInput {
                id: s.id,
                start_px: s.start_px,
                end_px: s.end_px,
                chain,
            })
        })
        .collect();
    let started = std::time::Instant::now();
    let slave_views: Vec<View> = slaves.iter().map(|&f| view(f)).collect();
    let line_segments: Vec<SlaveSegments> = line_frames
        .iter()
        .filter_map(|f| {
            let segments = st.frame_segments.get(f)?;
            Some(SlaveSegments {
                pose: st.poses[f].pose,
                segments,
            })
        })
        .collect();
    let MasterMatch { matches, unmatched } =
        match_master_with_lines(&view(master), &slave_views, &line_segments, &walls, &segments, params);
    let points: usize = matches.iter().map(|m| m.points.len()).sum();
    let line_depths: usize = matches.iter().map(|m| m.n_line_depths).sum();
    tracing::info!(
        "frame {master}: {} of {} segments matched, {points} points ({line_depths} placed by the 2-D lines of other frames), slaves {slaves:?}, {:.2} s; {unmatched}",
        matches.len(),
        segments.len(),
        started.elapsed().as_secs_f64()
    );
    if let Some(why) = unmatched.warning(matches.len()) {
        tracing::warn!("frame {master}: {why}");
    }
    st.revision += 1;
    publish(
        output,
        st.stamps.get(&master).copied().unwrap_or_default(),
        master,
        st.revision,
        &matches,
    )?;
    st.matched.insert(master, matches);
    Ok(())
}

/// Every matched point again, from its pixel and depth through the final pose.
fn reestimate_and_publish(st: &mut State, output: &Output<kinds::Points3D>) -> Result<()> {
    let walls = st.walls().unwrap_or_default();
    let Some((camera, _)) = &st.camera else { return Ok(()) };
    for (&master, matches) in st.matched.iter_mut() {
        let Some(s) = st.poses.get(&master) else { continue };
        if s.flags & PoseMsg::FINAL == 0 {
            continue;
        }
        for m in matches.iter_mut() {
            let Some(wall) = walls.get(m.wall) else { continue };
            for p in &mut m.points {
                let ray = s.pose.ray_of_ideal(camera, p.ideal);
                if let Some(t) = wall.ray_parameter(&s.pose.center, &ray, p.depth_m) {
                    p.xyz = s.pose.center + t * ray;
                }
            }
        }
        st.revision += 1;
        let mut stamp = st.stamps.get(&master).copied().unwrap_or_default();
        stamp.flags |= StampFlags::FINAL;
        publish(output, stamp, master, st.revision, matches)?;
    }
    Ok(())
}

fn publish(output: &Output<kinds::Points3D>, mut stamp: Stamp, master: u64, revision: u32, matches: &[SegmentMatch]) -> Result<()> {
    stamp.frame = master;
    stamp.revision = revision;
    let mut groups = Vec::with_capacity(matches.len());
    let mut points = Vec::new();
    for m in matches {
        groups.push(PointGroup {
            segment_id: m.segment_id,
            start: points.len() as u32,
            len: m.points.len() as u32,
            n_views: m.n_views,
        });
        points.extend(m.points.iter().map(|p| Point3 {
            xyz: p.xyz.into(),
            sncc: p.sncc,
        }));
    }
    let header = Points3DHeader {
        stamp,
        n_groups: groups.len() as u32,
        n_points: points.len() as u32,
    };
    output.publish_parts(header, &groups, &points)
}
