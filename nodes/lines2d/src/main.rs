//! `lineflow-lines2d`: the lines2d stage's process. `impl = "trace"` (default) feeds the state machine of
//! [`lineflow_lines2d::stage`] with the latched camera, each edge map and (when wired) the grey images; `impl =
//! "lsd"` detects segments on the grey images. Both publish segments with their pixel chains and write
//! `lines2d.csv` into the run's output folder.
use anyhow::{Context, Result};
use lineflow_formats::Lines2dWriter;
use lineflow_lines2d::stage::{FrameLines, TraceStage};
use lineflow_lines2d::{LsdParams, TraceParams};
use lineflow_messages::{kinds, Lines2DHeader};
use lineflow_runtime::{Flow, Input, NodeContext, Output};

fn main() -> std::process::ExitCode {
    lineflow_runtime::run_stage("lines2d", "trace", &[("trace", run_trace), ("lsd", run_lsd)])
}

/// Publishes one frame's segments and appends its rows to `lines2d.csv`.
fn publish(output: &Output<kinds::Lines2D>, lines: FrameLines, rows: &mut Lines2dWriter) -> Result<()> {
    let header = Lines2DHeader {
        stamp: lines.stamp,
        n_segments: lines.segments.len() as u32,
        n_chain: lines.chain.len() as u32,
        name: lines.name,
    };
    output.publish_parts(header, &lines.segments, &lines.chain)?;
    rows.append(&lines.rows)
        .with_context(|| format!("writing {}", rows.path().display()))
}

/// `lines2d.csv` in the run's output folder, written as the frames come.
fn rows_file(ctx: &NodeContext) -> Result<Lines2dWriter> {
    let path = ctx.out_dir().join("lines2d.csv");
    Lines2dWriter::create(&path).with_context(|| format!("creating {}", path.display()))
}

fn report_rows(rows: &Lines2dWriter, what: &str) {
    tracing::info!("{} segments{what} -> {}", rows.rows(), rows.path().display());
}

/// `impl = "lsd"`: segments straight from the grey images (input `images`; `edges` is ignored when wired).
fn run_lsd(ctx: NodeContext) -> Result<()> {
    let p: LsdParams = ctx.stage_params()?;
    let images = ctx.input::<kinds::Image>("images")?;
    let unused_edges = ctx.optional_input::<kinds::EdgeMap>("edges")?;
    let unused_camera = ctx.optional_input::<kinds::CameraModel>("camera")?;
    let output = ctx.output::<kinds::Lines2D>("lines2d")?;
    ctx.connect()?;
    let (mut gray, mut rows) = (Vec::new(), rows_file(&ctx)?);
    ctx.run(|| {
        drain(&unused_edges)?;
        drain(&unused_camera)?;
        lineflow_imaging::for_each_gray(&images, &mut gray, |h, gray| {
            // Between frames too: LSD takes long enough for the unused queues to fill.
            drain(&unused_edges)?;
            let found = lineflow_lines2d::lsd::lsd(gray, h.width as usize, h.height as usize, p.min_length_px);
            let lines = FrameLines::assemble(h.stamp, h.name, found.iter().map(|s| (s.start, s.end, s.chain.as_slice())));
            publish(&output, lines, &mut rows)
        })?;
        Ok(if images.is_ended() { Flow::Stop } else { Flow::Continue })
    })?;
    output.end_of_stream()?;
    report_rows(&rows, " (lsd)");
    ctx.finish();
    Ok(())
}

/// Takes and drops what waits on an input the implementation does not use (wired so that another implementation can
/// be swapped in without editing the graph), so that its publisher never waits for this node.
fn drain<M: lineflow_messages::Message>(input: &Option<Input<M>>) -> Result<()> {
    if let Some(i) = input {
        while i.receive()?.is_some() {}
    }
    Ok(())
}

/// `impl = "trace"`: the thesis's line tracing on the edge maps.
fn run_trace(ctx: NodeContext) -> Result<()> {
    let params: TraceParams = ctx.stage_params()?;
    let edges = ctx.input::<kinds::EdgeMap>("edges")?;
    let camera_in = ctx.input::<kinds::CameraModel>("camera")?;
    // With the images wired, lines are fitted to sub-pixel edge positions; without them, to the edge pixels.
    let images = ctx.optional_input::<kinds::Image>("images")?;
    let output = ctx.output::<kinds::Lines2D>("lines2d")?;
    ctx.connect()?;
    let mut stage = TraceStage::new(params, images.is_some());
    let (mut buffers, mut rows) = (lineflow_imaging::PlaneBuffers::default(), rows_file(&ctx)?);
    ctx.run(|| {
        if let Some(i) = &images {
            // Sub-pixel positions on the gradient the edges stage found the edges on with its default `color`:
            // colour images give their channels' where they are stronger across plumb edges.
            lineflow_imaging::for_each_planes(i, lineflow_imaging::ColourEdges::default(), &mut buffers, |h, planes| {
                stage.on_image(h.stamp.frame, planes);
                Ok(())
            })?;
        }
        while let Some(m) = camera_in.receive()? {
            stage.on_camera(m.user_header().camera());
        }
        while let Some(m) = edges.receive()? {
            stage.on_edges(*m.user_header(), m.payload());
        }
        let images_ended = images.as_ref().is_none_or(Input::is_ended);
        let named = |e: lineflow_lines2d::stage::TraceError| anyhow::anyhow!("node '{}': {e}", ctx.name());
        while let Some(lines) = stage.next_frame(images_ended) {
            publish(&output, lines.map_err(named)?, &mut rows)?;
        }
        stage.check_camera(edges.is_ended()).map_err(named)?;
        Ok(if edges.is_ended() && !stage.has_waiting() {
            Flow::Stop
        } else {
            Flow::Continue
        })
    })?;
    output.end_of_stream()?;
    report_rows(&rows, "");
    ctx.finish();
    Ok(())
}
