//! `lineflow-lines2d`: the lines2d stage. `impl = "trace"` (default) joins the latched camera with each edge map;
//! `impl = "lsd"` detects segments on the grey images. Both publish segments with their pixel chains and write
//! `lines2d.csv` into the run's output folder.
use anyhow::{bail, Context, Result};
use lineflow_formats::{write_lines2d, Line2Row};
use lineflow_lines2d::TraceParams;
use lineflow_messages::{kinds, EdgeMapHeader, EdgePixel, Lines2DHeader, Segment2};
use lineflow_photogrammetry::Camera;
use lineflow_runtime::{Flow, NodeContext};
use serde::Deserialize;

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct Params {
    /// Largest perpendicular distance of a new pixel from the current line, pixels.
    #[serde(default = "default_distance")]
    max_distance_px: f64,
    /// Shortest segment kept, pixels.
    #[serde(default = "default_length")]
    min_length_px: f64,
    /// Collinear fragments closer than this are joined (0 = the thesis's tracing alone).
    #[serde(default = "default_gap")]
    max_gap_px: f64,
    /// Largest angle between joined fragments, degrees.
    #[serde(default = "default_angle")]
    max_merge_angle_deg: f64,
    /// How far ahead along its line a chain looks for its next pixel across a gap, pixels (0 = the thesis's
    /// 8-neighbour search alone).
    #[serde(default = "default_jump")]
    max_jump_px: f64,
}

fn default_distance() -> f64 {
    TraceParams::default().max_distance_px
}
fn default_length() -> f64 {
    TraceParams::default().min_length_px
}
fn default_gap() -> f64 {
    TraceParams::default().max_gap_px
}
fn default_angle() -> f64 {
    TraceParams::default().max_merge_angle_deg
}
fn default_jump() -> f64 {
    TraceParams::default().max_jump_px
}

/// One frame's segments, their concatenated pixel chains, and their `lines2d.csv` rows.
type FrameLines = (Vec<Segment2>, Vec<[u16; 2]>, Vec<Line2Row>);

/// Numbers segments in order and lays out their chains one after the other, with their `lines2d.csv` rows.
fn assemble<'a>(image: &str, found: impl Iterator<Item = ([f64; 2], [f64; 2], &'a [[u16; 2]])>) -> FrameLines {
    let (mut segs, mut chain, mut rows) = (Vec::new(), Vec::new(), Vec::new());
    for (id, (a, b, pixels)) in found.enumerate() {
        segs.push(Segment2 {
            id: id as u32,
            chain_start: chain.len() as u32,
            chain_len: pixels.len() as u32,
            reserved: 0,
            start_px: a,
            end_px: b,
        });
        chain.extend_from_slice(pixels);
        rows.push(Line2Row {
            image: image.to_owned(),
            id: id as u64,
            start_px: a,
            end_px: b,
            n_pixels: Some(pixels.len() as u32),
        });
    }
    (segs, chain, rows)
}

/// Publishes one frame's segments with the stamp and image name of its source.
fn publish(
    output: &lineflow_runtime::Output<kinds::Lines2D>,
    stamp: lineflow_messages::Stamp,
    name: [u8; 64],
    segs: &[Segment2],
    chain: &[[u16; 2]],
) -> Result<()> {
    let header = Lines2DHeader {
        stamp,
        n_segments: segs.len() as u32,
        n_chain: chain.len() as u32,
        name,
    };
    output.publish_parts(header, segs, chain)
}

/// Segments of one edge map, with their rows for `lines2d.csv`; with the frame's grey image the lines are fitted to
/// the edges' sub-pixel positions.
fn segments(cam: &Camera, h: &EdgeMapHeader, px: &[EdgePixel], gray: Option<&[u8]>, p: &TraceParams) -> Result<FrameLines> {
    if (h.width, h.height) != (cam.width, cam.height) {
        bail!(
            "frame {} ({}): edge map is {}x{} but the camera is {}x{}",
            h.stamp.frame,
            h.name(),
            h.width,
            h.height,
            cam.width,
            cam.height
        );
    }
    let pixels: Vec<[u16; 2]> = px.iter().map(|e| [e.col, e.row]).collect();
    let traced = match gray {
        Some(g) if g.len() == cam.width as usize * cam.height as usize => {
            let positions = lineflow_imaging::subpixel_positions(g, cam.width as usize, cam.height as usize, px);
            lineflow_lines2d::trace_measured_at(cam, &pixels, &positions, p)
        }
        _ => lineflow_lines2d::trace_measured(cam, &pixels, p),
    };
    Ok(assemble(h.name(), traced.iter().map(|(a, b, chain)| (*a, *b, chain.as_slice()))))
}

fn main() -> std::process::ExitCode {
    lineflow_runtime::run_node(body)
}

fn body() -> Result<()> {
    let ctx = NodeContext::from_env()?;
    match ctx.implementation("trace") {
        "trace" => run_trace(ctx),
        "lsd" => run_lsd(ctx),
        other => bail!("node '{}': unknown lines2d impl '{other}' (available: trace, lsd)", ctx.name()),
    }
}

/// `impl = "lsd"`: segments straight from the grey images (input `images`; `edges` is ignored when wired).
fn run_lsd(ctx: NodeContext) -> Result<()> {
    #[derive(Debug, Deserialize)]
    #[serde(deny_unknown_fields)]
    struct LsdParams {
        #[serde(default = "default_length")]
        min_length_px: f64,
    }
    let p: LsdParams = ctx.params()?;
    if !p.min_length_px.is_finite() || p.min_length_px < 0.0 {
        bail!("node '{}': min_length_px must be >= 0", ctx.name());
    }
    let images = ctx.input::<kinds::Image>("images")?;
    let unused_edges = ctx.optional_input::<kinds::EdgeMap>("edges")?;
    let unused_camera = ctx.optional_input::<kinds::CameraModel>("camera")?;
    let output = ctx.output::<kinds::Lines2D>("lines2d")?;
    ctx.connect()?;
    let path = ctx.out_dir().join("lines2d.csv");
    let (mut gray, mut rows) = (Vec::new(), Vec::new());
    ctx.run(|| {
        drain(&unused_edges)?;
        drain(&unused_camera)?;
        lineflow_imaging::for_each_gray(&images, &mut gray, |h, gray| {
            // Between frames too: LSD takes long enough for the unused queues to fill.
            drain(&unused_edges)?;
            let found = lineflow_lines2d::lsd::lsd(gray, h.width as usize, h.height as usize, p.min_length_px);
            let (segs, chain, r) = assemble(h.name(), found.iter().map(|s| (s.start, s.end, s.chain.as_slice())));
            rows.extend(r);
            publish(&output, h.stamp, h.name, &segs, &chain)
        })?;
        Ok(if images.is_ended() { Flow::Stop } else { Flow::Continue })
    })?;
    output.end_of_stream()?;
    write_lines2d(&path, &rows).with_context(|| format!("writing {}", path.display()))?;
    tracing::info!("{} segments (lsd) -> {}", rows.len(), path.display());
    ctx.finish();
    Ok(())
}

/// Takes and drops what waits on an input the implementation does not use (wired so that another implementation can
/// be swapped in without editing the graph), so that its publisher never waits for this node.
fn drain<M: lineflow_messages::Message>(input: &Option<lineflow_runtime::Input<M>>) -> Result<()> {
    if let Some(i) = input {
        while i.receive()?.is_some() {}
    }
    Ok(())
}

/// Longer jumps would join unrelated edges that happen to line up.
const MAX_JUMP_PX: f64 = 32.0;

/// `impl = "trace"`: the thesis's line tracing on the edge maps.
fn run_trace(ctx: NodeContext) -> Result<()> {
    let p: Params = ctx.params()?;
    if !(p.max_distance_px > 0.0
        && p.min_length_px >= 0.0
        && p.max_gap_px >= 0.0
        && (0.0..90.0).contains(&p.max_merge_angle_deg)
        && (0.0..=MAX_JUMP_PX).contains(&p.max_jump_px))
    {
        bail!(
            "node '{}': max_distance_px must be > 0, min_length_px and max_gap_px >= 0, max_merge_angle_deg in [0, 90), max_jump_px in [0, {MAX_JUMP_PX}]",
            ctx.name()
        );
    }
    let params = TraceParams {
        max_distance_px: p.max_distance_px,
        min_length_px: p.min_length_px,
        max_gap_px: p.max_gap_px,
        max_merge_angle_deg: p.max_merge_angle_deg,
        max_jump_px: p.max_jump_px,
    };
    let edges = ctx.input::<kinds::EdgeMap>("edges")?;
    let camera_in = ctx.input::<kinds::CameraModel>("camera")?;
    // With the images wired, lines are fitted to sub-pixel edge positions; without them, to the edge pixels.
    let images = ctx.optional_input::<kinds::Image>("images")?;
    let output = ctx.output::<kinds::Lines2D>("lines2d")?;
    ctx.connect()?;
    let path = ctx.out_dir().join("lines2d.csv");
    let mut cam: Option<Camera> = None;
    // Edge maps that arrive before the camera (or their image) wait for it, in order.
    let mut waiting: std::collections::VecDeque<(EdgeMapHeader, Vec<EdgePixel>)> = Default::default();
    let mut grays: std::collections::BTreeMap<u64, Vec<u8>> = Default::default();
    let mut buffer = Vec::new();
    let mut rows = Vec::new();
    ctx.run(|| {
        if let Some(i) = &images {
            lineflow_imaging::for_each_gray(i, &mut buffer, |h, g| {
                grays.insert(h.stamp.frame, g.to_vec());
                Ok(())
            })?;
        }
        while let Some(m) = camera_in.receive()? {
            cam = Some(m.user_header().camera());
        }
        while let Some(m) = edges.receive()? {
            waiting.push_back((*m.user_header(), m.payload().to_vec()));
        }
        if let Some(c) = &cam {
            let images_done = images.as_ref().is_none_or(|i| i.is_ended());
            while let Some((h, _)) = waiting.front() {
                let frame = h.stamp.frame;
                if !grays.contains_key(&frame) && !images_done {
                    break;
                }
                let Some((h, px)) = waiting.pop_front() else { break };
                let (segs, chain, r) = segments(c, &h, &px, grays.get(&frame).map(Vec::as_slice), &params)?;
                publish(&output, h.stamp, h.name, &segs, &chain)?;
                rows.extend(r);
                // Images of frames without an edge map are not kept either.
                grays.retain(|&f, _| f > frame);
            }
        }
        let done = edges.is_ended() && waiting.is_empty();
        if edges.is_ended() && cam.is_none() {
            bail!("node '{}': the edge maps ended but no camera model arrived", ctx.name());
        }
        Ok(if done { Flow::Stop } else { Flow::Continue })
    })?;
    output.end_of_stream()?;
    write_lines2d(&path, &rows).with_context(|| format!("writing {}", path.display()))?;
    tracing::info!("{} segments -> {}", rows.len(), path.display());
    ctx.finish();
    Ok(())
}
