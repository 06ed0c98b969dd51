//! `lineflow info`, `diff` and `recover` on recordings.
use std::collections::BTreeMap;
use std::fmt::Write as _;
use std::path::Path;

use anyhow::Result;
use lineflow_messages::schema::{self, decode, FieldType, Layout, Payload};
use lineflow_messages::MessageKind;

use super::{McapWriter, Recording, META_END, META_RUN};

/// What `lineflow info` says of a recording (and `--json` prints).
#[derive(Debug, Clone, serde::Serialize)]
pub struct Summary {
    /// The file.
    pub file: String,
    /// Its size, bytes (of every file of a split recording).
    pub size_bytes: u64,
    /// Its files: 1, or the files of a split recording.
    pub files: usize,
    /// The run that wrote it, when the recorder stored one.
    pub run: Option<RunSummary>,
    /// From the first message to the last, seconds.
    pub duration_s: f64,
    /// Messages over every topic.
    pub messages: u64,
    /// Whether it ends with the recorder's end record, end-of-stream on every topic and nothing dropped.
    pub complete: bool,
    /// Its state in words (complete, incomplete and why, damaged up to where).
    pub status: String,
    /// Whether every message was read and every chunk's checksum checked (else the summary was trusted).
    pub chunks_verified: bool,
    /// Whether the file is unfinished or a read failed (`info` exits with status 2).
    pub damaged: bool,
    /// Each topic, by name.
    pub topics: Vec<TopicSummary>,
    /// Messages each node dropped, where any did.
    pub drops: BTreeMap<String, String>,
}

/// The run a recording holds.
#[derive(Debug, Clone, serde::Serialize)]
pub struct RunSummary {
    /// Run id.
    pub id: String,
    /// The graph's name.
    pub graph: String,
    /// The launch file it was started from.
    pub launch: String,
    /// The lineflow version that ran it.
    pub version: String,
}

/// One topic of a recording.
#[derive(Debug, Clone, serde::Serialize)]
pub struct TopicSummary {
    /// Topic.
    pub topic: String,
    /// Its messages.
    pub messages: u64,
    /// Their bytes.
    pub bytes: u64,
    /// Messages a second between its first and last, when it has two or more.
    pub rate_hz: Option<f64>,
    /// Schema name.
    pub schema: String,
    /// Message encoding.
    pub encoding: String,
}

/// How much of a recording [`summarize`] reads.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Reading {
    /// A finished file's summary and totals record only (milliseconds on a file of any size); an unfinished file,
    /// or one of another writer, is read through.
    Index,
    /// Every message, checking every chunk's checksum.
    Messages,
}

/// Topics, message counts, rates, duration, schemas and completeness of a recording.
pub fn summarize(rec: &Recording, reading: Reading) -> Summary {
    let indexed = match reading {
        Reading::Index => rec.topic_totals(),
        Reading::Messages => None,
    };
    let verified = indexed.is_none();
    let (totals, read) = match indexed {
        Some(totals) => (totals, Ok(())),
        None => rec.scan_totals(),
    };
    let mut schemas: BTreeMap<String, (String, String)> = BTreeMap::new();
    for c in rec.channels() {
        schemas.entry(c.topic).or_insert((c.schema, c.encoding));
    }
    let (t0, t1) = totals
        .values()
        .filter(|t| t.messages > 0)
        .fold((u64::MAX, 0), |(a, b), t| (a.min(t.first_log), b.max(t.last_log)));
    let meta = |k: &str| rec.run_meta(k).unwrap_or("?").to_owned();
    let run = rec.run_meta("graph_name").map(|graph| RunSummary {
        id: meta("run_id"),
        graph: graph.to_owned(),
        launch: meta("launch_path"),
        version: meta("version"),
    });
    let read_error = read.as_ref().err().map(|e| format!("{e:#}"));
    let mut topics: BTreeMap<String, TopicSummary> = BTreeMap::new();
    for (topic, (schema, encoding)) in schemas {
        let t = totals.get(&topic).copied().unwrap_or_default();
        let span = t.last_log.saturating_sub(t.first_log) as f64 * 1e-9;
        let summary = TopicSummary {
            topic: topic.clone(),
            messages: t.messages,
            bytes: t.bytes,
            rate_hz: (t.messages > 1 && span > 0.0).then(|| (t.messages - 1) as f64 / span),
            schema,
            encoding,
        };
        topics.insert(topic, summary);
    }
    let topics: Vec<TopicSummary> = topics.into_values().collect();
    let drops = rec
        .metadata
        .get(META_END)
        .map(|end| {
            end.iter()
                .filter_map(|(k, v)| k.strip_prefix("node.").and_then(|k| k.strip_suffix(".drops")).map(|n| (n, v)))
                .filter(|(_, v)| v.as_str() != "0")
                .map(|(n, v)| (n.to_owned(), v.clone()))
                .collect()
        })
        .unwrap_or_default();
    Summary {
        file: rec.path.display().to_string(),
        size_bytes: rec.size_bytes,
        files: 1 + rec.parts.len(),
        run,
        duration_s: if t1 > t0 { (t1 - t0) as f64 * 1e-9 } else { 0.0 },
        messages: topics.iter().map(|t| t.messages).sum(),
        complete: rec.damage.is_none() && read.is_ok() && rec.is_complete(),
        status: completeness(rec, read_error),
        chunks_verified: verified,
        damaged: rec.damage.is_some() || read.is_err(),
        topics,
        drops,
    }
}

/// A human-readable summary: topics, message counts, rates, duration, schemas, completeness.
pub fn info(s: &Summary) -> String {
    let mut out = String::new();
    let files = if s.files > 1 {
        format!(" in {} files", s.files)
    } else {
        String::new()
    };
    let _ = writeln!(out, "file:      {} ({:.1} MB{files})", s.file, s.size_bytes as f64 / 1e6);
    if let Some(r) = &s.run {
        let _ = writeln!(
            out,
            "run:       {} (graph '{}', {}, lineflow {})",
            r.id, r.graph, r.launch, r.version
        );
    }
    let _ = writeln!(out, "duration:  {:.3} s, {} messages", s.duration_s, s.messages);
    let _ = writeln!(out, "status:    {}", s.status);
    if !s.chunks_verified {
        let _ = writeln!(
            out,
            "chunks:    not read (totals from the summary); `--verify` reads and checks every one"
        );
    }
    let _ = writeln!(out, "\n{:<28} {:>8} {:>10} {:>9}  schema", "topic", "messages", "MB", "rate Hz");
    for t in &s.topics {
        let rate = t.rate_hz.map(|r| format!("{r:.2}")).unwrap_or_else(|| "-".into());
        let _ = writeln!(
            out,
            "{:<28} {:>8} {:>10.2} {rate:>9}  {} ({})",
            t.topic,
            t.messages,
            t.bytes as f64 / 1e6,
            t.schema,
            t.encoding
        );
    }
    for (node, drops) in &s.drops {
        let _ = writeln!(out, "node '{node}' dropped {drops} messages");
    }
    out
}

fn completeness(rec: &Recording, read_error: Option<String>) -> String {
    if let Some(damage) = &rec.damage {
        return format!(
            "INCOMPLETE: {damage}{}; `lineflow recover` rebuilds the file",
            read_error.map(|e| format!("; readable up to: {e}")).unwrap_or_default()
        );
    }
    if let Some(e) = read_error {
        return format!("CORRUPT: {e}");
    }
    match rec.metadata.get(META_END) {
        Some(_) if rec.is_complete() => "complete (end-of-stream on every topic, nothing dropped)".into(),
        Some(end) => format!("incomplete: {}", end.get("reason").map(String::as_str).unwrap_or("unknown")),
        None => "finished, but without the recorder's end record".into(),
    }
}

/// The first difference between two recordings, or `None` when every topic carries the same messages.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Difference {
    /// Topic.
    pub topic: String,
    /// What differs.
    pub what: String,
}

/// Outcome of [`diff`].
#[derive(Debug, Default)]
pub struct DiffReport {
    /// Topics whose messages are all equal.
    pub equal: Vec<String>,
    /// Topics that differ, each with its first difference.
    pub differ: Vec<Difference>,
}

/// Compares two recordings topic by topic, message by message (the message bytes; receipt times are ignored).
/// Viewer channels are skipped: they are renderings of the compared messages.
///
/// # Errors
/// When a file cannot be read to its end.
pub fn diff(a: &Recording, b: &Recording) -> Result<DiffReport> {
    // One pass over each file fingerprints every topic; only a topic whose fingerprints differ is read again, from
    // both files in step, to name its first difference. Memory stays that of a message or two on any file size.
    let (fa, fb) = (fingerprints(a)?, fingerprints(b)?);
    let mut report = DiffReport::default();
    let topics: std::collections::BTreeSet<&String> = fa.keys().chain(fb.keys()).collect();
    for topic in topics {
        let diff = match (fa.get(topic), fb.get(topic)) {
            (Some(_), None) => Some(format!("only in {}", a.path.display())),
            (None, Some(_)) => Some(format!("only in {}", b.path.display())),
            (Some(x), Some(y)) if x == y => None,
            (Some(x), Some(_)) => Some(first_difference(x.kind, topic_messages(a, topic)?, topic_messages(b, topic)?)?),
            (None, None) => None,
        };
        match diff {
            None => report.equal.push(topic.clone()),
            Some(what) => report.differ.push(Difference {
                topic: topic.clone(),
                what,
            }),
        }
    }
    Ok(report)
}

/// A topic's messages in a digest: their count and two independent 64-bit hashes of their bytes in order.
#[derive(Debug, PartialEq, Eq)]
struct Fingerprint {
    kind: Option<MessageKind>,
    messages: u64,
    hashes: [u64; 2],
}

fn fingerprints(r: &Recording) -> Result<BTreeMap<String, Fingerprint>> {
    use std::hash::{Hash, Hasher};
    let mut out: BTreeMap<String, (Fingerprint, [std::hash::DefaultHasher; 2])> = BTreeMap::new();
    let mut scratch = schema::Decoded::default();
    for msg in r.messages()? {
        let mut msg = msg?;
        if msg.view {
            continue;
        }
        // A compressed image is compared as the image it restores: a PNG recording equals its raw run.
        msg.restore(&mut scratch)?;
        let (f, hashers) = out.entry(msg.topic.clone()).or_insert_with(|| {
            let fingerprint = Fingerprint {
                kind: msg.kind,
                messages: 0,
                hashes: [0; 2],
            };
            let mut second = std::hash::DefaultHasher::new();
            0x5eed_u64.hash(&mut second);
            (fingerprint, [std::hash::DefaultHasher::new(), second])
        });
        f.messages += 1;
        for h in hashers.iter_mut() {
            msg.data.hash(h);
        }
    }
    Ok(out
        .into_iter()
        .map(|(topic, (mut f, hashers))| {
            f.hashes = [hashers[0].finish(), hashers[1].finish()];
            (topic, f)
        })
        .collect())
}

/// One topic's messages (restored), streamed.
fn topic_messages<'r>(r: &'r Recording, topic: &'r str) -> Result<impl Iterator<Item = Result<Vec<u8>>> + 'r> {
    let mut scratch = schema::Decoded::default();
    Ok(r.messages()?.filter_map(move |m| match m {
        Ok(m) if m.topic != topic || m.view => None,
        Ok(mut m) => Some(m.restore(&mut scratch).map(|()| m.data)),
        Err(e) => Some(Err(e)),
    }))
}

fn first_difference(
    kind: Option<MessageKind>,
    mut a: impl Iterator<Item = Result<Vec<u8>>>,
    mut b: impl Iterator<Item = Result<Vec<u8>>>,
) -> Result<String> {
    let mut i = 0usize;
    loop {
        match (a.next().transpose()?, b.next().transpose()?) {
            (Some(x), Some(y)) if x != y => {
                let detail = kind
                    .and_then(|k| field_difference(k, &x, &y))
                    .unwrap_or_else(|| "bytes differ".into());
                let frame = kind
                    .and_then(|k| decode(k, &x).ok())
                    .map(|d| format!(" (frame {})", d.stamp().frame))
                    .unwrap_or_default();
                return Ok(format!("message {i}{frame}: {detail}"));
            }
            (Some(_), Some(_)) => i += 1,
            (Some(_), None) => return Ok(format!("{} messages vs {i}", i + 1 + a.count())),
            (None, Some(_)) => return Ok(format!("{i} messages vs {}", i + 1 + b.count())),
            // Equal messages under different fingerprints: only a hash collision would get here.
            (None, None) => return Ok("fingerprints differ, messages equal".into()),
        }
    }
}

/// Names the first field that differs between two encodings of the same kind.
fn field_difference(kind: MessageKind, x: &[u8], y: &[u8]) -> Option<String> {
    let (dx, dy) = (decode(kind, x).ok()?, decode(kind, y).ok()?);
    let s = kind.schema();
    if let Some(f) = layout_difference(s.header, &dx.header, &dy.header, "") {
        return Some(format!("field '{f}' differs"));
    }
    let name = match s.payload {
        Payload::Empty => "payload",
        Payload::One(p) => p.name,
        Payload::Two { a, b, .. } => {
            return Some(format!(
                "'{}' or '{}' differ ({} vs {} bytes)",
                a.name,
                b.name,
                dx.payload.len(),
                dy.payload.len()
            ));
        }
    };
    let size = match s.payload {
        Payload::One(schema::Part {
            elem: schema::Elem::Struct(l),
            ..
        }) => l.size,
        _ => 1,
    };
    if dx.payload.len() != dy.payload.len() {
        return Some(format!(
            "'{name}' has {} vs {} elements",
            dx.payload.len() / size,
            dy.payload.len() / size
        ));
    }
    let at = dx.payload.iter().zip(&dy.payload).position(|(p, q)| p != q)?;
    Some(format!("'{name}' differs from element {}", at / size))
}

fn layout_difference(l: &Layout, x: &[u8], y: &[u8], prefix: &str) -> Option<String> {
    for f in l.fields {
        let (a, b) = (&x[f.offset..f.offset + f.ty.size()], &y[f.offset..f.offset + f.ty.size()]);
        if let FieldType::Struct(inner) = f.ty {
            if let Some(d) = layout_difference(inner, a, b, &format!("{prefix}{}.", f.name)) {
                return Some(d);
            }
        } else if a != b {
            return Some(format!("{prefix}{}", f.name));
        }
    }
    None
}

/// What [`recover`] saved.
#[derive(Debug)]
pub struct Recovered {
    /// Messages copied.
    pub messages: u64,
    /// Why the source ended early, if it did.
    pub lost: Option<String>,
}

/// Copies every readable message, channel and metadata record of a damaged recording into a new, finished file
/// (summary, chunk indexes), and marks it incomplete.
///
/// # Errors
/// When the source is not an MCAP file or the new file cannot be written.
pub fn recover(rec: &Recording, out: &Path) -> Result<Recovered> {
    if out.exists() && std::fs::canonicalize(out).ok() == std::fs::canonicalize(&rec.path).ok() {
        anyhow::bail!("{}: recover into another file", out.display());
    }
    let mut w = McapWriter::create(out, super::Compression::Lz4)?;
    if let Some(run) = rec.metadata.get(META_RUN) {
        w.metadata(META_RUN, run.clone())?;
    }
    let schemas = rec.raw_channels();
    let mut messages = 0u64;
    let result = rec.for_each_message(|m| {
        if !w.has_channel(&m.topic) {
            let Some((schema, encoding, meta)) = schemas.get(&m.topic) else {
                return Ok(());
            };
            w.add_raw_channel(&m.topic, (&schema.0, &schema.1, &schema.2), encoding, meta.clone())?;
        }
        w.write(&m.topic, m.log_time, m.publish_time, &m.data)?;
        messages += 1;
        Ok(())
    });
    let lost = result.err().map(|e| format!("{e:#}"));
    let mut end = rec.metadata.get(META_END).cloned().unwrap_or_default();
    if lost.is_some() || rec.damage.is_some() {
        end.insert("complete".into(), "false".into());
        end.insert(
            "reason".into(),
            format!(
                "recovered from a damaged file: {}",
                lost.clone().or(rec.damage.clone()).unwrap_or_default()
            ),
        );
    }
    w.metadata(META_END, end)?;
    w.finish()?;
    Ok(Recovered { messages, lost })
}
