//! `lineflow-linefit`: the linefit stage. Fits a 3-D segment to each matched point group (`impl = "tls"`, robust
//! total least squares, or `impl = "thesis"`, the thesis's RANSAC with the principal piercing plane), merges the
//! fragments of one edge across masters, publishes the merged set after every master, and at end-of-stream writes
//! `lines3d.csv` and `lines3d.ply`. A master published again (final poses) replaces its earlier groups. With
//! `lines2d`, `poses` and `camera` wired (and `multiview` on), the final set is re-estimated from every image's 2-D
//! segments once all of them and the final poses are in (docs/lines3d.md).
use std::collections::BTreeMap;

use anyhow::Result;
use lineflow_formats::{write_lines3d_results, Line3Row};
use lineflow_linefit::{
    bridges, fit_group, join_lines, line_elements, merge, refine_multiview, snap, snap_layers, FitParams, Fragment, Merged, Method,
    MULTIVIEW_MIN_SEGMENT_PX,
};
use lineflow_linegeom::{reclass, FrameSegments, Photo, PhotoView, Sight, SlaveSegments};
use lineflow_messages::{kinds, parts, Line3, LineClass, Lines3DHeader, Point3, PointGroup, Segment2, Stamp, StampFlags};
use lineflow_photogrammetry::{Camera, Pose, Vec3};
use lineflow_runtime::{Flow, NodeContext};

fn main() -> std::process::ExitCode {
    lineflow_runtime::run_stage("linefit", "tls", &[("tls", run_tls), ("thesis", run_thesis)])
}

fn run_tls(ctx: NodeContext) -> Result<()> {
    run(ctx, Method::Tls)
}

fn run_thesis(ctx: NodeContext) -> Result<()> {
    run(ctx, Method::Thesis)
}

fn run(ctx: NodeContext, method: Method) -> Result<()> {
    let params: FitParams = ctx.stage_params()?;
    let input = ctx.input::<kinds::Points3D>("points3d")?;
    let lines_in = ctx.optional_input::<kinds::Lines2D>("lines2d")?;
    let poses_in = ctx.optional_input::<kinds::Poses>("poses")?;
    let camera_in = ctx.optional_input::<kinds::CameraModel>("camera")?;
    let joined_in = ctx.optional_input::<kinds::Lines3D>("joined")?;
    // The images are for the half-plane test of the final lines only: without it they are taken and dropped.
    let images_in = ctx.optional_input::<kinds::Image>("images")?;
    let output = ctx.output::<kinds::Lines3D>("lines3d")?;
    ctx.connect()?;
    if params.sides.enabled && images_in.is_none() {
        tracing::warn!("sides.enabled, but no images are wired to linefit: the lines' sides are not tested");
    }
    let multiview = params.multiview && lines_in.is_some() && poses_in.is_some() && camera_in.is_some();
    let mut segments: BTreeMap<u64, Vec<Segment2>> = BTreeMap::new();
    let mut poses: BTreeMap<u64, Pose> = BTreeMap::new();
    let mut camera: Option<Camera> = None;
    // The other line stage's final set (flagged final): its earlier sets depend on when it remapped.
    let mut joined: Option<Vec<Line3>> = None;
    let mut photos: BTreeMap<u64, Photo> = BTreeMap::new();
    let mut gray = Vec::new();

    let mut fragments: BTreeMap<u64, Vec<Fragment>> = BTreeMap::new();
    let mut merged: Vec<Merged> = Vec::new();
    let mut last = Stamp::default();
    let mut published = std::collections::HashSet::new();
    ctx.run(|| {
        if let Some(i) = &camera_in {
            while let Some(m) = i.receive()? {
                camera = Some(m.user_header().camera());
            }
        }
        if let Some(i) = &lines_in {
            i.for_each_segments(|h, segs, _| {
                if multiview {
                    segments.insert(h.stamp.frame, segs.to_vec());
                }
                Ok(())
            })?;
        }
        if let Some(i) = images_in.as_ref().filter(|_| !params.sides.enabled) {
            while i.receive()?.is_some() {}
        }
        if let Some(i) = images_in.as_ref().filter(|_| params.sides.enabled) {
            lineflow_imaging::for_each_gray(i, &mut gray, |h, g| {
                match Photo::new(h.width as usize, h.height as usize, g.to_vec()) {
                    Some(photo) => {
                        photos.insert(h.stamp.frame, photo);
                    }
                    None => tracing::warn!("frame {}: image of {}x{} too small to test", h.stamp.frame, h.width, h.height),
                }
                Ok(())
            })?;
        }
        if let Some(i) = &poses_in {
            // Every Poses message holds every oriented frame; the last one is the final adjustment.
            while let Some(m) = i.receive()? {
                poses = m.payload().iter().map(|p| (p.frame, p.exterior())).collect();
            }
        }
        if let Some(i) = &joined_in {
            while let Some(m) = i.receive()? {
                if m.user_header().stamp.flags & StampFlags::FINAL != 0 {
                    joined = Some(m.payload().to_vec());
                }
            }
        }
        // Every frame received for the first time gets its own set, in order, so that downstream sees no frame
        // missing even when several arrive in one wake (a linematch with `master_every` > 1 passes frames on
        // without points); revisions of frames already out (the final re-estimation) share one set.
        let mut received: Vec<Stamp> = Vec::new();
        while let Some(m) = input.receive()? {
            let h = *m.user_header();
            let (groups, points) = parts::split::<PointGroup, Point3>(m.payload(), h.n_groups as usize, h.n_points as usize)
                .map_err(|e| anyhow::anyhow!("points3d of frame {}: {e}", h.stamp.frame))?;
            let master = h.stamp.frame;
            let fitted: Vec<Fragment> = groups
                .iter()
                .filter_map(|g| {
                    let pts: Vec<Vec3> = points
                        .get(g.start as usize..(g.start + g.len) as usize)?
                        .iter()
                        .map(|p| Vec3::from(p.xyz))
                        .collect();
                    fit_group(method, &pts, master, g.segment_id, g.n_views, &params)
                })
                .collect();
            tracing::debug!(master, groups = groups.len(), lines = fitted.len(), "fitted");
            fragments.insert(master, fitted);
            received.push(h.stamp);
        }
        if let Some(&newest) = received.last() {
            let all: Vec<Fragment> = fragments.values().flatten().cloned().collect();
            let pose_list: Vec<Pose> = poses.values().copied().collect();
            let sight = camera.as_ref().map(|camera| Sight { camera, poses: &pose_list });
            merged = merge(&all, &params.rule(), sight.as_ref());
            snap(&mut merged, &params);
            // Classed once per set: the frames of one wake share it.
            let lines = line_elements(&merged, &params, camera.as_ref(), &pose_list);
            for stamp in lineflow_runtime::frames_to_publish(&received, &mut published) {
                output.publish(Lines3DHeader { stamp }, &lines)?;
            }
            last = newest;
        }
        // The final set waits for every image's lines and the final poses too.
        let others_ended = [
            lines_in.as_ref().map(|i| i.is_ended()),
            poses_in.as_ref().map(|i| i.is_ended()),
            images_in.as_ref().map(|i| i.is_ended()),
        ]
        .iter()
        .all(|e| e.unwrap_or(true));
        let joined_ended = joined_in.as_ref().is_none_or(|i| i.is_ended());
        Ok(if input.is_ended() && (!multiview || others_ended) && joined_ended {
            Flow::Stop
        } else {
            Flow::Continue
        })
    })?;
    // Every image's segments with its final pose, for the re-estimate and the bridges.
    let frames: Vec<(Pose, FrameSegments)> = match (&camera, multiview) {
        (Some(cam), true) => segments
            .iter()
            .filter_map(|(f, s)| Some((*poses.get(f)?, FrameSegments::new(cam, s, MULTIVIEW_MIN_SEGMENT_PX))))
            .collect(),
        _ => Vec::new(),
    };
    let views: Vec<SlaveSegments> = frames
        .iter()
        .map(|(pose, segments)| SlaveSegments { pose: *pose, segments })
        .collect();
    match (&camera, multiview) {
        (Some(cam), true) => {
            let start = std::time::Instant::now();
            let (moved, rms_px) = refine_multiview(cam, &mut merged, &views, &params);
            snap(&mut merged, &params);
            tracing::info!(
                "{moved} of {} lines re-estimated from the 2-D segments of {} images (residual RMS {rms_px:.2} px) in {:.2} s",
                merged.len(),
                views.len(),
                start.elapsed().as_secs_f64()
            );
        }
        (None, true) => tracing::warn!("no camera model arrived: the lines are not re-estimated from every image"),
        _ => {}
    }
    let final_poses: Vec<Pose> = poses.values().copied().collect();
    match (&joined_in, &joined) {
        (Some(_), Some(joined)) => {
            let sight = camera.as_ref().map(|camera| Sight {
                camera,
                poses: &final_poses,
            });
            let n = join_lines(&mut merged, joined, &params, sight);
            snap(&mut merged, &params);
            tracing::info!(
                "joined: {n} stretches of the other line stage's {} lines that these leave uncovered",
                joined.len()
            );
        }
        (Some(i), None) => tracing::warn!(
            "topic '{}' ended without a final set (its stage failed or stopped early): nothing joined",
            i.topic()
        ),
        _ => {}
    }
    if let (Some(cam), true) = (&camera, multiview && params.bridge_max_span_m > 0.0) {
        let start = std::time::Instant::now();
        let found = bridges(cam, &merged, &views, &params);
        let n = found.len();
        merged.extend(found);
        snap(&mut merged, &params);
        tracing::info!(
            "bridges: {n} level lines between the ends of plumb lines, shown by the images, in {:.2} s",
            start.elapsed().as_secs_f64()
        );
    }
    if let (Some(cam), true) = (&camera, multiview && params.layer_k_sigma > 0.0) {
        let start = std::time::Instant::now();
        let stats = snap_layers(cam, &mut merged, &views, &params);
        snap(&mut merged, &params);
        tracing::info!(
            "depth layers: {} lines moved onto the plane their neighbours share, {} refused by their images, in {:.2} s",
            stats.moved,
            stats.refused,
            start.elapsed().as_secs_f64()
        );
    }
    // A revision above the last one, or subscribers would take the final set for a duplicate of it.
    last.flags |= StampFlags::FINAL;
    last.revision += 1;
    let mut lines = line_elements(&merged, &params, camera.as_ref(), &final_poses);
    match (&camera, &images_in) {
        (Some(cam), Some(_)) if params.classify && params.sides.enabled => {
            let start = std::time::Instant::now();
            let views: Vec<PhotoView> = photos
                .iter()
                .filter_map(|(f, photo)| {
                    Some(PhotoView {
                        pose: poses.get(f)?,
                        photo,
                    })
                })
                .collect();
            let counts = reclass(&mut lines, cam, &views, &params.sides);
            tracing::info!(
                "sides: {} of {} structure lines lie inside a surface (texture now), {} are steps; {} images, {:.2} s",
                counts.texture,
                counts.tested,
                counts.step,
                views.len(),
                start.elapsed().as_secs_f64()
            );
        }
        (None, Some(_)) if params.sides.enabled => tracing::warn!("no camera model arrived: the lines' sides are not tested"),
        _ => {}
    }
    output.publish(Lines3DHeader { stamp: last }, &lines)?;
    output.end_of_stream()?;
    let rows: Vec<Line3Row> = lines.iter().map(Line3Row::from).collect();
    let csv = write_lines3d_results(&ctx.out_dir(), &rows)?;
    let n_fragments: usize = fragments.values().map(Vec::len).sum();
    let texture = lines.iter().filter(|l| LineClass::from_code(l.class) == LineClass::Texture).count();
    tracing::info!(
        "{} 3-D lines ({texture} classed texture) from {n_fragments} fragments of {} masters -> {}",
        rows.len(),
        fragments.len(),
        csv.display()
    );
    ctx.finish();
    Ok(())
}
