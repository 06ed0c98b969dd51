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
    /// What the current file holds of the topic.
    totals: TopicTotals,
    /// Holds compressed images ([`image_codec`](super::image_codec)).
    compressed: bool,
    /// Schema (name, encoding, text), message encoding and metadata, to add the channel again to the next file of
    /// a split recording.
    schema: (String, String, Vec<u8>),
    encoding: String,
    metadata: BTreeMap<String, String>,
}

/// When a recording moves on to its next file, as `ros2 bag record --max-bag-size / --max-bag-duration` do;
/// zero turns a limit off.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct SplitLimits {
    /// Bytes of messages in one file.
    pub max_bytes: u64,
    /// Nanoseconds of receipt time in one file.
    pub max_duration_ns: u64,
}

/// The `k`-th file of a split recording: the first is `path` itself, the next `stem.001.mcap`, `stem.002.mcap`...
pub fn part_path(path: &Path, k: usize) -> PathBuf {
    if k == 0 {
        return path.to_owned();
    }
    let stem = path.file_stem().map(|s| s.to_string_lossy().into_owned()).unwrap_or_default();
    path.with_file_name(format!("{stem}.{k:03}.mcap"))
}

fn open_file(path: &Path, compression: Compression) -> Result<mcap::Writer<BufWriter<File>>> {
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
    options
        .create(BufWriter::with_capacity(1 << 20, file))
        .with_context(|| format!("cannot start recording {}", path.display()))
}

fn close_file(inner: mcap::Writer<BufWriter<File>>, path: &Path) -> Result<()> {
    let mut inner = inner;
    inner
        .finish()
        .with_context(|| format!("{}: cannot finish the recording", path.display()))?;
    let file = inner
        .into_inner()
        .into_inner()
        .map_err(|e| e.into_error())
        .with_context(|| format!("{}: cannot flush the recording", path.display()))?;
    file.sync_all()
        .with_context(|| format!("{}: cannot sync the recording", path.display()))
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

    /// Adds the totals of a later file of the same topic.
    pub fn merge(&mut self, later: &TopicTotals) {
        if later.messages == 0 {
            return;
        }
        if self.messages == 0 {
            self.first_log = later.first_log;
        }
        self.messages += later.messages;
        self.bytes += later.bytes;
        self.largest = self.largest.max(later.largest);
        self.last_log = later.last_log;
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

/// An MCAP file being written, or a set of them when split ([`McapWriter::split`]).
pub struct McapWriter {
    inner: mcap::Writer<BufWriter<File>>,
    /// The first file's path.
    base: PathBuf,
    /// The current file's path.
    path: PathBuf,
    compression: Compression,
    channels: HashMap<String, Channel>,
    schemas: HashMap<String, u16>,
    split: SplitLimits,
    /// The current file's index, its message bytes and its first receipt time.
    part: usize,
    part_bytes: u64,
    part_first_log: Option<u64>,
    /// The run record, written again at the start of every file of a split recording.
    run_record: Option<BTreeMap<String, String>>,
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
        Ok(Self {
            inner: open_file(path, compression)?,
            base: path.to_owned(),
            path: path.to_owned(),
            compression,
            channels: HashMap::new(),
            schemas: HashMap::new(),
            split: SplitLimits::default(),
            part: 0,
            part_bytes: 0,
            part_first_log: None,
            run_record: None,
            bytes: 0,
            messages: 0,
        })
    }

    /// Splits the recording into files of at most `limits` ([`part_path`] names them); every file is a finished
    /// MCAP file with the channels, the run record and a [`META_PART`](super::META_PART) record. Call before the
    /// first message.
    ///
    /// # Errors
    /// On a write failure.
    pub fn split(&mut self, limits: SplitLimits) -> Result<()> {
        self.split = limits;
        if limits != SplitLimits::default() {
            self.metadata(super::META_PART, BTreeMap::from([("index".to_owned(), "0".to_owned())]))?;
        }
        Ok(())
    }

    fn split_due(&self, log_time: u64) -> bool {
        let SplitLimits {
            max_bytes,
            max_duration_ns,
        } = self.split;
        (max_bytes > 0 && self.part_bytes >= max_bytes)
            || (max_duration_ns > 0 && self.part_first_log.is_some_and(|t0| log_time.saturating_sub(t0) >= max_duration_ns))
    }

    /// Finishes the current file and starts the next with the same channels and run record.
    fn next_file(&mut self) -> Result<()> {
        self.write_topic_totals()?;
        let next = part_path(&self.base, self.part + 1);
        let full = std::mem::replace(&mut self.inner, open_file(&next, self.compression)?);
        close_file(full, &self.path)?;
        self.part += 1;
        self.path = next;
        self.part_bytes = 0;
        self.part_first_log = None;
        self.schemas.clear();
        let mut channels: Vec<(String, Channel)> = self.channels.drain().collect();
        // Channels keep their order (and so their ids) from file to file.
        channels.sort_by_key(|(_, c)| c.id);
        for (topic, mut c) in channels {
            let sid = self.schema_id(&c.schema.0, &c.schema.1, &c.schema.2)?;
            c.id = self
                .inner
                .add_channel(sid, &topic, &c.encoding, &c.metadata)
                .with_context(|| format!("{}: cannot write channel {topic}", self.path.display()))?;
            c.totals = TopicTotals::default();
            self.channels.insert(topic, c);
        }
        if let Some(run) = self.run_record.clone() {
            self.metadata(super::META_RUN, run)?;
        }
        let index = BTreeMap::from([("index".to_owned(), self.part.to_string())]);
        self.metadata(super::META_PART, index)
    }

    fn write_topic_totals(&mut self) -> Result<()> {
        let totals = TopicTotals::to_metadata(self.channels.iter().map(|(t, c)| (t.as_str(), &c.totals)));
        self.metadata(super::META_TOPICS, totals)
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
        let text = s.ros2msg();
        let schema = (s.name(), schema::SCHEMA_ENCODING, text.as_bytes());
        self.add_raw_channel(topic, (&schema.0, schema.1, schema.2), schema::MESSAGE_ENCODING, BTreeMap::new())
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
        let schema = (super::image_codec::COMPRESSED_IMAGE, schema::SCHEMA_ENCODING, text.as_bytes());
        let meta = BTreeMap::from([(super::image_codec::IMAGE_FORMAT_KEY.to_owned(), name.to_owned())]);
        self.add_raw_channel(topic, schema, schema::MESSAGE_ENCODING, meta)
    }

    /// Adds a viewer channel (never replayed).
    ///
    /// # Errors
    /// On a write failure.
    pub fn add_view(&mut self, topic: &str, view: &super::views::ViewSchema) -> Result<()> {
        let schema = (view.name, view.schema_encoding, view.data.as_bytes());
        let meta = BTreeMap::from([(VIEW_KEY.to_owned(), "true".to_owned())]);
        self.add_raw_channel(topic, schema, view.message_encoding, meta)
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
        if self.channels.contains_key(topic) {
            return Ok(());
        }
        let sid = self.schema_id(schema.0, schema.1, schema.2)?;
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
                schema: (schema.0.to_owned(), schema.1.to_owned(), schema.2.to_vec()),
                encoding: encoding.to_owned(),
                metadata,
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
        if !self.channels.contains_key(topic) {
            bail!("recording: no channel for topic '{topic}'");
        }
        if self.split_due(log_time) {
            self.next_file()?;
        }
        self.part_first_log.get_or_insert(log_time);
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
        c.totals
            .add(log_time, data.len() as u64, super::image_codec::carried_len(data, c.compressed));
        self.inner
            .write_to_known_channel(&header, data)
            .with_context(|| format!("{}: cannot write a message on '{topic}'", self.path.display()))?;
        self.bytes += data.len() as u64;
        self.part_bytes += data.len() as u64;
        self.messages += 1;
        Ok(())
    }

    /// Writes a metadata record.
    ///
    /// # Errors
    /// On a write failure.
    pub fn metadata(&mut self, name: &str, map: BTreeMap<String, String>) -> Result<()> {
        if name == super::META_RUN {
            self.run_record = Some(map.clone());
        }
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
        self.write_topic_totals()?;
        close_file(self.inner, &self.path)
    }

    /// The files written so far (one unless split).
    pub fn files(&self) -> Vec<PathBuf> {
        (0..=self.part).map(|k| part_path(&self.base, k)).collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{Recording, META_END};

    /// A recording of 10 messages of 1 kB on two topics, in files of at most 3 kB.
    fn split_recording(dir: &Path) -> PathBuf {
        let path = dir.join("rec.mcap");
        let mut w = McapWriter::create(&path, Compression::None).unwrap();
        w.metadata(crate::META_RUN, BTreeMap::from([("run_id".to_owned(), "r".to_owned())]))
            .unwrap();
        w.split(SplitLimits {
            max_bytes: 3000,
            max_duration_ns: 0,
        })
        .unwrap();
        let schema = ("s", "ros2msg", &b"uint8[] data"[..]);
        w.add_raw_channel("a", schema, "cdr", BTreeMap::new()).unwrap();
        w.add_raw_channel("b", schema, "cdr", BTreeMap::new()).unwrap();
        for k in 0..10u64 {
            w.write(if k % 2 == 0 { "a" } else { "b" }, k, k, &[k as u8; 1000]).unwrap();
        }
        w.metadata(META_END, BTreeMap::from([("complete".to_owned(), "true".to_owned())]))
            .unwrap();
        assert_eq!(w.files().len(), 4);
        w.finish().unwrap();
        path
    }

    #[test]
    fn a_split_recording_reads_as_one_and_names_a_missing_file() {
        let dir = tempfile::tempdir().unwrap();
        let path = split_recording(dir.path());
        assert!(part_path(&path, 3).exists() && !part_path(&path, 4).exists());
        let rec = Recording::open(&path).unwrap();
        assert_eq!(rec.parts.len(), 3);
        assert!(rec.damage.is_none() && rec.is_finished() && rec.is_complete(), "{:?}", rec.damage);
        let mut seen = Vec::new();
        rec.for_each_message(|m| {
            seen.push((m.topic.clone(), m.sequence, m.data[0]));
            Ok(())
        })
        .unwrap();
        let expected: Vec<_> = (0..10u8)
            .map(|k| (if k % 2 == 0 { "a" } else { "b" }.to_owned(), k as u32 / 2, k))
            .collect();
        assert_eq!(seen, expected, "every file in order, sequence numbers running on");
        let totals = rec.topic_totals().unwrap();
        assert_eq!((totals["a"].messages, totals["b"].bytes, totals["b"].last_log), (5, 5000, 9));
        // Every file is a recording of its own, with the run record.
        let second = Recording::open(&part_path(&path, 1)).unwrap();
        assert_eq!(second.run_meta("run_id"), Some("r"));
        assert_eq!(second.channels().len(), 2);
        // A missing file in the middle: named, and nothing after it is read.
        std::fs::remove_file(part_path(&path, 2)).unwrap();
        let rec = Recording::open(&path).unwrap();
        let damage = rec.damage.clone().unwrap();
        assert!(damage.contains("rec.002.mcap of the split recording is missing"), "{damage}");
        assert_eq!(rec.parts.len(), 1);
        assert!(rec.topic_totals().is_none() && !rec.is_complete());
        // The last file lost: no end record, so not complete.
        std::fs::remove_file(part_path(&path, 3)).unwrap();
        let rec = Recording::open(&path).unwrap();
        assert!(rec.damage.is_none() && !rec.is_complete());
    }
}
