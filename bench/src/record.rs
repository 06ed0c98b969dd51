//! `lineflow bench record`: how many MB/s of raw camera frames the recorder node writes with nothing dropped,
//! against the disk's own sequential write speed (`write` + `fsync` of the same bytes) measured in the same run.
//!
//! A player process publishes noisy 12 MP RGB frames flat out; the recorder (the real node, as the supervisor adds
//! it to every graph) writes them. Throughput is the image bytes over the time from the first message's receipt to
//! the end of the run, the final `fsync` included.
use std::io::Write;
use std::path::Path;
use std::process::ExitCode;
use std::time::Instant;

use anyhow::{bail, Context, Result};
use lineflow_messages::schema::{bytes_of, encode};
use lineflow_messages::{Encoding, ImageHeader, MessageKind, Stamp};
use lineflow_recordings::{now_ns, Compression, McapWriter, Recording, META_END};
use lineflow_runtime::launch::{self, Resolver};
use lineflow_runtime::supervisor::{self, RunOptions};
use lineflow_synthetic::rng::Rng;

/// The recorder's target, MB/s.
const TARGET_MBPS: f64 = 500.0;
/// With `images = "png"`, MB/s of raw frames taken in (#32).
const TARGET_PNG_MBPS: f64 = 200.0;

/// A camera-like frame: a smooth pattern plus per-pixel noise, so that compression cannot cheat.
pub(crate) fn frame(width: u32, height: u32, seed: u64) -> Vec<u8> {
    let mut rng = Rng::new(seed, 0);
    let mut out = Vec::with_capacity(width as usize * height as usize * 3);
    for y in 0..height {
        for x in 0..width {
            let state = rng.next_u64();
            let base = ((x / 8 + y / 8) % 200) as u8;
            out.extend([
                base.wrapping_add((state & 7) as u8),
                base.wrapping_add((state >> 8 & 7) as u8),
                base,
            ]);
        }
    }
    out
}

/// The CDR of frame `k` of a 30 Hz stream, `pixels` with one byte changed so that frames differ; returns its
/// capture time.
pub(crate) fn frame_cdr(k: usize, width: u32, height: u32, pixels: &[u8], cdr: &mut Vec<u8>) -> u64 {
    let stamp = Stamp {
        frame: k as u64,
        capture_time_ns: 1_600_000_000_000_000_000 + k as u64 * 33_333_333,
        ..Default::default()
    };
    let h = ImageHeader {
        stamp,
        width,
        height,
        step: width * 3,
        encoding: Encoding::Rgb8 as u32,
        ..Default::default()
    };
    let mut px = pixels.to_vec();
    let at = k % px.len();
    px[at] ^= 0x55;
    encode(MessageKind::Image, bytes_of(&h), &px, cdr);
    stamp.capture_time_ns
}

fn disk_mbps(dir: &Path, frame: &[u8], frames: usize) -> Result<f64> {
    let path = dir.join("reference.bin");
    let start = Instant::now();
    let mut f = std::fs::File::create(&path)?;
    for _ in 0..frames {
        f.write_all(frame)?;
    }
    f.sync_all()?;
    let mbps = (frame.len() * frames) as f64 / 1e6 / start.elapsed().as_secs_f64();
    std::fs::remove_file(&path)?;
    Ok(mbps)
}

/// Where the benchmark's frames come from.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum FrameSource {
    /// A smooth pattern with 3 bits of noise per channel, `--width` × `--height`: compression cannot cheat.
    Noise,
    /// The synthetic camera's façade (a55-two-strips at full size, 4912 × 3264), as a run records it: what the
    /// PNG ratio is on the presets.
    Facade,
}

/// Frames of the source, as RGB pixels; a façade renders a few distinct frames, cycled.
pub(crate) fn source_frames(source: FrameSource, width: u32, height: u32) -> Result<(u32, u32, Vec<Vec<u8>>)> {
    Ok(match source {
        FrameSource::Noise => (width, height, vec![frame(width, height, 1)]),
        FrameSource::Facade => {
            let syn = lineflow_synthetic::Synthetic::new("a55-two-strips", 1.0, 1)?;
            let (cam, n) = (*syn.camera(), syn.poses().len());
            let rendered = (0..4).map(|k| syn.render(k * n / 4)).collect();
            (cam.width, cam.height, rendered)
        }
    })
}

/// Runs the benchmark.
pub fn bench_record(frames: usize, source: FrameSource, width: u32, height: u32, preview_max_px: u32) -> Result<ExitCode> {
    let dir = tempfile::Builder::new()
        .prefix("lineflow-bench-record")
        .tempdir_in(std::env::temp_dir())?;
    let (width, height, distinct) = source_frames(source, width, height)?;
    let pixels = &distinct[0];
    let frame_mb = pixels.len() as f64 / 1e6;
    eprintln!(
        "{frames} RGB frames of {width}x{height} ({source:?}, {frame_mb:.1} MB each, {:.0} MB in all), in {}",
        frame_mb * frames as f64,
        dir.path().display()
    );

    // The source recording the player publishes from.
    let source = dir.path().join("source.mcap");
    let mut w = McapWriter::create(&source, Compression::None)?;
    w.add_topic("images", MessageKind::Image)?;
    let mut cdr = Vec::new();
    for k in 0..frames {
        let capture_time_ns = frame_cdr(k, width, height, &distinct[k % distinct.len()], &mut cdr);
        w.write("images", k as u64, capture_time_ns, &cdr)?;
    }
    w.finish()?;

    let reference = disk_mbps(dir.path(), pixels, frames)?;
    println!("disk reference (write + fsync of the same bytes): {reference:.0} MB/s");
    println!(
        "{:<12} {:>9} {:>10} {:>10} {:>12} {:>13} {:>9} {:>10}",
        "recording", "MB/s", "vs disk", "vs target", "recorder cpu", "cpu s per GB", "dropped", "vs raw size"
    );
    let mut all_met = true;
    let mut raw_size = None;
    // (name, [record] settings, its throughput target): raw chunks as shipped, LZ4 for comparison, PNG images.
    let cases = [
        ("none", "compression = \"none\"", TARGET_MBPS),
        ("lz4", "compression = \"lz4\"", 0.0),
        ("png", "images = \"png\"", TARGET_PNG_MBPS),
    ];
    for (name, settings, target) in cases {
        let out = dir.path().join(format!("run-{name}"));
        let graph = dir.path().join(format!("bench-{name}.toml"));
        std::fs::write(
            &graph,
            format!(
                "[graph]\nname = \"bench-record\"\n[record]\n{settings}\npreview_max_px = {preview_max_px}\n\
                 [[node]]\nname = \"player\"\nstage = \"play\"\nparams = {{ recording = \"{}\", rate = 0 }}\n\
                 [[edge]]\ntopic = \"images\"\ntype = \"Image\"\nfrom = \"player\"\nto = []\nmax_payload_bytes = {}\n",
                source.display(),
                pixels.len()
            ),
        )?;
        let g = launch::load(&graph, &[], &Resolver::beside_current_exe())?;
        let outcome = supervisor::run(
            &g,
            &RunOptions {
                out: out.clone(),
                expected_frames: None,
                progress: false,
                echo_logs: true,
                node_log_level: None,
                connect_timeout: None,
                chaos: Vec::new(),
            },
        )?;
        let ended = now_ns();
        if let Some(e) = &outcome.error {
            bail!("{name}: the run failed: {e}");
        }
        let rec = Recording::open(&out.join("recording.mcap"))?;
        let first = rec
            .summary
            .as_ref()
            .and_then(|s| s.stats.as_ref())
            .map(|s| s.message_start_time)
            .context("recording without statistics")?;
        let end = rec.metadata.get(META_END).context("no end record")?;
        let complete = rec.is_complete();
        let dropped: u64 = end.get("drops_total").and_then(|v| v.parse().ok()).unwrap_or(u64::MAX);
        let seconds = (ended.saturating_sub(first)) as f64 * 1e-9;
        let mbps = frame_mb * frames as f64 / seconds;
        let recorder = outcome.nodes.iter().find(|n| n.name == launch::RECORDER).context("no recorder")?;
        let cpu = recorder.cpu.as_secs_f64();
        let size = std::fs::metadata(out.join("recording.mcap"))?.len() as f64;
        let raw = *raw_size.get_or_insert(size);
        println!(
            "{name:<12} {mbps:>9.0} {:>9.2}x {:>9} {:>11.0}% {:>13.2} {:>9} {:>9.2}x",
            mbps / reference,
            if target > 0.0 {
                format!("{:.2}x", mbps / target)
            } else {
                "-".into()
            },
            100.0 * cpu / seconds,
            cpu / (frame_mb * frames as f64 / 1e3),
            if complete {
                dropped.to_string()
            } else {
                format!("INCOMPLETE ({dropped})")
            },
            raw / size
        );
        all_met &= complete && dropped == 0 && mbps >= target;
    }
    println!(
        "targets: raw >= {TARGET_MBPS:.0} MB/s, png >= {TARGET_PNG_MBPS:.0} MB/s of raw input, nothing dropped: {} (the disk \
         reference bounds raw)",
        if all_met { "met" } else { "NOT met" }
    );
    Ok(ExitCode::SUCCESS)
}
