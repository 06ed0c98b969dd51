//! MCAP recordings: the writer the recorder node uses, and the reader behind `replay`, `info`, `diff`, `export`
//! and `recover`.
//!
//! One channel per topic, named as the topic, with the message's ros2msg schema and CDR encoding
//! ([`lineflow_messages::schema`]); `publish_time` is the message's capture time, `log_time` the moment the recorder
//! received it. Viewer channels (`<topic>/preview`, `<topic>/annotations`, `<topic>/scene`) hold Foxglove
//! renderings of the same messages and are marked with the channel metadata `lineflow.view = true`; they are never
//! replayed into a graph. Metadata records: [`META_RUN`] (versions, the launch file, the resolved graph) at the start,
//! [`META_END`] (completeness and every node's counters) at the end.
#![warn(missing_docs)]
pub mod export;
pub mod fields;
pub mod image_codec;
mod reader;
pub mod replay;
pub mod tools;
pub mod views;
pub mod writer;

use std::collections::BTreeMap;
use std::io::{Read, Seek, SeekFrom};
use std::path::{Path, PathBuf};

use anyhow::{bail, Context, Result};
use lineflow_messages::schema::{self, MessageSchema};
use lineflow_messages::MessageKind;

pub use writer::{part_path, Compression, McapWriter, SplitLimits, TopicTotals};

/// Metadata record written at the start: `version`, `run_id`, `graph_name`, `launch_path`, `launch_text`,
/// `graph_json`, and `node.<name>` = the node's stage, implementation and command.
pub const META_RUN: &str = "lineflow.run";
/// Metadata record written when the recorder finishes: `complete`, `reason`, `topic.<topic>.messages`,
/// `topic.<topic>.ended`, `node.<name>.{in,out,drops,missed}`.
pub const META_END: &str = "lineflow.end";
/// Metadata record written by [`McapWriter::finish`]: `topic.<topic>.{messages,bytes,largest,first_log,last_log}`
/// ([`TopicTotals`]), so that a finished file's totals need no pass over its messages.
pub const META_TOPICS: &str = "lineflow.topics";
/// Metadata record of every file of a split recording: `index` (0 for the first file, named as the recording;
/// then `stem.001.mcap`, ...).
pub const META_PART: &str = "lineflow.part";
/// Channel metadata key marking a viewer channel.
pub const VIEW_KEY: &str = "lineflow.view";
/// The MCAP profile of lineflow recordings.
pub const PROFILE: &str = "lineflow";

const MAGIC: &[u8] = b"\x89MCAP0\r\n";

/// A recorded message.
#[derive(Debug, Clone)]
pub struct RecordedMessage {
    /// Topic (channel) name.
    pub topic: String,
    /// The message kind, when the channel carries a lineflow schema (not a viewer channel).
    pub kind: Option<MessageKind>,
    /// Whether this is a viewer channel.
    pub view: bool,
    /// Per-channel sequence number.
    pub sequence: u32,
    /// Receipt time, ns since the Unix epoch.
    pub log_time: u64,
    /// Capture time of the message (its stamp), ns.
    pub publish_time: u64,
    /// Encoded message (CDR for lineflow channels), as stored: see [`Self::restore`].
    pub data: Vec<u8>,
    /// An image stored compressed ([`image_codec`]); `kind` is `Image`.
    pub compressed: bool,
}

impl RecordedMessage {
    /// Restores a compressed image in place, so that `data` holds the `Image` message as the graph carried it;
    /// other messages are left as they are.
    ///
    /// # Errors
    /// When the compressed image is damaged.
    pub fn restore(&mut self, scratch: &mut lineflow_messages::schema::Decoded) -> Result<()> {
        if self.compressed {
            let mut out = Vec::new();
            image_codec::restore(&self.data, scratch, &mut out)
                .with_context(|| format!("topic '{}' message {}", self.topic, self.sequence))?;
            self.data = out;
            self.compressed = false;
        }
        Ok(())
    }

    /// The message's size as the graph carries it (a compressed image's restored size).
    pub fn carried_len(&self) -> u64 {
        image_codec::carried_len(&self.data, self.compressed)
    }
}

/// A channel of a recording.
#[derive(Debug, Clone)]
pub struct ChannelInfo {
    /// Topic.
    pub topic: String,
    /// Schema name.
    pub schema: String,
    /// Schema encoding.
    pub schema_encoding: String,
    /// Message encoding.
    pub encoding: String,
    /// The message kind, for lineflow channels.
    pub kind: Option<MessageKind>,
    /// Viewer channel.
    pub view: bool,
    /// Images stored compressed: the format (`png`, `jpeg`).
    pub image_format: Option<String>,
}

/// Per topic: schema (name, encoding, text), message encoding, channel metadata.
pub type RawChannels = std::collections::HashMap<String, ((String, String, Vec<u8>), String, BTreeMap<String, String>)>;

/// An opened recording: its parsed metadata and, for a finished file, the summary. The messages stay in the file
/// and are streamed when asked for, so a recording of any size opens in bounded memory.
pub struct Recording {
    /// The file.
    pub path: PathBuf,
    /// Its size in bytes when opened.
    pub size_bytes: u64,
    /// The summary section; `None` when the recorder did not finish (killed, disk full) or it is corrupt.
    pub summary: Option<mcap::Summary>,
    /// Why the summary is missing.
    pub damage: Option<String>,
    /// Metadata records by name (of a split recording: the first file's, with the last file's end record).
    pub metadata: BTreeMap<String, BTreeMap<String, String>>,
    /// The files after the first of a split recording ([`McapWriter::split`]), in order.
    pub parts: Vec<Recording>,
}

impl Recording {
    /// Opens a recording, reading its start, its footer and summary and its metadata records.
    ///
    /// # Errors
    /// When the file cannot be read or is not an MCAP file. A file without summary (not finished) opens; its
    /// `summary` is `None` and reading its messages stops at the first incomplete record.
    pub fn open(path: &Path) -> Result<Self> {
        let mut rec = Self::open_file(path)?;
        rec.open_parts()?;
        Ok(rec)
    }

    /// The files after the first of a split recording, up to the first missing one; a later file beyond a gap
    /// marks the recording damaged (nothing after the gap is read).
    fn open_parts(&mut self) -> Result<()> {
        if self.metadata.get(META_PART).and_then(|m| m.get("index")).map(String::as_str) != Some("0") {
            return Ok(());
        }
        let mut k = 1;
        while part_path(&self.path, k).exists() {
            self.parts.push(Self::open_file(&part_path(&self.path, k))?);
            k += 1;
        }
        let missing = part_path(&self.path, k);
        if let Some(later) = later_part(&self.path, k) {
            self.damage.get_or_insert(format!(
                "{} of the split recording is missing; {} and after are not read",
                missing.display(),
                later.display()
            ));
        }
        for part in &self.parts {
            self.size_bytes += part.size_bytes;
            if let Some(d) = &part.damage {
                self.damage.get_or_insert(format!("{}: {d}", part.path.display()));
            }
        }
        match self.parts.last().and_then(|p| p.metadata.get(META_END)) {
            Some(end) => {
                self.metadata.insert(META_END.to_owned(), end.clone());
            }
            // The recorder writes its end record into the last file only.
            None if !self.parts.is_empty() => {
                self.metadata.remove(META_END);
            }
            None => {}
        }
        Ok(())
    }

    fn open_file(path: &Path) -> Result<Self> {
        let cannot_read = || format!("{}: cannot read", path.display());
        let mut file = std::fs::File::open(path).with_context(cannot_read)?;
        let size_bytes = file.metadata().with_context(cannot_read)?.len();
        let mut head = Vec::with_capacity(MAGIC.len());
        (&mut file)
            .take(MAGIC.len() as u64)
            .read_to_end(&mut head)
            .with_context(cannot_read)?;
        if head != MAGIC {
            bail!(
                "{}: not an MCAP file (starts with {:02x?} instead of the MCAP magic)",
                path.display(),
                &head
            );
        }
        let mut tail = [0u8; MAGIC.len()];
        let finished = size_bytes >= 2 * MAGIC.len() as u64
            && file.seek(SeekFrom::End(-(MAGIC.len() as i64))).is_ok()
            && file.read_exact(&mut tail).is_ok()
            && tail == MAGIC;
        let (summary, damage) = if finished {
            match reader::catch_quietly(|| reader::summary(path, size_bytes)) {
                Some(Ok(s)) => (s, None),
                Some(Err(e)) => (None, Some(format!("the summary section is corrupt ({e})"))),
                None => (None, Some("the summary section is corrupt".to_owned())),
            }
        } else {
            (
                None,
                Some("the file ends without summary and footer: the recorder did not finish".to_owned()),
            )
        };
        // Metadata records sit outside chunks: the summary indexes them; without it a scan over the chunks finds
        // them in unfinished files too.
        let metadata = match &summary {
            Some(s) if !s.metadata_indexes.is_empty() => {
                reader::indexed_metadata(path, s).with_context(|| format!("{}: cannot read its metadata", path.display()))?
            }
            _ => reader::scanned_metadata(path),
        };
        Ok(Self {
            path: path.to_owned(),
            size_bytes,
            summary,
            damage,
            metadata,
            parts: Vec::new(),
        })
    }

    /// Whether the file ends properly (summary and footer written).
    pub fn is_finished(&self) -> bool {
        self.summary.is_some() && self.parts.iter().all(Self::is_finished)
    }

    /// Whether the recorder saw end-of-stream on every topic and nothing was dropped or missed.
    pub fn is_complete(&self) -> bool {
        self.metadata
            .get(META_END)
            .and_then(|m| m.get("complete"))
            .is_some_and(|v| v == "true")
    }

    /// A field of the [`META_RUN`] record.
    pub fn run_meta(&self, key: &str) -> Option<&str> {
        self.metadata.get(META_RUN).and_then(|m| m.get(key)).map(String::as_str)
    }

    /// Calls `f` with every message in file order, streamed from the file.
    ///
    /// # Errors
    /// The first error of `f`, or of the file (truncated or corrupt), naming the byte offset region.
    pub fn for_each_message(&self, mut f: impl FnMut(RecordedMessage) -> Result<()>) -> Result<()> {
        for m in self.messages()? {
            f(m?)?;
        }
        Ok(())
    }

    /// Every message in file order, streamed from the file; after an error (a truncated or corrupt file) the
    /// iterator ends.
    ///
    /// # Errors
    /// When the file cannot be opened.
    pub fn messages(&self) -> Result<impl Iterator<Item = Result<RecordedMessage>> + '_> {
        let mut streams = Vec::new();
        for file in std::iter::once(self).chain(&self.parts) {
            streams.push(file.file_messages()?);
        }
        // A damaged file ends the read: the files after it would leave a gap in every topic.
        Ok(streams.into_iter().flatten().scan(false, |failed, m| {
            (!*failed).then(|| {
                *failed = m.is_err();
                m
            })
        }))
    }

    fn file_messages(&self) -> Result<impl Iterator<Item = Result<RecordedMessage>> + '_> {
        let stream = reader::messages(&self.path).with_context(|| format!("{}: cannot read messages", self.path.display()))?;
        Ok(stream.enumerate().map(|(count, m)| {
            let m = m.map_err(|e| {
                let hint = if self.is_finished() {
                    "the file is corrupt"
                } else {
                    "the recording was not finished; everything before this point is readable"
                };
                anyhow::anyhow!("{}: after {count} messages: {e} ({hint})", self.path.display())
            })?;
            let info = channel_info(&m.channel);
            Ok(RecordedMessage {
                topic: m.channel.topic.clone(),
                kind: info.kind,
                view: info.view,
                sequence: m.sequence,
                log_time: m.log_time,
                publish_time: m.publish_time,
                data: m.data.into_owned(),
                compressed: info.image_format.is_some(),
            })
        }))
    }

    /// Each topic's totals from the [`META_TOPICS`] record of a finished file, without reading a message; `None`
    /// for an unfinished file or one of another writer.
    pub fn topic_totals(&self) -> Option<BTreeMap<String, TopicTotals>> {
        if self.damage.is_some() {
            return None;
        }
        let mut totals = BTreeMap::<String, TopicTotals>::new();
        for file in std::iter::once(self).chain(&self.parts) {
            file.summary.as_ref()?;
            for (topic, t) in TopicTotals::from_metadata(file.metadata.get(META_TOPICS)?)? {
                totals.entry(topic).or_default().merge(&t);
            }
        }
        Some(totals)
    }

    /// Each topic's totals by reading every message (checking every chunk), with the read's error if it ended
    /// early: the totals then hold what came before.
    pub fn scan_totals(&self) -> (BTreeMap<String, TopicTotals>, Result<()>) {
        let mut totals: BTreeMap<String, TopicTotals> = BTreeMap::new();
        let read = self.for_each_message(|m| {
            let carried = m.carried_len();
            totals.entry(m.topic).or_default().add(m.log_time, m.data.len() as u64, carried);
            Ok(())
        });
        (totals, read)
    }

    /// Each topic's schema (name, encoding, text), message encoding and channel metadata, as written, for copying
    /// channels into another file.
    pub fn raw_channels(&self) -> RawChannels {
        let mut out = RawChannels::new();
        self.each_channel(|c| {
            out.entry(c.topic.clone()).or_insert_with(|| {
                let schema = c
                    .schema
                    .as_ref()
                    .map(|s| (s.name.clone(), s.encoding.clone(), s.data.to_vec()))
                    .unwrap_or_default();
                (schema, c.message_encoding.clone(), c.metadata.clone())
            });
        });
        out
    }

    /// The channels, from the summary or (for an unfinished file) from the records that were written.
    pub fn channels(&self) -> Vec<ChannelInfo> {
        let mut by_id: BTreeMap<u16, ChannelInfo> = BTreeMap::new();
        self.each_channel(|c| {
            by_id.entry(c.id).or_insert_with(|| channel_info(c));
        });
        by_id.into_values().collect()
    }

    // The summary's channels; an unfinished file's are found by streaming its messages.
    fn each_channel(&self, mut f: impl FnMut(&mcap::Channel<'_>)) {
        for file in std::iter::once(self).chain(&self.parts) {
            if let Some(s) = &file.summary {
                s.channels.values().for_each(|c| f(c));
            } else if let Ok(stream) = reader::messages(&file.path) {
                stream.map_while(Result::ok).for_each(|m| f(&m.channel));
            }
        }
    }
}

fn channel_info(c: &mcap::Channel<'_>) -> ChannelInfo {
    let (schema, schema_encoding) = c.schema.as_ref().map(|s| (s.name.clone(), s.encoding.clone())).unwrap_or_default();
    let view = c.metadata.get(VIEW_KEY).is_some_and(|v| v == "true");
    let lineflow = schema_encoding == schema::SCHEMA_ENCODING && c.message_encoding == schema::MESSAGE_ENCODING && !view;
    let image_format = c
        .metadata
        .get(image_codec::IMAGE_FORMAT_KEY)
        .filter(|_| lineflow && schema == image_codec::COMPRESSED_IMAGE)
        .cloned();
    let kind = if image_format.is_some() {
        Some(MessageKind::Image)
    } else {
        MessageSchema::by_name(&schema).filter(|_| lineflow).map(|s| s.kind)
    };
    ChannelInfo {
        topic: c.topic.clone(),
        schema,
        schema_encoding,
        encoding: c.message_encoding.clone(),
        kind,
        view,
        image_format,
    }
}

/// The first file named as a later file of the split recording `path` beyond index `k`, if any.
fn later_part(path: &Path, k: usize) -> Option<PathBuf> {
    let stem = path.file_stem()?.to_string_lossy().into_owned();
    let dir = path.parent().filter(|d| !d.as_os_str().is_empty()).unwrap_or(Path::new("."));
    std::fs::read_dir(dir)
        .ok()?
        .filter_map(|e| e.ok())
        .filter_map(|e| {
            let name = e.file_name().to_string_lossy().into_owned();
            let index: usize = name.strip_prefix(&format!("{stem}."))?.strip_suffix(".mcap")?.parse().ok()?;
            (index > k).then_some((index, e.path()))
        })
        .min()
        .map(|(_, p)| p)
}

/// The [`META_RUN`] record of a run of `graph`.
pub fn run_metadata(graph: &lineflow_runtime::launch::Graph, run_id: &str) -> BTreeMap<String, String> {
    let mut m = BTreeMap::from([
        ("version".to_owned(), env!("CARGO_PKG_VERSION").to_owned()),
        ("run_id".to_owned(), run_id.to_owned()),
        ("graph_name".to_owned(), graph.name.clone()),
        ("launch_path".to_owned(), graph.source.display().to_string()),
        ("launch_text".to_owned(), graph.text.clone()),
        ("graph_json".to_owned(), serde_json::to_string(graph).unwrap_or_default()),
        ("created_unix_ns".to_owned(), now_ns().to_string()),
    ]);
    for n in &graph.nodes {
        m.insert(
            format!("node.{}", n.name),
            format!(
                "stage={} impl={} version={} command={}",
                n.stage.as_deref().unwrap_or("-"),
                n.implementation.as_deref().unwrap_or("default"),
                env!("CARGO_PKG_VERSION"),
                n.command.join(" ")
            ),
        );
    }
    m
}

/// Nanoseconds since the Unix epoch now.
pub fn now_ns() -> u64 {
    std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map(|d| d.as_nanos() as u64)
        .unwrap_or(0)
}
