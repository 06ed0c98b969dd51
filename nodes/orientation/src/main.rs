//! `lineflow-orientation`: the orientation stage, implementations `bundle` (the default), `essential` (seed 001's
//! chained essential matrices) and `file` (the user's poses). Orients each frame as its tie points arrive,
//! publishes every oriented frame's pose after each change (revisions per `architecture.md`), and at end-of-stream
//! runs the full adjustment (or, for `essential`, the final transformation into the control frame) and writes
//! `poses.csv` and `checkpoints.csv` into the run's output folder.
use std::collections::BTreeMap;

use anyhow::{bail, Context, Result};
use lineflow_formats::{write_checkpoints, write_poses, CheckRow, PoseRow};
use lineflow_messages::{kinds, ControlPoint, Pose, PosesHeader, Stamp, StampFlags, TiePoint};
use lineflow_orientation::{Block, Method, OrientationParams, Surveyed};
use lineflow_photogrammetry::Vec3;
use lineflow_runtime::{Flow, NodeContext, Output};

fn main() -> std::process::ExitCode {
    lineflow_runtime::run_node(body)
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

/// Every oriented frame's pose as the block holds it now.
fn pose_elements(block: &Block) -> Vec<Pose> {
    block
        .poses
        .iter()
        .map(|(&frame, pose)| {
            let state = block.states.get(&frame).copied().unwrap_or_default();
            let mut flags = Pose::ORIENTED;
            if state.settled {
                flags |= Pose::SETTLED;
            }
            if block.finished {
                flags |= Pose::FINAL;
            }
            if block.georeferenced {
                flags |= Pose::GEOREFERENCED;
            }
            let mut p = Pose::from_exterior(frame, state.revision, flags, pose);
            if let Some((c, a)) = state.sigmas {
                p.sigma_center_m = c;
                p.sigma_angles_rad = a;
            }
            p
        })
        .collect()
}

fn publish(output: &Output<kinds::Poses>, block: &Block, mut stamp: Stamp, revision: u32, pixel_mm: f64) -> Result<()> {
    stamp.revision = revision;
    if block.finished {
        stamp.flags |= StampFlags::FINAL;
    }
    let header = PosesHeader {
        stamp,
        sigma0: block.report.sigma0,
        rms_px: block.report.rms_mm / pixel_mm,
    };
    output.publish(header, &pose_elements(block))
}

/// Writes `poses.csv` and, when the block is in the control frame, `checkpoints.csv`.
fn write_results(ctx: &NodeContext, block: &Block, names: &BTreeMap<u64, String>) -> Result<()> {
    let dir = ctx.out_dir();
    let rows: Vec<PoseRow> = pose_elements(block)
        .iter()
        .map(|p| PoseRow {
            image: names.get(&p.frame).cloned().unwrap_or_else(|| format!("frame_{:05}", p.frame)),
            pose: p.exterior(),
            sigma_center_m: p.sigma_center_m[0].is_finite().then_some(p.sigma_center_m),
            sigma_angles_deg: p.sigma_angles_rad[0].is_finite().then(|| p.sigma_angles_rad.map(f64::to_degrees)),
        })
        .collect();
    let path = dir.join("poses.csv");
    write_poses(&path, &rows).with_context(|| format!("writing {}", path.display()))?;
    if !block.poses.is_empty() {
        let colmap_dir = dir.join("colmap");
        let name = |f: u64| names.get(&f).cloned().unwrap_or_else(|| format!("frame_{f:05}"));
        let worst = lineflow_orientation::colmap::write_text_model(&colmap_dir, block.camera(), &block.poses, &name, &block.points())
            .with_context(|| format!("writing the COLMAP model into {}", colmap_dir.display()))?;
        tracing::info!(
            "COLMAP text model in {} (distortion fitted within {worst:.3} px)",
            colmap_dir.display()
        );
    }
    if block.poses.is_empty() {
        tracing::warn!("no frame could be oriented (too few verified tie points): poses.csv has no rows");
        return Ok(());
    }
    if !block.georeferenced {
        tracing::warn!(
            "fewer than three control points were intersected: poses.csv is in the arbitrary frame of the first pair, \
             and no checkpoints.csv is written"
        );
        return Ok(());
    }
    let checks: Vec<CheckRow> = block
        .check_points()
        .into_iter()
        .map(|(id, d)| CheckRow { id, delta_m: d.into() })
        .collect();
    let path = dir.join("checkpoints.csv");
    write_checkpoints(&path, &checks).with_context(|| format!("writing {}", path.display()))?;
    let n = checks.len().max(1) as f64;
    let rmse: Vec<f64> = (0..3)
        .map(|k| (checks.iter().map(|c| c.delta_m[k].powi(2)).sum::<f64>() / n).sqrt() * 1e3)
        .collect();
    tracing::info!(
        "{} check points, RMSE X {:.1} Y {:.1} Z {:.1} mm",
        checks.len(),
        rmse[0],
        rmse[1],
        rmse[2]
    );
    Ok(())
}

fn body() -> Result<()> {
    let ctx = NodeContext::from_env()?;
    match ctx.implementation("bundle") {
        "bundle" => run_block(ctx, Method::Bundle),
        "essential" => run_block(ctx, Method::Essential),
        "file" => run_file(ctx),
        other => bail!(
            "node '{}': unknown orientation impl '{other}' (available: bundle, essential, file)",
            ctx.name()
        ),
    }
}

/// Parameters of `impl = "file"` (the `bundle` parameters a launch file may carry are ignored).
#[derive(Debug, serde::Deserialize)]
struct FileParams {
    /// The poses, in the `poses.csv` format of `conventions.md` (relative to the launch file).
    poses: std::path::PathBuf,
}

/// The survey's control and check points and their observations, from the latched topics; empty when not wired or
/// never sent.
fn survey_into(
    block: &mut Block,
    control_in: Option<&lineflow_runtime::Input<kinds::ControlPoints>>,
    observations_in: Option<&lineflow_runtime::Input<kinds::Observations>>,
) -> Result<()> {
    if let Some(input) = control_in {
        while let Some(m) = input.receive()? {
            block.set_surveyed(surveyed(m.payload()));
        }
    }
    if let Some(input) = observations_in {
        while let Some(m) = input.receive()? {
            for o in m.payload() {
                block.add_target(o.point_id(), o.frame, [o.col, o.row]);
            }
        }
    }
    Ok(())
}

/// `impl = "file"`: poses supplied by the user (`poses.csv`, e.g. from another photogrammetry package) in place of
/// the orientation: each image's pose is published as it arrives, oriented, settled and in the control frame (the
/// last message, after the images end, final); `poses.csv` and, with a survey, `checkpoints.csv` (the check points intersected from the given poses)
/// are written as the `bundle` implementation writes them.
fn run_file(ctx: NodeContext) -> Result<()> {
    let p: FileParams = ctx.params()?;
    let base = ctx.graph().source.parent().map(std::path::Path::to_path_buf).unwrap_or_default();
    let path = lineflow_runtime::launch::resolve_param_path(&base, &p.poses.display().to_string());
    let rows = lineflow_formats::read_poses(&path).map_err(|e| anyhow::anyhow!("node '{}': {e}", ctx.name()))?;
    let supplied: BTreeMap<String, PoseRow> = rows.into_iter().map(|r| (r.image.clone(), r)).collect();
    tracing::info!("{} poses from {}", supplied.len(), path.display());
    let images_in = ctx.input::<kinds::Image>("images")?;
    let camera_in = ctx.input::<kinds::CameraModel>("camera")?;
    let control_in = ctx.optional_input::<kinds::ControlPoints>("control_points")?;
    let observations_in = ctx.optional_input::<kinds::Observations>("observations")?;
    let ties_in = ctx.optional_input::<kinds::TiePoints>("tiepoints")?;
    let output = ctx.output::<kinds::Poses>("poses")?;
    ctx.connect()?;

    let mut block: Option<Block> = None;
    let mut pixel_mm = 1.0;
    let mut waiting: Vec<(Stamp, String)> = Vec::new();
    let mut names: BTreeMap<u64, String> = BTreeMap::new();
    let (mut revision, mut last_stamp) = (0u32, Stamp::default());
    ctx.run(|| {
        while let Some(m) = camera_in.receive()? {
            let camera = m.user_header().camera();
            pixel_mm = camera.pixel_size_mm;
            block.get_or_insert_with(|| Block::new(OrientationParams::default(), camera));
        }
        while let Some(m) = images_in.receive()? {
            waiting.push((m.user_header().stamp, m.user_header().name().to_owned()));
        }
        if let Some(t) = &ties_in {
            while t.receive()?.is_some() {}
        }
        if let Some(b) = block.as_mut() {
            survey_into(b, control_in.as_ref(), observations_in.as_ref())?;
            for (stamp, name) in waiting.drain(..) {
                names.insert(stamp.frame, name.clone());
                match supplied.get(&name) {
                    Some(row) => {
                        let sigmas = match (row.sigma_center_m, row.sigma_angles_deg) {
                            (None, None) => None,
                            (c, a) => Some((c.unwrap_or([f64::NAN; 3]), a.map_or([f64::NAN; 3], |a| a.map(f64::to_radians)))),
                        };
                        b.add_supplied(stamp.frame, row.pose, sigmas);
                        revision += 1;
                        publish(&output, b, stamp, revision, pixel_mm)?;
                    }
                    None => tracing::warn!("frame {} ({name}): no pose in {}; not oriented", stamp.frame, path.display()),
                }
                last_stamp = stamp;
            }
        } else if images_in.is_ended() {
            bail!("node '{}': the images ended but no camera model arrived", ctx.name());
        }
        Ok(if images_in.is_ended() && waiting.is_empty() {
            Flow::Stop
        } else {
            Flow::Continue
        })
    })?;
    if let Some(b) = block.as_mut() {
        survey_into(b, control_in.as_ref(), observations_in.as_ref())?;
        if b.poses.is_empty() {
            tracing::warn!("none of the {} images has a pose in {}", names.len(), path.display());
        }
        b.finished = true;
        publish(&output, b, last_stamp, revision + 1, pixel_mm)?;
        write_results(&ctx, b, &names)?;
    }
    output.end_of_stream()?;
    ctx.finish();
    Ok(())
}

fn run_block(ctx: NodeContext, method: Method) -> Result<()> {
    let params: OrientationParams = ctx.params()?;
    if let Err(e) = params.validate() {
        bail!("node '{}': {e}", ctx.name());
    }
    let ties_in = ctx.input::<kinds::TiePoints>("tiepoints")?;
    let camera_in = ctx.input::<kinds::CameraModel>("camera")?;
    let control_in = ctx.optional_input::<kinds::ControlPoints>("control_points")?;
    let observations_in = ctx.optional_input::<kinds::Observations>("observations")?;
    let images_in = ctx.optional_input::<kinds::Image>("images")?;
    let output = ctx.output::<kinds::Poses>("poses")?;
    ctx.connect()?;

    let mut block: Option<Block> = None;
    let mut pixel_mm = 1.0;
    // The latched survey topics, when wired, are awaited before the first frame is oriented (`None` = pending).
    let mut survey: Option<BTreeMap<String, Surveyed>> = control_in.is_none().then(BTreeMap::new);
    let mut targets: Option<Vec<(String, u64, [f64; 2])>> = observations_in.is_none().then(Vec::new);
    let mut survey_joined = false;
    let mut waiting: Vec<(Stamp, Vec<TiePoint>)> = Vec::new();
    let mut names: BTreeMap<u64, String> = BTreeMap::new();
    let (mut revision, mut last_stamp, mut frames) = (0u32, Stamp::default(), 0usize);
    ctx.run(|| {
        while let Some(m) = camera_in.receive()? {
            let camera = m.user_header().camera();
            pixel_mm = camera.pixel_size_mm;
            block.get_or_insert_with(|| Block::new(params.clone(), camera).with_method(method));
        }
        if let Some(input) = &control_in {
            while let Some(m) = input.receive()? {
                survey = Some(surveyed(m.payload()));
            }
        }
        if let Some(input) = &observations_in {
            while let Some(m) = input.receive()? {
                targets = Some(
                    m.payload()
                        .iter()
                        .map(|o| (o.point_id().to_owned(), o.frame, [o.col, o.row]))
                        .collect(),
                );
            }
        }
        if let Some(input) = &images_in {
            while let Some(m) = input.receive()? {
                names.insert(m.user_header().stamp.frame, m.user_header().name().to_owned());
            }
        }
        while let Some(m) = ties_in.receive()? {
            waiting.push((m.user_header().stamp, m.payload().to_vec()));
        }
        // The survey joins the block once, before the first frame; if it never comes, the frames go on without.
        let survey_ready = survey.is_some() && targets.is_some();
        if let (Some(b), false, true) = (block.as_mut(), survey_joined, survey_ready || ties_in.is_ended()) {
            if !survey_ready {
                tracing::warn!("the control points or their observations never arrived: orienting without them");
            }
            let s = survey.take().unwrap_or_default();
            let controls = s.values().filter(|p| p.control).count();
            if controls < 3 {
                tracing::warn!("{controls} control points: the block cannot be georeferenced (three are needed)");
            }
            b.set_surveyed(s);
            for (id, frame, px) in targets.take().unwrap_or_default() {
                b.add_target(&id, frame, px);
            }
            survey_joined = true;
        }
        if let (Some(b), true) = (block.as_mut(), survey_joined) {
            waiting.sort_by_key(|(s, _)| s.frame);
            for (stamp, ties) in waiting.drain(..) {
                b.add_ties(ties.iter().map(|t| (t.track, t.frame, [t.col, t.row])));
                frames += 1;
                let oriented = b.orient(stamp.frame);
                if oriented {
                    revision += 1;
                }
                tracing::info!(
                    "frame {}: {} ({} of {frames} oriented{}, σ0 {:.2})",
                    stamp.frame,
                    if oriented { "oriented" } else { "not oriented yet" },
                    b.poses.len(),
                    if b.georeferenced { ", georeferenced" } else { "" },
                    b.report.sigma0
                );
                publish(&output, b, stamp, revision, pixel_mm)?;
                last_stamp = stamp;
            }
        }
        if ties_in.is_ended() && block.is_none() {
            bail!("node '{}': the tie points ended but no camera model arrived", ctx.name());
        }
        Ok(if ties_in.is_ended() && waiting.is_empty() {
            Flow::Stop
        } else {
            Flow::Continue
        })
    })?;
    if let Some(b) = block.as_mut() {
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
            b.report.rms_mm / pixel_mm,
            b.report.removed.len()
        );
        publish(&output, b, last_stamp, revision + 1, pixel_mm)?;
        write_results(&ctx, b, &names)?;
    }
    output.end_of_stream()?;
    ctx.finish();
    Ok(())
}
