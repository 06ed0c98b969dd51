//! `lineflow-linemap`: the linemap stage. 3-D lines from the 2-D segments of every oriented image
//! (`impl = "tracks"`): pairwise hypotheses scored by every image, re-estimated from all their segments, cut to the
//! stretches the images cover. Publishes the current set for every frame, the final set after the final poses,
//! and writes `lines3d.csv` and `lines3d.ply`.
use std::collections::BTreeMap;

use anyhow::Result;
use lineflow_formats::{write_lines3d_results, Line3Row};
use lineflow_linemap::{line_messages, MapParams, MapStage, MappedLine, Photo};
use lineflow_messages::{kinds, Lines3DHeader, Stamp, StampFlags};
use lineflow_photogrammetry::Vec3;
use lineflow_runtime::{Flow, NodeContext, Output};

fn main() -> std::process::ExitCode {
    lineflow_runtime::run_stage("linemap", "tracks", &[("tracks", run)])
}

fn publish(output: &Output<kinds::Lines3D>, stamp: Stamp, lines: &[MappedLine]) -> Result<()> {
    output.publish(Lines3DHeader { stamp }, &line_messages(lines))
}

fn run(ctx: NodeContext) -> Result<()> {
    let params: MapParams = ctx.stage_params()?;
    let lines_in = ctx.input::<kinds::Lines2D>("lines2d")?;
    let poses_in = ctx.input::<kinds::Poses>("poses")?;
    let camera_in = ctx.input::<kinds::CameraModel>("camera")?;
    let site_in = ctx.optional_input::<kinds::Site>("site")?;
    let images_in = ctx.optional_input::<kinds::Image>("images")?;
    let output = ctx.output::<kinds::Lines3D>("lines3d")?;
    ctx.connect()?;
    let mut stage = MapStage::new(params);
    if images_in.is_some() {
        stage.wait_for_photos();
    } else {
        tracing::info!("no images input: lines are made without the appearance test");
    }
    let mut gray = Vec::new();
    let mut waiting: Vec<Stamp> = Vec::new();
    let mut last = Stamp::default();
    ctx.run(|| {
        while let Some(m) = camera_in.receive()? {
            stage.set_camera(m.user_header().camera());
        }
        if let Some(i) = &site_in {
            while let Some(m) = i.receive()? {
                let walls: Vec<Vec<Vec3>> = m
                    .payload()
                    .iter()
                    .map(|w| w.corners().iter().map(|&c| Vec3::from(c)).collect())
                    .collect();
                tracing::info!("site model: {} walls bound the search", walls.len());
                stage.set_walls(&walls);
            }
        }
        if let Some(i) = &images_in {
            lineflow_imaging::for_each_gray(i, &mut gray, |h, g| {
                match Photo::new(h.width as usize, h.height as usize, g.to_vec()) {
                    Some(photo) => stage.add_photo(h.stamp.frame, photo),
                    None => tracing::warn!("frame {}: image of {}x{} too small to compare", h.stamp.frame, h.width, h.height),
                }
                Ok(())
            })?;
        }
        lines_in.for_each_segments(|h, segments, _| {
            stage.add_segments(h.stamp.frame, segments.to_vec());
            waiting.push(h.stamp);
            Ok(())
        })?;
        while let Some(m) = poses_in.receive()? {
            // Every Poses message holds every oriented frame; the newest is the best.
            stage.set_poses(m.payload().iter().map(|p| (p.frame, p.exterior())).collect::<BTreeMap<_, _>>());
        }
        if stage.update() {
            tracing::debug!(lines = stage.lines().len(), frames = stage.ready_frames(), "mapped");
        }
        // Every frame gets a set once it is in, so downstream sees no frame missing.
        for stamp in waiting.drain(..) {
            publish(&output, stamp, stage.lines())?;
            if stamp.frame >= last.frame {
                last = stamp;
            }
        }
        // The camera and the site model are latched: they arrive first and never end.
        Ok(
            if lines_in.is_ended() && poses_in.is_ended() && images_in.as_ref().is_none_or(|i| i.is_ended()) {
                Flow::Stop
            } else {
                Flow::Continue
            },
        )
    })?;
    if !stage.has_camera() {
        tracing::warn!("no camera model arrived: no 3-D lines");
    }
    let start = std::time::Instant::now();
    let lines = stage.finish().to_vec();
    tracing::info!(
        "{} 3-D lines from {} oriented frames in {:.2} s",
        lines.len(),
        stage.ready_frames(),
        start.elapsed().as_secs_f64()
    );
    // A revision above the last one, or subscribers would take the final set for a duplicate of it.
    last.flags |= StampFlags::FINAL;
    last.revision += 1;
    publish(&output, last, &lines)?;
    output.end_of_stream()?;
    let rows: Vec<Line3Row> = line_messages(&lines).iter().map(Line3Row::from).collect();
    let csv = write_lines3d_results(&ctx.out_dir(), &rows)?;
    tracing::info!("{} 3-D lines -> {}", rows.len(), csv.display());
    ctx.finish();
    Ok(())
}
