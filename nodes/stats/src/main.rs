//! `lineflow-stats`: a sink that writes `frames.csv` (one row per image that arrived) and, when wired, `edges.csv`
//! (one row per edge map: frame, detector, edge pixels, checksum) and `segments.csv` (one row per Lines2D message:
//! frame, segments, chain pixels, checksum), and logs rates.
use std::io::Write;

use anyhow::{Context, Result};
use lineflow_messages::kinds::{EdgeMap, Image, Lines2D};
use lineflow_runtime::{Flow, NodeContext};
use lineflow_stats::{edges_row, frame_row, segments_row, StatsParams, EDGES_CSV_HEADER, FRAMES_CSV_HEADER, SEGMENTS_CSV_HEADER};

type Sink = (std::io::BufWriter<std::fs::File>, std::path::PathBuf);

/// A CSV file in the run's output folder, header written.
fn csv_sink(ctx: &NodeContext, name: &str, header: &str) -> Result<Sink> {
    let path = ctx.out_dir().join(name);
    let mut f = std::io::BufWriter::new(std::fs::File::create(&path).with_context(|| format!("cannot create {}", path.display()))?);
    writeln!(f, "{header}")?;
    Ok((f, path))
}

fn main() -> std::process::ExitCode {
    lineflow_runtime::run_stage("stats", "csv", &[("csv", run)])
}

fn run(ctx: NodeContext) -> Result<()> {
    let p: StatsParams = ctx.stage_params()?;
    let input = ctx.input::<Image>("images")?;
    let edges = ctx.optional_input::<EdgeMap>("edges")?;
    let lines = ctx.optional_input::<Lines2D>("lines2d")?;
    ctx.connect()?;
    let mut segments_csv = lines
        .as_ref()
        .map(|_| csv_sink(&ctx, "segments.csv", SEGMENTS_CSV_HEADER))
        .transpose()?;
    let mut edges_csv = edges.as_ref().map(|_| csv_sink(&ctx, "edges.csv", EDGES_CSV_HEADER)).transpose()?;
    let (mut out, path) = csv_sink(&ctx, &p.file, FRAMES_CSV_HEADER)?;
    let (start, mut bytes, mut frames) = (std::time::Instant::now(), 0usize, 0u64);
    ctx.run(|| {
        while let Some(msg) = input.receive()? {
            writeln!(out, "{}", frame_row(msg.user_header(), msg.payload()))?;
            bytes += msg.payload().len();
            frames += 1;
        }
        if let (Some(e), Some((f, _))) = (&edges, &mut edges_csv) {
            while let Some(msg) = e.receive()? {
                writeln!(f, "{}", edges_row(msg.user_header(), msg.payload()))?;
            }
        }
        if let (Some(l), Some((f, _))) = (&lines, &mut segments_csv) {
            while let Some(msg) = l.receive()? {
                writeln!(f, "{}", segments_row(msg.user_header(), msg.payload()))?;
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
