//! `lineflow-stats`: a sink that writes `frames.csv` (one row per image that arrived) and logs rates.
use std::io::Write;

use anyhow::{Context, Result};
use lineflow_messages::{kinds::Image, Encoding};
use lineflow_runtime::{Flow, NodeContext};
use lineflow_stats::{fnv1a64, FRAMES_CSV_HEADER};

#[derive(serde::Deserialize)]
#[serde(deny_unknown_fields)]
struct Params {
    #[serde(default = "default_file")]
    file: String,
}
fn default_file() -> String {
    "frames.csv".into()
}

fn main() -> std::process::ExitCode {
    lineflow_runtime::run_node(body)
}

fn body() -> Result<()> {
    let ctx = NodeContext::from_env()?;
    let p: Params = ctx.params()?;
    let input = ctx.input::<Image>("images")?;
    ctx.connect()?;
    let path = ctx.out_dir().join(&p.file);
    let mut out = std::io::BufWriter::new(std::fs::File::create(&path).with_context(|| format!("cannot create {}", path.display()))?);
    writeln!(out, "{FRAMES_CSV_HEADER}")?;
    let (start, mut bytes, mut frames) = (std::time::Instant::now(), 0usize, 0u64);
    ctx.run(|| {
        while let Some(msg) = input.receive()? {
            let h = msg.user_header();
            let enc = Encoding::from_u32(h.encoding).map(Encoding::name).unwrap_or("unknown");
            writeln!(
                out,
                "{},{},{},{},{enc},{},{:016x}",
                h.stamp.frame,
                h.name(),
                h.width,
                h.height,
                h.stamp.capture_time_ns,
                fnv1a64(msg.payload())
            )?;
            bytes += msg.payload().len();
            frames += 1;
        }
        Ok(if input.is_ended() { Flow::Stop } else { Flow::Continue })
    })?;
    out.flush().with_context(|| format!("cannot write {}", path.display()))?;
    let secs = start.elapsed().as_secs_f64().max(1e-9);
    tracing::info!(
        "{frames} frames, {:.1} MB in {secs:.2} s ({:.1} frames/s) -> {}",
        bytes as f64 / 1e6,
        frames as f64 / secs,
        path.display()
    );
    ctx.finish();
    Ok(())
}
