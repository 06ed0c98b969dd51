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
pub mod replay;
pub mod tools;
pub mod views;
pub mod writer;

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use anyhow::{bail, Context, Result};
use lineflow_messages::schema::{self, MessageSchema};
use lineflow_messages::MessageKind;

pub use writer::{Compression, McapWriter};

/// Metadata record written at the start: `version`, `run_id`, `graph_name`, `launch_path`, `launch_text`,
/// `graph_json`, and `node.<name>` = the node's stage, implementation and command.
pub const META_RUN: &str = "lineflow.run";
/// Metadata record written when the recorder finishes: `complete`, `reason`, `topic.<topic>.messages`,
/// `topic.<topic>.ended`, `node.<name>.{in,out,drops,missed}`.
pub const META_END: &str = "lineflow.end";
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

/// An opened recording: its bytes, parsed metadata and, for a finished file, the summary.
pub struct Recording {
    /// The file.
    pub path: PathBuf,
    bytes: Vec<u8>,
    /// The summary section; `None` when the recorder did not finish (killed, disk full) or it is corrupt.
    pub summary: Option<mcap::Summary>,
    /// Why the summary is missing.
    pub damage: Option<String>,
    /// Metadata records by name.
    pub metadata: BTreeMap<String, BTreeMap<String, String>>,
}

impl Recording {
    /// Opens a recording.
    ///
    /// # Errors
    /// When the file cannot be read or is not an MCAP file. A file without summary (not finished) opens; its
    /// `summary` is `None` and reading its messages stops at the first incomplete record.
    pub fn open(path: &Path) -> Result<Self> {
        let bytes = std::fs::read(path).with_context(|| format!("{}: cannot read", path.display()))?;
        if bytes.len() < MAGIC.len() || &bytes[..MAGIC.len()] != MAGIC {
            bail!(
                "{}: not an MCAP file (starts with {:02x?} instead of the MCAP magic)",
                path.display(),
                &bytes[..bytes.len().min(8)]
            );
        }
        let finished = bytes.len() >= 2 * MAGIC.len() && &bytes[bytes.len() - MAGIC.len()..] == MAGIC;
        let (summary, damage) = if finished {
            match std::panic::catch_unwind(|| mcap::Summary::read(&bytes)) {
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
        let mut rec = Self {
            path: path.to_owned(),
            bytes,
            summary,
            damage,
            metadata: BTreeMap::new(),
        };
        rec.metadata = rec.read_metadata();
        Ok(rec)
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

    fn read_metadata(&self) -> BTreeMap<String, BTreeMap<String, String>> {
        let mut out = BTreeMap::new();
        // Metadata records sit outside chunks; a linear scan finds them in finished and unfinished files alike.
        let Ok(reader) = record_stream(&self.bytes) else {
            return out;
        };
        for record in reader {
            match record {
                Ok(mcap::records::Record::Metadata(m)) => {
                    out.insert(m.name, m.metadata);
                }
                Ok(_) => {}
                Err(_) => break,
            }
        }
        out
    }

    /// Calls `f` with every message in file order.
    ///
    /// # Errors
    /// The first error of `f`, or of the file (truncated or corrupt), naming the byte offset region.
    pub fn for_each_message(&self, mut f: impl FnMut(RecordedMessage) -> Result<()>) -> Result<()> {
        let stream = message_stream(&self.bytes).with_context(|| format!("{}: cannot read messages", self.path.display()))?;
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

    /// Each topic's schema (name, encoding, text), message encoding and whether it is a viewer channel, as
    /// written, for copying channels into another file.
    pub fn raw_channels(&self) -> RawChannels {
        let mut out = RawChannels::new();
        let mut add = |c: &mcap::Channel<'_>| {
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
        };
        if let Some(s) = &self.summary {
            s.channels.values().for_each(|c| add(c));
        } else if let Ok(stream) = message_stream(&self.bytes) {
            stream.map_while(Result::ok).for_each(|m| add(&m.channel));
        }
        out
    }

    /// The channels, from the summary or (for an unfinished file) from the records that were written.
    pub fn channels(&self) -> Vec<ChannelInfo> {
        let mut by_id: BTreeMap<u16, ChannelInfo> = BTreeMap::new();
        if let Some(s) = &self.summary {
            for (id, c) in &s.channels {
                by_id.insert(*id, channel_info(c));
            }
        } else if let Ok(stream) = message_stream(&self.bytes) {
            for m in stream.map_while(Result::ok) {
                by_id.entry(m.channel.id).or_insert_with(|| channel_info(&m.channel));
            }
        }
        by_id.into_values().collect()
    }
}

// Lenient about a missing end (unfinished files), strict about chunk checksums (corrupt files).
fn message_stream(bytes: &[u8]) -> mcap::McapResult<Guarded<mcap::MessageStream<'_>>> {
    mcap::MessageStream::new_with_options(bytes, mcap::read::Options::IgnoreEndMagic | mcap::read::Options::ValidateChunkCrcs)
        .map(|r| Guarded(Some(r)))
}
fn record_stream(bytes: &[u8]) -> mcap::McapResult<Guarded<mcap::read::LinearReader<'_>>> {
    mcap::read::LinearReader::new_with_options(bytes, mcap::read::Options::IgnoreEndMagic.into()).map(|r| Guarded(Some(r)))
}

/// Why a record could not be read.
#[derive(Debug)]
enum ReadError {
    /// The mcap crate's own verdict.
    Mcap(mcap::McapError),
    /// The mcap crate panicked: 0.26 subtracts a record's length from what is left of its chunk unchecked, so a
    /// damaged length panics in a build with overflow checks (found by `lineflow bench fuzz`).
    Panicked,
}

impl std::fmt::Display for ReadError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            ReadError::Mcap(e) => e.fmt(f),
            ReadError::Panicked => f.write_str("a damaged record stopped the MCAP reader"),
        }
    }
}

/// An iterator of the mcap crate whose panic on damaged input becomes its last item, an error: a reader that
/// panicked is in no state to be asked again.
struct Guarded<I>(Option<I>);

impl<T, I: Iterator<Item = mcap::McapResult<T>>> Iterator for Guarded<I> {
    type Item = Result<T, ReadError>;

    fn next(&mut self) -> Option<Self::Item> {
        let inner = self.0.as_mut()?;
        match std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| inner.next())) {
            Ok(item) => item.map(|r| r.map_err(ReadError::Mcap)),
            Err(_) => {
                self.0 = None;
                Some(Err(ReadError::Panicked))
            }
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
