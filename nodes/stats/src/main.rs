//! `lineflow-stats`: a sink that writes `frames.csv` (one row per image that arrived) and, when wired, `edges.csv`
//! (one row per edge map: frame, detector, edge pixels, checksum) and `segments.csv` (one row per Lines2D message:
//! frame, segments, chain pixels, checksum), and logs rates.
use std::io::Write;

use anyhow::{Context, Result};
use lineflow_messages::kinds::{EdgeMap, Image, Lines2D};
use lineflow_messages::Encoding;
use lineflow_runtime::{Flow, NodeContext};
use lineflow_stats::{fnv1a64, fnv1a64_extend, FNV1A64_START, FRAMES_CSV_HEADER};

#[derive(serde::Deserialize)]
#[serde(deny_unknown_fields)]
struct Params {
    #[serde(default = "default_file")]
    file: String,
}
fn default_file() -> String {
    "frames.csv".into()
}

type Sink = (std::io::BufWriter<std::fs::File>, std::path::PathBuf);

/// A CSV file in the run's output folder, header written.
fn csv_sink(ctx: &NodeContext, name: &str, header: &str) -> Result<Sink> {
    let path = ctx.out_dir().join(name);
    let mut f = std::io::BufWriter::new(std::fs::File::create(&path).with_context(|| format!("cannot create {}", path.display()))?);
    writeln!(f, "{header}")?;
    Ok((f, path))
}

fn main() -> std::process::ExitCode {
    lineflow_runtime::run_node(body)
}

fn body() -> Result<()> {
    let ctx = NodeContext::from_env()?;
    let p: Params = ctx.params()?;
    let input = ctx.input::<Image>("images")?;
    let edges = ctx.optional_input::<EdgeMap>("edges")?;
    let lines = ctx.optional_input::<Lines2D>("lines2d")?;
    ctx.connect()?;
    let mut segments_csv = lines
        .as_ref()
        .map(|_| csv_sink(&ctx, "segments.csv", "frame,image,n_segments,n_chain,fnv1a64"))
        .transpose()?;
    let mut edges_csv = edges
        .as_ref()
        .map(|_| csv_sink(&ctx, "edges.csv", "frame,detector,n_pixels,fnv1a64"))
        .transpose()?;
    let (mut out, path) = csv_sink(&ctx, &p.file, FRAMES_CSV_HEADER)?;
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
        if let (Some(e), Some((f, _))) = (&edges, &mut edges_csv) {
            while let Some(msg) = e.receive()? {
                let h = msg.user_header();
                // Field by field in little-endian order, so the checksum does not depend on the struct's layout.
                let sum = msg.payload().iter().fold(FNV1A64_START, |h, p| {
                    let h = fnv1a64_extend(h, &p.col.to_le_bytes());
                    let h = fnv1a64_extend(h, &p.row.to_le_bytes());
                    let h = fnv1a64_extend(h, &p.magnitude.to_le_bytes());
                    fnv1a64_extend(h, &p.direction_rad.to_le_bytes())
                });
                writeln!(
                    f,
                    "{},{},{},{:016x}",
                    h.stamp.frame,
                    lineflow_messages::str_from_fixed(&h.detector),
                    msg.payload().len(),
                    sum
                )?;
            }
        }
        if let (Some(l), Some((f, _))) = (&lines, &mut segments_csv) {
            while let Some(msg) = l.receive()? {
                let h = msg.user_header();
                writeln!(
                    f,
                    "{},{},{},{},{:016x}",
                    h.stamp.frame,
                    h.name(),
                    h.n_segments,
                    h.n_chain,
                    fnv1a64(msg.payload())
                )?;
            }
        }
        let done = input.is_ended() && edges.as_ref().is_none_or(|e| e.is_ended()) && lines.as_ref().is_none_or(|e| e.is_ended());
        Ok(if done { Flow::Stop } else { Flow::Continue })
    })?;
    for (mut f, path) in edges_csv.into_iter().chain(segments_csv) {
        f.flush().with_context(|| format!("cannot write {}", path.display()))?;
    }
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
