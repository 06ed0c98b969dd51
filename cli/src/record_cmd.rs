//! `lineflow record`: attaches to a running run as one more subscriber and records chosen topics into a new MCAP
//! file (the format of the recorder node, `docs/recording.md`), until the run ends, every chosen topic has sent
//! end-of-stream, or Ctrl-C.
use std::collections::BTreeMap;
use std::path::Path;
use std::process::ExitCode;
use std::time::{Duration, Instant};

use anyhow::{anyhow, bail, Result};
use iceoryx2::port::subscriber::Subscriber;
use iceoryx2::port::update_connections::UpdateConnections;
use iceoryx2::prelude::*;
use lineflow_messages::schema::{bytes_of, encode, slice_bytes};
use lineflow_messages::{with_kind, Message, MessageKind};
use lineflow_recordings::image_codec::{ImageCompressor, ImageFormat, DEFAULT_JPEG_QUALITY};
use lineflow_recordings::{now_ns, run_metadata, McapWriter, META_END, META_RUN};
use lineflow_runtime::launch::EdgeSpec;
use lineflow_runtime::runs::RunRecord;
use lineflow_runtime::transport;

/// A subscribed topic of any message type.
trait Tap {
    /// Encodes every waiting message and hands it to `write`; whether end-of-stream came.
    fn drain(&mut self, write: &mut dyn FnMut(u64, &[u8]) -> Result<()>) -> Result<bool>;
}

struct TypedTap<M: Message> {
    sub: Subscriber<ipc::Service, [M::Element], M::Header>,
    cdr: Vec<u8>,
}

impl<M: Message> Tap for TypedTap<M> {
    fn drain(&mut self, write: &mut dyn FnMut(u64, &[u8]) -> Result<()>) -> Result<bool> {
        let _ = self.sub.update_connections();
        while let Some(sample) = self.sub.receive().map_err(|e| anyhow!("{e:?}"))? {
            let stamp = *M::stamp(sample.user_header());
            if stamp.is_end_of_stream() {
                return Ok(true);
            }
            encode(
                M::KIND,
                bytes_of(sample.user_header()),
                slice_bytes(sample.payload()),
                &mut self.cdr,
            );
            drop(sample);
            write(stamp.capture_time_ns, &self.cdr)?;
        }
        Ok(false)
    }
}

fn tap<M: Message>(node: &Node<ipc::Service>, e: &EdgeSpec) -> Result<Box<dyn Tap>> {
    let sub = transport::open_pubsub::<M>(node, e, 0)?
        .subscriber_builder()
        .buffer_size(e.depth)
        .create()
        .map_err(|err| {
            anyhow!(
                "cannot subscribe to '{}': {err:?} (the edge has room for one tool at a time)",
                e.topic
            )
        })?;
    Ok(Box::new(TypedTap::<M> { sub, cdr: Vec::new() }))
}

/// Records `topics` (every topic when empty) of a running run into `out`.
pub fn record(run: Option<&str>, topics: &[String], out: &Path, images: ImageFormat) -> Result<ExitCode> {
    let rec = RunRecord::find(run)?;
    let graph = rec.load_graph()?;
    let edges: Vec<&EdgeSpec> = if topics.is_empty() {
        graph.edges.iter().collect()
    } else {
        topics
            .iter()
            .map(|t| {
                graph.edges.iter().find(|e| &e.topic == t).ok_or_else(|| {
                    let names: Vec<_> = graph.edges.iter().map(|e| e.topic.as_str()).collect();
                    anyhow!("no topic '{t}' in run {} (topics: {})", rec.id, names.join(", "))
                })
            })
            .collect::<Result<_>>()?
    };
    if out.is_dir() {
        bail!("{}: a folder; name the recording file", out.display());
    }
    let cfg = transport::config(&rec.prefix, &rec.root)?;
    let node = transport::create_node(&cfg, &format!("cli-record-{}", std::process::id()))?;
    let mut writer = McapWriter::create(out, lineflow_recordings::image_codec::chunk_compression(images))?;
    let mut meta = run_metadata(&graph, &rec.id);
    meta.insert("attached".into(), "true".into());
    writer.metadata(META_RUN, meta)?;
    let mut taps = Vec::new();
    for e in &edges {
        let kind = e.kind();
        match kind {
            MessageKind::Image => writer.add_image_topic(&e.topic, images)?,
            _ => writer.add_topic(&e.topic, kind)?,
        }
        taps.push((e.topic.clone(), kind, with_kind!(kind, M => tap::<M>(&node, e)?), false));
    }
    eprintln!(
        "recording {} topics of run {} into {} (Ctrl-C ends)",
        taps.len(),
        rec.id,
        out.display()
    );
    let mut compressor = ImageCompressor::default();
    let mut packed = Vec::new();
    let mut counts: BTreeMap<String, u64> = BTreeMap::new();
    let mut checked = Instant::now();
    let why = loop {
        if node.wait(Duration::from_millis(20)).is_err() {
            break "interrupted (SIGINT/SIGTERM)";
        }
        for (topic, kind, tap, ended) in taps.iter_mut().filter(|t| !t.3) {
            *ended = tap.drain(&mut |publish_time, cdr| {
                let data = match (*kind, images) {
                    (MessageKind::Image, ImageFormat::Png | ImageFormat::Jpeg) => {
                        compressor.compress(cdr, images, DEFAULT_JPEG_QUALITY, &mut packed)?;
                        &packed[..]
                    }
                    _ => cdr,
                };
                *counts.entry(topic.clone()).or_default() += 1;
                writer.write(topic, now_ns(), publish_time, data)
            })?;
        }
        // Latched topics never end: they are done when everything else is, or when the run is.
        if taps.iter().all(|(_, kind, _, ended)| *ended || kind.latched()) {
            break "end-of-stream on every chosen topic";
        }
        if checked.elapsed() > Duration::from_secs(1) {
            checked = Instant::now();
            if !RunRecord::load(&rec.id).is_ok_and(|r| r.is_running()) {
                break "the run ended";
            }
        }
    };
    let mut end = BTreeMap::from([
        ("complete".to_owned(), "false".to_owned()),
        (
            "reason".to_owned(),
            format!("attached to a running run (what came before is not in the file); {why}"),
        ),
    ]);
    for (topic, n) in &counts {
        end.insert(format!("topic.{topic}.messages"), n.to_string());
    }
    writer.metadata(META_END, end)?;
    writer.finish()?;
    eprintln!(
        "{} messages of {} topics into {}; {why}",
        counts.values().sum::<u64>(),
        counts.len(),
        out.display()
    );
    Ok(ExitCode::SUCCESS)
}
