//! `lineflow-linemap`: the linemap stage. 3-D lines from the 2-D segments of every oriented image
//! (`impl = "tracks"`): pairwise hypotheses scored by every image, re-estimated from all their segments, cut to the
//! stretches the images cover. Publishes the current set for every frame, the final set after the final poses,
//! and writes `lines3d.csv` and `lines3d.ply`.
use std::collections::BTreeMap;

use anyhow::Result;
use lineflow_formats::{write_lines3d_results_as, Line3Row};
use lineflow_linemap::{line_messages, MapParams, MapStage, MappedLine, Photo};
use lineflow_messages::{kinds, Lines3DHeader, Segment2, Stamp, StampFlags};
use lineflow_photogrammetry::{Camera, Pose, Vec3};
use lineflow_runtime::{Flow, Input, NodeContext, Output};

fn main() -> std::process::ExitCode {
    lineflow_runtime::run_stage("linemap", "tracks", &[("tracks", run)])
}

fn publish(output: &Output<kinds::Lines3D>, stamp: Stamp, lines: &[MappedLine], params: &MapParams) -> Result<()> {
    output.publish(Lines3DHeader { stamp }, &line_messages(lines, params))
}

/// The stage's inputs.
struct Ports {
    lines: Input<kinds::Lines2D>,
    poses: Input<kinds::Poses>,
    camera: Input<kinds::CameraModel>,
    site: Option<Input<kinds::Site>>,
    images: Option<Input<kinds::Image>>,
}

/// What arrived and is not yet handed to the stage (it is busy remapping meanwhile).
#[derive(Default)]
struct Arrivals {
    camera: Option<Camera>,
    walls: Option<Vec<Vec<Vec3>>>,
    photos: Vec<(u64, Photo)>,
    segments: Vec<(Stamp, Vec<Segment2>)>,
    /// Every Poses message holds every oriented frame: the newest is the best.
    poses: Option<BTreeMap<u64, Pose>>,
}

impl Ports {
    fn ended(&self) -> bool {
        // The camera and the site model are latched: they arrive first and never end.
        self.lines.is_ended() && self.poses.is_ended() && self.images.as_ref().is_none_or(|i| i.is_ended())
    }

    /// Takes every waiting message into `into`.
    fn receive(&self, into: &mut Arrivals, gray: &mut Vec<u8>) -> Result<()> {
        while let Some(m) = self.camera.receive()? {
            into.camera = Some(m.user_header().camera());
        }
        if let Some(i) = &self.site {
            while let Some(m) = i.receive()? {
                let walls = m.payload().iter().map(|w| w.corners().iter().map(|&c| Vec3::from(c)).collect());
                into.walls = Some(walls.collect());
            }
        }
        if let Some(i) = &self.images {
            lineflow_imaging::for_each_gray(i, gray, |h, g| {
                match Photo::new(h.width as usize, h.height as usize, g.to_vec()) {
                    Some(photo) => into.photos.push((h.stamp.frame, photo)),
                    None => tracing::warn!("frame {}: image of {}x{} too small to compare", h.stamp.frame, h.width, h.height),
                }
                Ok(())
            })?;
        }
        self.lines.for_each_segments(|h, segments, _| {
            into.segments.push((h.stamp, segments.to_vec()));
            Ok(())
        })?;
        while let Some(m) = self.poses.receive()? {
            into.poses = Some(m.payload().iter().map(|p| (p.frame, p.exterior())).collect());
        }
        Ok(())
    }
}

impl Arrivals {
    fn is_empty(&self) -> bool {
        self.camera.is_none() && self.walls.is_none() && self.photos.is_empty() && self.segments.is_empty() && self.poses.is_none()
    }

    /// Hands everything to the stage; the frames whose segments came are added to `waiting`.
    fn apply(&mut self, stage: &mut MapStage, waiting: &mut Vec<Stamp>) {
        if let Some(camera) = self.camera.take() {
            stage.set_camera(camera);
        }
        if let Some(walls) = self.walls.take() {
            tracing::info!("site model: {} walls bound the search", walls.len());
            stage.set_walls(&walls);
        }
        for (frame, photo) in self.photos.drain(..) {
            stage.add_photo(frame, photo);
        }
        for (stamp, segments) in self.segments.drain(..) {
            stage.add_segments(stamp.frame, segments);
            waiting.push(stamp);
        }
        if let Some(poses) = self.poses.take() {
            stage.set_poses(poses);
        }
    }
}

/// Remaps in a worker thread while this one keeps taking the inputs: a remap takes minutes at full size, and a
/// stage that stops taking its inputs for that long holds every lossless publisher upstream (the orientation's
/// final adjustment waited four minutes on it). What arrives meanwhile is handed over after the remap, which
/// works on the frames it started with.
fn remap_taking_inputs(stage: &mut MapStage, ports: &Ports, arrivals: &mut Arrivals, gray: &mut Vec<u8>) -> Result<()> {
    std::thread::scope(|s| {
        let worker = s.spawn(|| stage.remap());
        while !worker.is_finished() {
            ports.receive(arrivals, gray)?;
            std::thread::sleep(std::time::Duration::from_millis(50));
        }
        worker.join().map_err(|_| anyhow::anyhow!("the remap failed"))
    })
}

fn run(ctx: NodeContext) -> Result<()> {
    let params: MapParams = ctx.stage_params()?;
    let ports = Ports {
        lines: ctx.input("lines2d")?,
        poses: ctx.input("poses")?,
        camera: ctx.input("camera")?,
        site: ctx.optional_input("site")?,
        images: ctx.optional_input("images")?,
    };
    let output = ctx.output::<kinds::Lines3D>("lines3d")?;
    ctx.connect()?;
    let mut stage = MapStage::new(params.clone());
    if ports.images.is_some() {
        stage.wait_for_photos();
    } else {
        tracing::info!("no images input: lines are made without the appearance test");
    }
    let mut gray = Vec::new();
    let mut arrivals = Arrivals::default();
    let mut waiting: Vec<Stamp> = Vec::new();
    let mut last = Stamp::default();
    ctx.run(|| {
        ports.receive(&mut arrivals, &mut gray)?;
        arrivals.apply(&mut stage, &mut waiting);
        if stage.remap_due() {
            remap_taking_inputs(&mut stage, &ports, &mut arrivals, &mut gray)?;
            tracing::debug!(lines = stage.lines().len(), frames = stage.ready_frames(), "mapped");
        }
        // Every frame gets a set once it is in, so downstream sees no frame missing.
        for stamp in waiting.drain(..) {
            publish(&output, stamp, stage.lines(), &params)?;
            if stamp.frame >= last.frame {
                last = stamp;
            }
        }
        Ok(if ports.ended() && arrivals.is_empty() {
            Flow::Stop
        } else {
            Flow::Continue
        })
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
    publish(&output, last, &lines, &params)?;
    output.end_of_stream()?;
    let rows: Vec<Line3Row> = line_messages(&lines, &params).iter().map(Line3Row::from).collect();
    let csv = write_lines3d_results_as(&ctx.out_dir(), &params.results, &rows)?;
    tracing::info!("{} 3-D lines -> {}", rows.len(), csv.display());
    ctx.finish();
    Ok(())
}
