//! `lineflow-convert`: pixel-format conversion (`impl = "gray"`). Stateless: one output per input frame.
use anyhow::Result;
use lineflow_messages::{image::ImageHeader, kinds::Image, Encoding};
use lineflow_runtime::{Flow, NodeContext};

/// `gray` takes no parameters; any given is a typo worth an error.
#[derive(serde::Deserialize)]
#[serde(deny_unknown_fields)]
struct NoParams {}

fn main() -> std::process::ExitCode {
    lineflow_runtime::run_stage("convert", "gray", &[("gray", run)])
}

fn run(ctx: NodeContext) -> Result<()> {
    let _: NoParams = ctx.params()?;
    let (input, output) = (ctx.input::<Image>("images")?, ctx.output::<Image>("gray")?);
    ctx.connect()?;
    ctx.run(|| {
        while let Some(msg) = input.receive()? {
            let h = *msg.user_header();
            let (w, ht) = (h.width as usize, h.height as usize);
            let out = ImageHeader {
                step: h.width,
                encoding: Encoding::Mono8 as u32,
                ..h
            };
            let mut result = Ok(());
            output.publish_with(out, w * ht, |dst| result = lineflow_imaging::gray_of_image(&h, msg.payload(), dst))?;
            result?;
        }
        Ok(if input.is_ended() { Flow::Stop } else { Flow::Continue })
    })?;
    output.end_of_stream()?;
    ctx.finish();
    Ok(())
}
