//! `lineflow bench reader`: `info`, `info --verify` and `export` of one topic on a recording larger than the reader
//! could hold, each a child `lineflow` process whose wall time and peak RSS are measured, beside a plain sequential
//! read of the same file in the same run.
//!
//! The recording holds 12 MP RGB frames (as the recorder writes them, in 4 MB chunks) and a thumbnail per frame on
//! a second topic, the one exported.
use std::io::Read;
use std::path::{Path, PathBuf};
use std::process::{Command, ExitCode, Stdio};
use std::time::Instant;

use anyhow::{bail, Context, Result};
use lineflow_messages::MessageKind;
use lineflow_recordings::{Compression, McapWriter};

use crate::record::{frame, frame_cdr};

/// `info` on the file: at most this long (#32)…
const INFO_TARGET_S: f64 = 1.0;
/// …and every reading command in at most this much memory.
const RSS_TARGET_MB: f64 = 100.0;

const WIDTH: u32 = 4288;
const HEIGHT: u32 = 2848;

/// A child `lineflow` process's wall time, peak resident memory and whether it succeeded.
#[derive(Debug, Clone, Copy)]
struct Measured {
    seconds: f64,
    peak_rss_mb: f64,
    success: bool,
}

/// Set to a file name, `lineflow` writes its peak resident memory there as it exits ([`report_peak_rss`]).
pub const PEAK_RSS_ENV: &str = "LINEFLOW_PEAK_RSS_FILE";

/// Writes this process's peak resident set (`VmHWM`, kB) to the file [`PEAK_RSS_ENV`] names, if it is set.
///
/// The child's own figure, because the `ru_maxrss` that `wait4` reports carries the parent's peak across
/// `exec` on Linux (it read 118 MB for every command here, the bench's own peak while writing the file).
pub fn report_peak_rss() {
    let Some(file) = std::env::var_os(PEAK_RSS_ENV) else {
        return;
    };
    let status = std::fs::read_to_string("/proc/self/status").unwrap_or_default();
    if let Some(kb) = status.lines().find_map(|l| l.strip_prefix("VmHWM:")) {
        let _ = std::fs::write(file, kb.trim().trim_end_matches("kB").trim());
    }
}

fn measure(args: &[&str], scratch: &Path) -> Result<Measured> {
    let exe = std::env::current_exe().context("cannot find the lineflow executable")?;
    let report = scratch.join("peak-rss-kb");
    let _ = std::fs::remove_file(&report);
    let start = Instant::now();
    let status = Command::new(exe)
        .args(args)
        .env(PEAK_RSS_ENV, &report)
        .stdout(Stdio::null())
        .status()
        .with_context(|| format!("cannot start lineflow {}", args.join(" ")))?;
    let seconds = start.elapsed().as_secs_f64();
    let kb: f64 = std::fs::read_to_string(&report)
        .ok()
        .and_then(|s| s.trim().parse().ok())
        .with_context(|| format!("lineflow {} reported no peak memory", args.join(" ")))?;
    Ok(Measured {
        seconds,
        peak_rss_mb: kb * 1024.0 / 1e6,
        success: status.success(),
    })
}

fn write_recording(path: &Path, frames: usize) -> Result<()> {
    let pixels = frame(WIDTH, HEIGHT, 1);
    let thumb = frame(64, 43, 2);
    let mut w = McapWriter::create(path, Compression::None)?;
    w.add_topic("images", MessageKind::Image)?;
    w.add_topic("thumbs", MessageKind::Image)?;
    let mut cdr = Vec::new();
    for k in 0..frames {
        let t = frame_cdr(k, WIDTH, HEIGHT, &pixels, &mut cdr);
        w.write("images", t, t, &cdr)?;
        let t = frame_cdr(k, 64, 43, &thumb, &mut cdr);
        w.write("thumbs", t, t, &cdr)?;
        if k % 25 == 24 {
            eprintln!("  {:.1} GB written", w.bytes as f64 / 1e9);
        }
    }
    w.finish()
}

fn plain_read_s(path: &Path) -> Result<f64> {
    let start = Instant::now();
    let mut f = std::fs::File::open(path)?;
    let mut buf = vec![0u8; 1 << 20];
    while f.read(&mut buf)? > 0 {}
    Ok(start.elapsed().as_secs_f64())
}

/// Runs the benchmark on a recording of about `gb` GB written into `dir` (a temporary folder by default).
pub fn bench_reader(gb: f64, dir: Option<PathBuf>, json: bool) -> Result<ExitCode> {
    if !gb.is_finite() || gb <= 0.0 {
        bail!("--gb must be positive");
    }
    let temp;
    let dir = match dir {
        Some(d) => {
            std::fs::create_dir_all(&d).with_context(|| format!("cannot create {}", d.display()))?;
            d
        }
        None => {
            temp = tempfile::Builder::new().prefix("lineflow-bench-reader").tempdir()?;
            temp.path().to_owned()
        }
    };
    let path = dir.join("large.mcap");
    let frame_bytes = WIDTH as f64 * HEIGHT as f64 * 3.0;
    let frames = ((gb * 1e9 / frame_bytes).ceil() as usize).max(1);
    eprintln!("writing {frames} frames of {WIDTH}x{HEIGHT} into {}", path.display());
    let start = Instant::now();
    write_recording(&path, frames)?;
    let size_mb = std::fs::metadata(&path)?.len() as f64 / 1e6;
    let written_s = start.elapsed().as_secs_f64();
    let file = path.to_str().context("a temporary path that is not UTF-8")?;
    let out = dir.join("export");
    let out_str = out.to_str().context("a temporary path that is not UTF-8")?;

    let reference = plain_read_s(&path)?;
    let cases = [
        ("info", measure(&["info", file], &dir)?),
        ("info --verify", measure(&["info", file, "--verify"], &dir)?),
        (
            "export --topic thumbs",
            measure(&["export", file, "--topic", "thumbs", "--out", out_str], &dir)?,
        ),
    ];
    let exported = std::fs::read_dir(&out).map(|d| d.count()).unwrap_or(0);
    let info = cases[0].1;
    let met = cases.iter().all(|(_, m)| m.success && m.peak_rss_mb <= RSS_TARGET_MB) && info.seconds <= INFO_TARGET_S;
    if json {
        let rows: Vec<_> = cases
            .iter()
            .map(|(name, m)| serde_json::json!({"command": name, "seconds": m.seconds, "peak_rss_mb": m.peak_rss_mb, "success": m.success}))
            .collect();
        let doc = serde_json::json!({
            "file_mb": size_mb, "frames": frames, "plain_read_s": reference, "exported_files": exported,
            "cases": rows, "targets_met": met,
        });
        println!("{doc}");
    } else {
        println!(
            "recording: {size_mb:.0} MB, {frames} frames + {frames} thumbnails, written in {written_s:.1} s ({:.0} MB/s)",
            size_mb / written_s
        );
        println!(
            "reference: a plain sequential read of the file, {reference:.2} s ({:.0} MB/s)",
            size_mb / reference
        );
        println!(
            "{:<24} {:>9} {:>13} {:>12} {:>10}",
            "command", "seconds", "vs plain read", "peak RSS MB", "vs 100 MB"
        );
        for (name, m) in &cases {
            println!(
                "{name:<24} {:>9.3} {:>12.2}x {:>12.1} {:>9.2}x{}",
                m.seconds,
                m.seconds / reference,
                m.peak_rss_mb,
                m.peak_rss_mb / RSS_TARGET_MB,
                if m.success { "" } else { "  FAILED" }
            );
        }
        println!(
            "targets: info ≤ {INFO_TARGET_S} s ({:.3} s), every command ≤ {RSS_TARGET_MB} MB: {}; {exported} thumbnails exported",
            info.seconds,
            if met { "met" } else { "NOT met" }
        );
    }
    Ok(if met { ExitCode::SUCCESS } else { ExitCode::FAILURE })
}
