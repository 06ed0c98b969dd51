//! `lineflow-edges`: the edges stage's process (`impl = "canny"`, `"sobel"` or `"log"`, [`lineflow_edges::detector`]);
//! one EdgeMap per image.
use anyhow::{bail, Result};
use lineflow_edges::{Detector, EdgeParams};
use lineflow_messages::{fixed_str, kinds, EdgeMapHeader};
use lineflow_runtime::{Flow, NodeContext};

fn main() -> std::process::ExitCode {
    let run: lineflow_runtime::Implementation = run;
    lineflow_runtime::run_stage("edges", "canny", &[("canny", run), ("sobel", run), ("log", run)])
}

fn run(ctx: NodeContext) -> Result<()> {
    let impl_ = ctx.implementation("canny").to_owned();
    let params: EdgeParams = ctx.params()?;
    let detector = Detector::new(&impl_, params).map_err(|e| anyhow::anyhow!("node '{}': {e}", ctx.name()))?;
    let input = ctx.input::<kinds::Image>("images")?;
    let output = ctx.output::<kinds::EdgeMap>("edges")?;
    ctx.connect()?;
    let colour = params.color.unwrap_or_default();
    let mut buffers = lineflow_imaging::PlaneBuffers::default();
    ctx.run(|| {
        lineflow_imaging::for_each_planes(&input, colour, &mut buffers, |h, planes| {
            let (w, ht) = (h.width as usize, h.height as usize);
            if w > u16::MAX as usize || ht > u16::MAX as usize {
                bail!("frame {}: {w}x{ht} exceeds the 65535-pixel edge map limit", h.stamp.frame);
            }
            let header = EdgeMapHeader {
                stamp: h.stamp,
                width: h.width,
                height: h.height,
                detector: fixed_str(&impl_),
                name: h.name,
            };
            output.publish(header, &detector.detect_in(planes, w, ht))
        })?;
        Ok(if input.is_ended() { Flow::Stop } else { Flow::Continue })
    })?;
    output.end_of_stream()?;
    ctx.finish();
    Ok(())
}
