//! `lineflow-convert`: pixel-format conversion (`impl = "gray"`). Stateless: one output per input frame.
use anyhow::Result;
use lineflow_convert::{gray_header, gray_len};
use lineflow_messages::kinds::Image;
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
            let mut result = Ok(());
            output.publish_with(gray_header(&h), gray_len(&h), |dst| {
                result = lineflow_imaging::gray_of_image(&h, msg.payload(), dst)
            })?;
            result?;
        }
        Ok(if input.is_ended() { Flow::Stop } else { Flow::Continue })
    })?;
    output.end_of_stream()?;
    ctx.finish();
    Ok(())
}
