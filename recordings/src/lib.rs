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
pub mod fields;
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

pub use writer::{Compression, McapWriter, TopicTotals};

/// Metadata record written at the start: `version`, `run_id`, `graph_name`, `launch_path`, `launch_text`,
/// `graph_json`, and `node.<name>` = the node's stage, implementation and command.
pub const META_RUN: &str = "lineflow.run";
/// Metadata record written when the recorder finishes: `complete`, `reason`, `topic.<topic>.messages`,
/// `topic.<topic>.ended`, `node.<name>.{in,out,drops,missed}`.
pub const META_END: &str = "lineflow.end";
/// Metadata record written by [`McapWriter::finish`]: `topic.<topic>.{messages,bytes,largest,first_log,last_log}`
/// ([`TopicTotals`]), so that a finished file's totals need no pass over its messages.
pub const META_TOPICS: &str = "lineflow.topics";
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
    /// Encoded message (CDR for lineflow channels).
    pub data: Vec<u8>,
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
}

/// Per topic: schema (name, encoding, text), message encoding, viewer channel.
pub type RawChannels = std::collections::HashMap<String, ((String, String, Vec<u8>), String, bool)>;

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
    /// Metadata records by name.
    pub metadata: BTreeMap<String, BTreeMap<String, String>>,
}

impl Recording {
    /// Opens a recording, reading its start, its footer and summary and its metadata records.
    ///
    /// # Errors
    /// When the file cannot be read or is not an MCAP file. A file without summary (not finished) opens; its
    /// `summary` is `None` and reading its messages stops at the first incomplete record.
    pub fn open(path: &Path) -> Result<Self> {
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
            match std::panic::catch_unwind(|| reader::summary(path, size_bytes)) {
                Ok(Ok(s)) => (s, None),
                Ok(Err(e)) => (None, Some(format!("the summary section is corrupt ({e})"))),
                Err(_) => (None, Some("the summary section is corrupt".to_owned())),
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
        })
    }

    /// Whether the file ends properly (summary and footer written).
    pub fn is_finished(&self) -> bool {
        self.summary.is_some()
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
        let stream = reader::messages(&self.path).with_context(|| format!("{}: cannot read messages", self.path.display()))?;
        for (count, m) in stream.enumerate() {
            let m = match m {
                Ok(m) => m,
                Err(e) => {
                    let hint = if self.is_finished() {
                        "the file is corrupt"
                    } else {
                        "the recording was not finished; everything before this point is readable"
                    };
                    bail!("{}: after {count} messages: {e} ({hint})", self.path.display());
                }
            };
            let info = channel_info(&m.channel);
            f(RecordedMessage {
                topic: m.channel.topic.clone(),
                kind: info.kind,
                view: info.view,
                sequence: m.sequence,
                log_time: m.log_time,
                publish_time: m.publish_time,
                data: m.data.into_owned(),
            })?;
        }
        Ok(())
    }

    /// Each topic's totals from the [`META_TOPICS`] record of a finished file, without reading a message; `None`
    /// for an unfinished file or one of another writer.
    pub fn topic_totals(&self) -> Option<BTreeMap<String, TopicTotals>> {
        self.summary.as_ref()?;
        TopicTotals::from_metadata(self.metadata.get(META_TOPICS)?)
    }

    /// Each topic's totals by reading every message (checking every chunk), with the read's error if it ended
    /// early: the totals then hold what came before.
    pub fn scan_totals(&self) -> (BTreeMap<String, TopicTotals>, Result<()>) {
        let mut totals: BTreeMap<String, TopicTotals> = BTreeMap::new();
        let read = self.for_each_message(|m| {
            totals.entry(m.topic).or_default().add(m.log_time, m.data.len() as u64);
            Ok(())
        });
        (totals, read)
    }

    /// Each topic's schema (name, encoding, text), message encoding and whether it is a viewer channel, as
    /// written, for copying channels into another file.
    pub fn raw_channels(&self) -> RawChannels {
        let mut out = RawChannels::new();
        self.each_channel(|c| {
            out.entry(c.topic.clone()).or_insert_with(|| {
                let schema = c
                    .schema
                    .as_ref()
                    .map(|s| (s.name.clone(), s.encoding.clone(), s.data.to_vec()))
                    .unwrap_or_default();
                (
                    schema,
                    c.message_encoding.clone(),
                    c.metadata.get(VIEW_KEY).is_some_and(|v| v == "true"),
                )
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
        if let Some(s) = &self.summary {
            s.channels.values().for_each(|c| f(c));
        } else if let Ok(stream) = reader::messages(&self.path) {
            stream.map_while(Result::ok).for_each(|m| f(&m.channel));
        }
    }
}

fn channel_info(c: &mcap::Channel<'_>) -> ChannelInfo {
    let (schema, schema_encoding) = c.schema.as_ref().map(|s| (s.name.clone(), s.encoding.clone())).unwrap_or_default();
    let view = c.metadata.get(VIEW_KEY).is_some_and(|v| v == "true");
    let kind = if view {
        None
    } else {
        MessageSchema::by_name(&schema)
            .filter(|_| schema_encoding == schema::SCHEMA_ENCODING && c.message_encoding == schema::MESSAGE_ENCODING)
            .map(|s| s.kind)
    };
    ChannelInfo {
        topic: c.topic.clone(),
        schema,
        schema_encoding,
        encoding: c.message_encoding.clone(),
        kind,
        view,
    }
}

/// Nanoseconds since the Unix epoch now.
pub fn now_ns() -> u64 {
    std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map(|d| d.as_nanos() as u64)
        .unwrap_or(0)
}
