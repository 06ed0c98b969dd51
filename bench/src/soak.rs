//! `lineflow bench soak`: the synthetic camera streaming at a steady rate (its strip repeated, `capture.repeat`)
//! through a whole graph for N minutes, every node's resident memory, shared memory and open files and the
//! recording's size sampled into `soak.csv` and drawn into `soak.svg`; then, against #34's targets, each node's
//! memory growth after the warm-up, the drops on the (lossless) edges, and a frame's latency (capture stamp to the
//! recorder's receipt of the frame's last per-frame message) at the end against the start.
use std::fmt::Write as _;
use std::io::Write as _;
use std::path::{Path, PathBuf};
use std::process::{Command, ExitCode, Stdio};
use std::time::{Duration, Instant};

use anyhow::{bail, Context, Result};
use lineflow_recordings::Recording;

use crate::processes::{node_processes, usage, Usage};

/// What to soak and how (`lineflow bench soak`'s arguments).
#[derive(Debug, clap::Args)]
pub struct Soak {
    /// Minutes of streaming.
    #[arg(long, default_value_t = 60.0)]
    pub minutes: f64,
    /// The graph.
    #[arg(long, default_value = "launch/demo.toml")]
    pub graph: PathBuf,
    /// Parameter overrides (NODE.PARAM=VALUE), as for `lineflow run`.
    #[arg(long = "set", value_name = "NODE.PARAM=VALUE")]
    pub sets: Vec<String>,
    /// Image scale of the synthetic camera.
    #[arg(long, default_value_t = 0.5)]
    pub scale: f64,
    /// Frames per second.
    #[arg(long, default_value_t = 1.0)]
    pub fps: f64,
    /// Seconds between samples.
    #[arg(long, default_value_t = 5.0)]
    pub every: f64,
    /// Folder for the run, soak.csv and soak.svg.
    #[arg(long, default_value = "soak")]
    pub out: PathBuf,
}

/// Share of the run treated as warm-up (at least a minute, at most half): stages fill their windows and buffers.
const WARM_UP_SHARE: f64 = 0.2;

/// One sample of one node.
struct Row {
    t: f64,
    node: String,
    usage: Usage,
}

pub fn bench_soak(s: &Soak) -> Result<ExitCode> {
    let frames = (s.minutes * 60.0 * s.fps).ceil().max(2.0) as u64;
    std::fs::create_dir_all(&s.out).with_context(|| format!("cannot create {}", s.out.display()))?;
    let run_out = s.out.join("run");
    let mut cmd = Command::new(std::env::current_exe().context("cannot find the lineflow executable")?);
    cmd.arg("run").arg(&s.graph).arg("-q");
    for set in [
        "capture.repeat=true".to_owned(),
        format!("capture.frames={frames}"),
        format!("capture.fps={}", s.fps),
        format!("capture.scale={}", s.scale),
        // Stamps from the clock: a message's recorded latency is then its receipt time less its frame's stamp.
        "capture.use_clock=true".to_owned(),
        // An hour of raw frames at scale 0.5 would fill a laptop's disk.
        "record.images=\"png\"".to_owned(),
    ]
    .iter()
    .chain(&s.sets)
    {
        cmd.args(["--set", set]);
    }
    let log = std::fs::File::create(s.out.join("run.log"))?;
    cmd.arg("--out")
        .arg(&run_out)
        .stdin(Stdio::null())
        .stdout(log.try_clone()?)
        .stderr(log);
    println!(
        "{}: {frames} frames at {} frames/s, scale {}, sampled every {} s, into {}",
        s.graph.display(),
        s.fps,
        s.scale,
        s.every,
        s.out.display()
    );
    let start = Instant::now();
    let mut child = cmd.spawn().context("cannot start the run")?;
    // The stream's length and time to start the graph: a graph still working then is slower than the stream, and
    // is interrupted (its recorder keeps what it received); then it has a minute to end.
    let stream_end = Duration::from_secs_f64(s.minutes * 60.0 + 120.0);
    let mut interrupted: Option<Instant> = None;
    let recording = run_out.join("recording.mcap");
    let mut rows: Vec<Row> = Vec::new();
    let mut csv = std::io::BufWriter::new(std::fs::File::create(s.out.join("soak.csv"))?);
    writeln!(csv, "t_s,node,rss_kb,shmem_kb,open_files,recording_bytes")?;
    let mut minutes_shown = 0;
    let status = loop {
        if let Some(status) = child.try_wait()? {
            break Some(status);
        }
        match interrupted {
            None if start.elapsed() > stream_end => {
                // SAFETY: a signal to the run this function started.
                unsafe { libc::kill(child.id() as i32, libc::SIGINT) };
                interrupted = Some(Instant::now());
            }
            Some(at) if at.elapsed() > Duration::from_secs(60) => {
                let _ = child.kill();
                let _ = child.wait();
                break None;
            }
            Some(_) => {
                std::thread::sleep(Duration::from_millis(100));
                continue;
            }
            None => {}
        }
        let t = start.elapsed().as_secs_f64();
        let recorded = std::fs::metadata(&recording).map_or(0, |m| m.len());
        for (node, pid) in node_processes(child.id()) {
            let Some(u) = usage(pid) else { continue };
            writeln!(csv, "{t:.1},{node},{},{},{},{recorded}", u.rss_kb, u.shmem_kb, u.open_files)?;
            rows.push(Row { t, node, usage: u });
        }
        csv.flush()?;
        let minute = (t / 60.0) as u64;
        if minute > minutes_shown {
            minutes_shown = minute;
            eprintln!("{minute} of {:.0} min: {} MB recorded", s.minutes, recorded >> 20);
        }
        std::thread::sleep(Duration::from_secs_f64(s.every));
    };
    let wall = interrupted.map_or_else(|| start.elapsed(), |at| at - start).as_secs_f64();
    let log = s.out.join("run.log");
    match (status, interrupted) {
        (None, _) => bail!("the run did not end within a minute of its interrupt (see {})", log.display()),
        (Some(_), Some(_)) => println!(
            "\nthe graph had not finished {:.0} s after the stream's end: it works slower than the stream; interrupted",
            stream_end.as_secs_f64() - s.minutes * 60.0
        ),
        (Some(st), None) if !st.success() => bail!("the run failed ({st}); see {}", log.display()),
        (Some(_), None) => {}
    }
    std::fs::write(s.out.join("soak.svg"), plot(&rows, wall))?;

    let warm = (wall * WARM_UP_SHARE).clamp(60.0_f64.min(wall / 2.0), wall / 2.0);
    println!("\nwarm-up: the first {warm:.0} s of {wall:.0} s; growth: the mean of the last tenth against the first sample after it\n");
    // RSS counts the shared-memory pages a node has touched; the iceoryx2 segments are fixed pools, touched as the
    // edges cycle through them, so the node's own (private) memory is shown beside it: the state it keeps.
    println!(
        "| node | RSS after warm-up (MB) | RSS at the end (MB) | growth | private memory (MB) | private growth | shared memory (MB) | open files | target ≤ 5 % |"
    );
    println!("|---|---|---|---|---|---|---|---|---|");
    for name in node_names(&rows) {
        let mine: Vec<&Row> = rows.iter().filter(|r| r.node == name).collect();
        // A node that finished early is judged on its own last tenth.
        let after: Vec<&Row> = mine.into_iter().filter(|r| r.t >= warm).collect();
        let Some(first) = after.first() else { continue };
        let tail = &after[after.len() - (after.len() / 10).max(1)..];
        let mean = |kb: fn(&Usage) -> u64| tail.iter().map(|r| kb(&r.usage) as f64).sum::<f64>() / tail.len() as f64;
        let (rss, private) = (|u: &Usage| u.rss_kb, |u: &Usage| u.rss_kb.saturating_sub(u.shmem_kb));
        let (end, end_private) = (mean(rss), mean(private));
        let growth = (end / rss(&first.usage).max(1) as f64 - 1.0) * 100.0;
        let private_growth = (end_private / private(&first.usage).max(1) as f64 - 1.0) * 100.0;
        let last = after.last().map_or_else(Usage::default, |r| r.usage);
        println!(
            "| {name} | {:.1} | {:.1} | {growth:+.1} % | {:.1} → {:.1} | {private_growth:+.1} % | {:.1} → {:.1} | {} → {} | {} |",
            first.usage.rss_kb as f64 / 1024.0,
            end / 1024.0,
            private(&first.usage) as f64 / 1024.0,
            end_private / 1024.0,
            first.usage.shmem_kb as f64 / 1024.0,
            last.shmem_kb as f64 / 1024.0,
            first.usage.open_files,
            last.open_files,
            if growth <= 5.0 { "met" } else { "MISSED" }
        );
    }

    let summary: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(run_out.join("summary.json"))?)?;
    let drops: u64 = summary["nodes"]
        .as_array()
        .map_or(0, |n| n.iter().filter_map(|n| n["drops"].as_u64()).sum());
    // Gaps in the frame numbers a node received; a stage that publishes snapshots (orientation's poses) leaves
    // gaps by design when frames come faster than it works, so they are shown, not judged.
    let missed: Vec<String> = summary["nodes"].as_array().map_or_else(Vec::new, |nodes| {
        nodes
            .iter()
            .filter(|n| n["missed"].as_u64().unwrap_or(0) > 0)
            .map(|n| format!("{} {}", n["name"].as_str().unwrap_or("?"), n["missed"]))
            .collect()
    });
    println!(
        "\ndrops on the edges: {drops} (target 0); frames missed on inputs: {}",
        if missed.is_empty() { "none".to_owned() } else { missed.join(", ") }
    );

    // By capture time: a graph slower than the stream has taken fewer frames than the stream offered.
    let latency = frame_latencies(&recording, frames)?;
    let first_stamp = latency.first().map_or(0, |(stamp, _)| *stamp);
    let after: Vec<f64> = latency
        .iter()
        .filter(|(stamp, _)| stamp.saturating_sub(first_stamp) as f64 * 1e-9 >= warm)
        .map(|(_, l)| *l)
        .collect();
    let after = if after.len() >= 2 {
        after
    } else {
        latency.iter().map(|(_, l)| *l).collect()
    };
    let tenth = (after.len() / 10).max(1);
    let (early, late) = (
        median(&after[..tenth.min(after.len())]),
        median(&after[after.len().saturating_sub(tenth)..]),
    );
    println!(
        "frame latency (capture to the recorder's receipt of its last per-frame message), median over a tenth of the \
         {} frames taken after the warm-up: {:.0} ms first, {:.0} ms last: {:+.1} % (target within 10 %)",
        after.len(),
        early * 1e3,
        late * 1e3,
        (late / early - 1.0) * 100.0
    );
    println!(
        "\nsamples: {} (soak.csv), plot: soak.svg, run: {}",
        s.out.join("soak.csv").display(),
        run_out.display()
    );
    Ok(if drops == 0 { ExitCode::SUCCESS } else { ExitCode::FAILURE })
}

/// Each frame's capture stamp (ns) and latency (s), by stamp: the latest of the per-frame topics' (those with a
/// message for half the frames taken or more) first receipts of a message stamped with the frame's capture time,
/// less that time.
fn frame_latencies(recording: &Path, frames: u64) -> Result<Vec<(u64, f64)>> {
    let rec = Recording::open(recording)?;
    let mut by_topic: std::collections::BTreeMap<String, Vec<(u64, u64)>> = Default::default();
    rec.for_each_message(|m| {
        if m.kind.is_some() && !m.view && !m.topic.starts_with("gt/") {
            by_topic.entry(m.topic).or_default().push((m.publish_time, m.log_time));
        }
        Ok(())
    })?;
    let taken = by_topic.get("images").map_or(frames, |v| v.len() as u64);
    let mut latest: std::collections::BTreeMap<u64, u64> = Default::default();
    for messages in by_topic.values().filter(|v| v.len() as u64 * 2 >= taken) {
        // A topic's first message of a frame: revisions published later (a final re-estimate) are not its latency.
        let mut first: std::collections::BTreeMap<u64, u64> = Default::default();
        for &(stamp, received) in messages {
            let e = first.entry(stamp).or_insert(received);
            *e = (*e).min(received);
        }
        for (stamp, received) in first {
            let e = latest.entry(stamp).or_insert(received);
            *e = (*e).max(received);
        }
    }
    Ok(latest
        .iter()
        .map(|(stamp, received)| (*stamp, received.saturating_sub(*stamp) as f64 * 1e-9))
        .collect())
}

fn median(v: &[f64]) -> f64 {
    let mut v = v.to_vec();
    v.sort_by(f64::total_cmp);
    v.get(v.len() / 2).copied().unwrap_or(f64::NAN)
}

/// The nodes sampled, by name.
fn node_names(rows: &[Row]) -> Vec<&str> {
    let mut names: Vec<&str> = rows.iter().map(|r| r.node.as_str()).collect();
    names.sort_unstable();
    names.dedup();
    names
}

/// Resident memory of every node against time, one line each.
fn plot(rows: &[Row], wall: f64) -> String {
    let (w, h, left, bottom) = (900.0, 480.0, 60.0, 40.0);
    let top = rows.iter().map(|r| r.usage.rss_kb).max().unwrap_or(1) as f64 / 1024.0 * 1.1;
    let x = |t: f64| left + t / wall.max(1.0) * (w - left - 160.0);
    let y = |mb: f64| h - bottom - mb / top.max(1.0) * (h - bottom - 20.0);
    let mut svg = format!(
        "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"{w}\" height=\"{h}\" font-family=\"sans-serif\" font-size=\"12\">\n\
         <rect width=\"100%\" height=\"100%\" fill=\"white\"/>\n\
         <text x=\"{left}\" y=\"14\">resident memory per node (MB) against time (s)</text>\n\
         <line x1=\"{left}\" y1=\"{}\" x2=\"{}\" y2=\"{}\" stroke=\"black\"/>\n<line x1=\"{left}\" y1=\"20\" x2=\"{left}\" y2=\"{}\" stroke=\"black\"/>\n",
        h - bottom,
        x(wall),
        h - bottom,
        h - bottom
    );
    for k in 0..=4 {
        let (t, mb) = (wall * k as f64 / 4.0, top * k as f64 / 4.0);
        let _ = writeln!(
            svg,
            "<text x=\"{:.0}\" y=\"{}\" text-anchor=\"middle\">{t:.0}</text>",
            x(t),
            h - bottom + 16.0
        );
        let _ = writeln!(
            svg,
            "<text x=\"{}\" y=\"{:.0}\" text-anchor=\"end\">{mb:.0}</text>",
            left - 4.0,
            y(mb) + 4.0
        );
    }
    let names = node_names(rows);
    for (k, name) in names.iter().enumerate() {
        let colour = format!("hsl({},70%,40%)", k * 360 / names.len().max(1));
        let points: Vec<String> = rows
            .iter()
            .filter(|r| r.node == *name)
            .map(|r| format!("{:.1},{:.1}", x(r.t), y(r.usage.rss_kb as f64 / 1024.0)))
            .collect();
        let _ = writeln!(
            svg,
            "<polyline fill=\"none\" stroke=\"{colour}\" stroke-width=\"1.5\" points=\"{}\"/>\n<text x=\"{}\" y=\"{}\" fill=\"{colour}\">{name}</text>",
            points.join(" "),
            w - 150.0,
            30.0 + 16.0 * k as f64
        );
    }
    svg + "</svg>\n"
}
