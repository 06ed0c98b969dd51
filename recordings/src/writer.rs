//! Writing a recording: channels with their schemas, messages, metadata, and a summary with chunk indexes.
use std::collections::{BTreeMap, HashMap};
use std::fs::File;
use std::io::BufWriter;
use std::path::{Path, PathBuf};

use anyhow::{bail, Context, Result};
use lineflow_messages::schema;
use lineflow_messages::MessageKind;

use super::{PROFILE, VIEW_KEY};

/// Chunk compression. mcap 0.26 compresses every chunk of a file alike, so one setting covers images and small
/// messages. Raw camera frames barely compress (sensor noise) and LZ4 halves the recorder's throughput on them
/// (`lineflow bench record`), so the default is none; `lz4` or `zstd` pay off for graphs of small messages.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Deserialize, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Compression {
    /// Uncompressed chunks (fastest).
    #[default]
    None,
    /// LZ4 frames.
    Lz4,
    /// Zstandard, level 1.
    Zstd,
}

impl std::str::FromStr for Compression {
    type Err = anyhow::Error;
    fn from_str(s: &str) -> Result<Self> {
        Ok(match s {
            "none" => Self::None,
            "lz4" => Self::Lz4,
            "zstd" => Self::Zstd,
            _ => bail!("unknown compression '{s}' (none, lz4, zstd)"),
        })
    }
}

struct Channel {
    id: u16,
    next_sequence: u32,
    totals: TopicTotals,
    /// Holds compressed images ([`image_codec`](super::image_codec)).
    compressed: bool,
}

/// What a file holds of one topic, written as the [`META_TOPICS`](super::META_TOPICS) record when the file is
/// finished, so that `info` and `replay` need not read every message of a large file.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct TopicTotals {
    /// Messages.
    pub messages: u64,
    /// Their bytes.
    pub bytes: u64,
    /// The largest message as a graph carries it (a compressed image restored), bytes.
    pub largest: u64,
    /// `log_time` of the first and the last message.
    pub first_log: u64,
    /// See `first_log`.
    pub last_log: u64,
}

impl TopicTotals {
    /// Counts a message.
    pub fn add(&mut self, log_time: u64, bytes: u64, carried: u64) {
        if self.messages == 0 {
            self.first_log = log_time;
        }
        self.messages += 1;
        self.bytes += bytes;
        self.largest = self.largest.max(carried);
        self.last_log = log_time;
    }

    const FIELDS: [&'static str; 5] = ["messages", "bytes", "largest", "first_log", "last_log"];

    fn values(&self) -> [u64; 5] {
        [self.messages, self.bytes, self.largest, self.first_log, self.last_log]
    }

    /// The record's fields of every topic.
    pub fn to_metadata<'a>(topics: impl IntoIterator<Item = (&'a str, &'a TopicTotals)>) -> BTreeMap<String, String> {
        let mut out = BTreeMap::new();
        for (topic, t) in topics {
            for (field, value) in Self::FIELDS.iter().zip(t.values()) {
                out.insert(format!("topic.{topic}.{field}"), value.to_string());
            }
        }
        out
    }

    /// The totals of every topic in a record written by [`Self::to_metadata`]; `None` when a field is missing or
    /// not a number (a record of another writer).
    pub fn from_metadata(map: &BTreeMap<String, String>) -> Option<BTreeMap<String, TopicTotals>> {
        let mut out: BTreeMap<String, [Option<u64>; 5]> = BTreeMap::new();
        for (key, value) in map {
            let (topic, field) = key.strip_prefix("topic.")?.rsplit_once('.')?;
            let i = Self::FIELDS.iter().position(|f| *f == field)?;
            out.entry(topic.to_owned()).or_default()[i] = Some(value.parse().ok()?);
        }
        out.into_iter()
            .map(|(topic, v)| {
                let [messages, bytes, largest, first_log, last_log] = v;
                Some((
                    topic,
                    TopicTotals {
                        messages: messages?,
                        bytes: bytes?,
                        largest: largest?,
                        first_log: first_log?,
                        last_log: last_log?,
                    },
                ))
            })
            .collect()
    }
}

/// An MCAP file being written.
pub struct McapWriter {
    inner: mcap::Writer<BufWriter<File>>,
    path: PathBuf,
    channels: HashMap<String, Channel>,
    schemas: HashMap<String, u16>,
    /// Message bytes written so far.
    pub bytes: u64,
    /// Messages written so far.
    pub messages: u64,
}

impl McapWriter {
    /// Creates the file (replacing an existing one).
    ///
    /// # Errors
    /// When the file cannot be created.
    pub fn create(path: &Path, compression: Compression) -> Result<Self> {
        if let Some(dir) = path.parent().filter(|d| !d.as_os_str().is_empty()) {
            std::fs::create_dir_all(dir).with_context(|| format!("cannot create {}", dir.display()))?;
        }
        let file = File::create(path).with_context(|| format!("cannot create recording {}", path.display()))?;
        let options = mcap::WriteOptions::new()
            .profile(PROFILE)
            .library(format!("lineflow {}", env!("CARGO_PKG_VERSION")))
            .compression(match compression {
                Compression::None => None,
                Compression::Lz4 => Some(mcap::Compression::Lz4),
                Compression::Zstd => Some(mcap::Compression::Zstd),
            })
            .compression_level(if compression == Compression::Zstd { 1 } else { 0 })
            // zstd's worker threads would compete with the graph for the cores.
            .compression_threads(0)
            .chunk_size(Some(4 << 20));
        let inner = options
            .create(BufWriter::with_capacity(1 << 20, file))
            .with_context(|| format!("cannot start recording {}", path.display()))?;
        Ok(Self {
            inner,
            path: path.to_owned(),
            channels: HashMap::new(),
            schemas: HashMap::new(),
            bytes: 0,
            messages: 0,
        })
    }

    fn schema_id(&mut self, name: &str, encoding: &str, data: &[u8]) -> Result<u16> {
        if let Some(id) = self.schemas.get(name) {
            return Ok(*id);
        }
        let id = self
            .inner
            .add_schema(name, encoding, data)
            .with_context(|| format!("{}: cannot write schema {name}", self.path.display()))?;
        self.schemas.insert(name.to_owned(), id);
        Ok(id)
    }

    /// Adds the channel of a graph topic carrying `kind`.
    ///
    /// # Errors
    /// On a write failure.
    pub fn add_topic(&mut self, topic: &str, kind: MessageKind) -> Result<()> {
        let s = kind.schema();
        let sid = self.schema_id(&s.name(), schema::SCHEMA_ENCODING, s.ros2msg().as_bytes())?;
        self.add_channel(topic, sid, schema::MESSAGE_ENCODING, BTreeMap::new())
    }

    /// Adds the channel of an image topic recorded compressed ([`image_codec`](super::image_codec)); `raw` adds
    /// the plain topic.
    ///
    /// # Errors
    /// On a write failure.
    pub fn add_image_topic(&mut self, topic: &str, format: super::image_codec::ImageFormat) -> Result<()> {
        let Some(name) = format.name() else {
            return self.add_topic(topic, MessageKind::Image);
        };
        let text = super::image_codec::compressed_image_schema();
        let sid = self.schema_id(super::image_codec::COMPRESSED_IMAGE, schema::SCHEMA_ENCODING, text.as_bytes())?;
        let meta = BTreeMap::from([(super::image_codec::IMAGE_FORMAT_KEY.to_owned(), name.to_owned())]);
        self.add_channel(topic, sid, schema::MESSAGE_ENCODING, meta)
    }

    /// Adds a viewer channel (never replayed).
    ///
    /// # Errors
    /// On a write failure.
    pub fn add_view(&mut self, topic: &str, view: &super::views::ViewSchema) -> Result<()> {
        let sid = self.schema_id(view.name, view.schema_encoding, view.data.as_bytes())?;
        self.add_channel(
            topic,
            sid,
            view.message_encoding,
            BTreeMap::from([(VIEW_KEY.to_owned(), "true".to_owned())]),
        )
    }

    /// Adds a channel with an arbitrary schema (used by `recover` to copy channels).
    ///
    /// # Errors
    /// On a write failure.
    pub fn add_raw_channel(
        &mut self,
        topic: &str,
        schema: (&str, &str, &[u8]),
        encoding: &str,
        metadata: BTreeMap<String, String>,
    ) -> Result<()> {
        let sid = self.schema_id(schema.0, schema.1, schema.2)?;
        self.add_channel(topic, sid, encoding, metadata)
    }

    fn add_channel(&mut self, topic: &str, sid: u16, encoding: &str, metadata: BTreeMap<String, String>) -> Result<()> {
        if self.channels.contains_key(topic) {
            return Ok(());
        }
        let id = self
            .inner
            .add_channel(sid, topic, encoding, &metadata)
            .with_context(|| format!("{}: cannot write channel {topic}", self.path.display()))?;
        self.channels.insert(
            topic.to_owned(),
            Channel {
                id,
                next_sequence: 0,
                totals: TopicTotals::default(),
                compressed: metadata.contains_key(super::image_codec::IMAGE_FORMAT_KEY),
            },
        );
        Ok(())
    }

    /// Whether a channel exists.
    pub fn has_channel(&self, topic: &str) -> bool {
        self.channels.contains_key(topic)
    }

    /// Writes a message on an added channel.
    ///
    /// # Errors
    /// When the channel was not added, or on a write failure (disk full).
    pub fn write(&mut self, topic: &str, log_time: u64, publish_time: u64, data: &[u8]) -> Result<()> {
        let Some(c) = self.channels.get_mut(topic) else {
            bail!("recording: no channel for topic '{topic}'");
        };
        let header = mcap::records::MessageHeader {
            channel_id: c.id,
            sequence: c.next_sequence,
            log_time,
            publish_time,
        };
        c.next_sequence = c.next_sequence.wrapping_add(1);
        let carried = match c.compressed {
            true => super::image_codec::restored_len(data).unwrap_or(data.len() as u64),
            false => data.len() as u64,
        };
        c.totals.add(log_time, data.len() as u64, carried);
        self.inner
            .write_to_known_channel(&header, data)
            .with_context(|| format!("{}: cannot write a message on '{topic}'", self.path.display()))?;
        self.bytes += data.len() as u64;
        self.messages += 1;
        Ok(())
    }

    /// Writes a metadata record.
    ///
    /// # Errors
    /// On a write failure.
    pub fn metadata(&mut self, name: &str, map: BTreeMap<String, String>) -> Result<()> {
        self.inner
            .write_metadata(&mcap::records::Metadata {
                name: name.to_owned(),
                metadata: map,
            })
            .with_context(|| format!("{}: cannot write metadata {name}", self.path.display()))
    }

    /// Writes the [`META_TOPICS`](super::META_TOPICS) record, the summary and footer, and syncs the file to disk.
    ///
    /// # Errors
    /// On a write failure (the file then ends without summary; `lineflow recover` rebuilds it).
    pub fn finish(mut self) -> Result<()> {
        let path = self.path.clone();
        let totals = TopicTotals::to_metadata(self.channels.iter().map(|(t, c)| (t.as_str(), &c.totals)));
        self.metadata(super::META_TOPICS, totals)?;
        self.inner
            .finish()
            .with_context(|| format!("{}: cannot finish the recording", path.display()))?;
        let file = self
            .inner
            .into_inner()
            .into_inner()
            .map_err(|e| e.into_error())
            .with_context(|| format!("{}: cannot flush the recording", path.display()))?;
        file.sync_all()
            .with_context(|| format!("{}: cannot sync the recording", path.display()))
    }
}
