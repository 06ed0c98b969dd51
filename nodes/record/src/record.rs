//! `lineflow-record`: the recorder the supervisor adds to every graph. It subscribes to every topic and writes one
//! MCAP file per run (`docs/recording.md`): messages are CDR-encoded as they arrive and handed to a writer thread,
//! so that disk I/O never holds a sample in shared memory. On end-of-stream on every topic, or on SIGINT/SIGTERM,
//! it writes every node's counters and finishes the file.
use std::collections::BTreeMap;
use std::time::{Duration, Instant};

use anyhow::Result;
use lineflow_messages::schema::encode;
use lineflow_messages::{MessageKind, NodeStatus};
use lineflow_recordings::image_codec::{ImageFormat, DEFAULT_JPEG_QUALITY};
use lineflow_recordings::views::ViewRenderer;
use lineflow_recordings::{now_ns, run_metadata, Compression, McapWriter, SplitLimits, META_END, META_RUN};
use lineflow_runtime::launch::Graph;
use lineflow_runtime::tap::{all_ended, subscribe_all, update_ended, Topic};
use lineflow_runtime::{Flow, NodeContext, RunEnd};
use pipeline::{Item, Pipeline};

mod pipeline;

#[derive(serde::Deserialize)]
#[serde(deny_unknown_fields)]
struct Params {
    /// Recording file's name in the run's output folder (no folder: nothing is written outside it).
    #[serde(default = "default_file")]
    file: String,
    /// Chunk compression: none, lz4, zstd; by default none for raw images (they barely compress and it would
    /// halve the recorder's throughput), zstd when the images are compressed already (the rest then dominates).
    #[serde(default)]
    compression: Option<Compression>,
    /// How image topics are recorded: raw, png (lossless), jpeg.
    #[serde(default)]
    images: ImageFormat,
    /// JPEG quality of `images = "jpeg"`, 1–100.
    #[serde(default = "default_jpeg_quality")]
    jpeg_quality: u8,
    /// Move on to the next file once one holds this many MB of messages (0: one file).
    #[serde(default)]
    max_file_mb: f64,
    /// Move on to the next file once one spans this many seconds (0: one file).
    #[serde(default)]
    max_file_seconds: f64,
    /// Longest side of the image previews for viewers; 0 turns previews off.
    #[serde(default = "default_preview")]
    preview_max_px: u32,
    /// Memory for messages waiting to be written, MiB.
    #[serde(default = "default_queue_mib")]
    queue_mib: u64,
}
fn default_file() -> String {
    "recording.mcap".into()
}
fn default_jpeg_quality() -> u8 {
    DEFAULT_JPEG_QUALITY
}
fn default_preview() -> u32 {
    1280
}
fn default_queue_mib() -> u64 {
    1024
}

fn main() -> std::process::ExitCode {
    lineflow_runtime::run_node(body)
}

fn body() -> Result<()> {
    let ctx = NodeContext::from_env()?;
    let p: Params = ctx.params()?;
    lineflow_runtime::params::file_name("file", &p.file)?;
    if !(1..=100).contains(&p.jpeg_quality) {
        anyhow::bail!("record.jpeg_quality must be 1 to 100, got {}", p.jpeg_quality);
    }
    for (key, v) in [("max_file_mb", p.max_file_mb), ("max_file_seconds", p.max_file_seconds)] {
        if !(v.is_finite() && v >= 0.0) {
            anyhow::bail!("record.{key} must be 0 (one file) or positive, got {v}");
        }
    }
    let graph = ctx.graph().clone();
    let mut topics = subscribe_all(&ctx)?;
    let mut status = ctx.watch_status()?;
    if lineflow_runtime::env::RunEnv::describe_requested() {
        return ctx.connect();
    }
    // The file exists before the graph starts: an unwritable path fails the run before any frame is lost.
    let path = ctx.out_dir().join(&p.file);
    let compression = p
        .compression
        .unwrap_or(lineflow_recordings::image_codec::chunk_compression(p.images));
    let mut writer = McapWriter::create(&path, compression)?;
    writer.split(SplitLimits {
        max_bytes: (p.max_file_mb * 1e6) as u64,
        max_duration_ns: (p.max_file_seconds * 1e9) as u64,
    })?;
    let run_id = std::env::var(lineflow_runtime::env::RUN_ID).unwrap_or_default();
    writer.metadata(META_RUN, run_metadata(&graph, &run_id))?;
    let renderer = ViewRenderer::new(p.preview_max_px).with_compressed_previews(p.images != ImageFormat::Raw);
    for t in &topics {
        match t.kind {
            MessageKind::Image => writer.add_image_topic(&t.name, p.images)?,
            kind => writer.add_topic(&t.name, kind)?,
        }
        for (suffix, view) in renderer.views(t.kind) {
            writer.add_view(&format!("{}/{suffix}", t.name), view)?;
        }
    }
    // Bounded by memory: as many of the largest messages as fit in the queue budget.
    let largest = graph.edges.iter().map(|e| e.max_payload_bytes).max().unwrap_or(1).max(1);
    let capacity = ((p.queue_mib << 20) / largest).clamp(4, 4096) as usize;
    let (give_back, pool) = crossbeam::channel::bounded::<Vec<u8>>(capacity);
    let names: Vec<(String, MessageKind)> = topics.iter().map(|t| (t.name.clone(), t.kind)).collect();
    let images = (p.images != ImageFormat::Raw).then_some((p.images, p.jpeg_quality));
    let mut pipeline = Pipeline::start(writer, names, renderer, images, give_back, capacity)?;
    ctx.connect()?;
    tracing::info!("recording {} topics to {}", topics.len(), path.display());

    let mut taken = Vec::new();
    let ended = ctx.run(|| {
        // Status first: what a finished publisher sent is already waiting, and the drain below takes it.
        update_ended(&mut topics, status.as_mut());
        for (i, t) in topics.iter_mut().enumerate() {
            let kind = t.kind;
            t.messages += t.tap.drain(&mut |publish_time, header, payload| {
                // Buffers come back from the writer thread: large images reuse memory already faulted in.
                let mut cdr = pool.try_recv().unwrap_or_default();
                encode(kind, header, payload, &mut cdr);
                taken.push(Item {
                    topic: i,
                    log_time: now_ns(),
                    publish_time,
                    cdr,
                });
                Ok(())
            })? as u64;
            // Handed on once the samples are released: a full queue never holds shared memory.
            for item in taken.drain(..) {
                pipeline.send(item)?;
            }
        }
        Ok(if all_ended(&topics) { Flow::Stop } else { Flow::Continue })
    });
    update_ended(&mut topics, status.as_mut());
    let complete = matches!(ended, Ok(RunEnd::Finished)) && topics.iter().all(|t| t.ended);
    let reason = match &ended {
        Ok(RunEnd::Finished) => "end-of-stream on every topic".to_owned(),
        Ok(RunEnd::Interrupted) => "interrupted (SIGINT/SIGTERM)".to_owned(),
        Err(e) => format!("recorder failed: {e:#}"),
    };
    // Counters of the other nodes: wait briefly for their final reports (sent right after their end-of-stream).
    let counters = status
        .as_mut()
        .map(|s| final_counters(s, &graph, ctx.name(), complete))
        .unwrap_or_default();
    let mut writer = pipeline.finish()?;
    writer.metadata(META_END, end_metadata(&graph, &topics, &counters, complete, &reason))?;
    let (messages, bytes, files) = (writer.messages, writer.bytes, writer.files().len());
    writer.finish()?;
    tracing::info!(
        "{} messages, {:.1} MB in {}{} ({})",
        messages,
        bytes as f64 / 1e6,
        path.display(),
        if files > 1 {
            format!(" and {} more files", files - 1)
        } else {
            String::new()
        },
        if complete { "complete" } else { &reason }
    );
    ctx.finish();
    ended.map(|_| ())
}

fn final_counters(status: &mut lineflow_runtime::StatusWatch, graph: &Graph, me: &str, wait: bool) -> BTreeMap<u32, NodeStatus> {
    let deadline = Instant::now() + Duration::from_secs(2);
    loop {
        let latest = status.poll();
        let all_finished = graph
            .nodes
            .iter()
            .filter(|n| n.name != me)
            .all(|n| latest.get(&n.index).is_some_and(|s| s.flags & NodeStatus::FINISHED != 0));
        if all_finished || !wait || Instant::now() > deadline {
            return latest.clone();
        }
        std::thread::sleep(Duration::from_millis(20));
    }
}

fn end_metadata(
    graph: &Graph,
    topics: &[Topic],
    counters: &BTreeMap<u32, NodeStatus>,
    ended: bool,
    reason: &str,
) -> BTreeMap<String, String> {
    let mut m = BTreeMap::from([("ended_unix_ns".to_owned(), now_ns().to_string())]);
    for t in topics {
        m.insert(format!("topic.{}.messages", t.name), t.messages.to_string());
        m.insert(format!("topic.{}.ended", t.name), t.ended.to_string());
    }
    let mut lost = 0;
    for n in &graph.nodes {
        let Some(s) = counters.get(&n.index) else {
            continue;
        };
        for (k, v) in [("in", s.msgs_in), ("out", s.msgs_out), ("drops", s.drops), ("missed", s.missed)] {
            m.insert(format!("node.{}.{k}", n.name), v.to_string());
        }
        lost += s.drops + s.missed;
    }
    m.insert("drops_total".to_owned(), lost.to_string());
    let complete = ended && lost == 0;
    let reason = if ended && lost > 0 {
        format!("{lost} messages dropped or missed")
    } else {
        reason.to_owned()
    };
    m.insert("complete".to_owned(), complete.to_string());
    m.insert("reason".to_owned(), reason);
    m
}
