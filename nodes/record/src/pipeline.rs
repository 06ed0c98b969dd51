//! The recorder's writing side, behind the thread that takes the samples: images compressed on worker threads when
//! `[record] images` asks for it, then one writer thread that writes every message in its order of arrival with its
//! viewer renderings. Disk I/O and compression never hold a shared-memory sample.
use std::collections::BTreeMap;
use std::thread::JoinHandle;

use anyhow::{anyhow, Context, Result};
use crossbeam::channel::{Receiver, Sender};
use lineflow_messages::MessageKind;
use lineflow_recordings::image_codec::{ImageCompressor, ImageFormat};
use lineflow_recordings::views::ViewRenderer;
use lineflow_recordings::McapWriter;

/// One received message on its way to the writer.
pub struct Item {
    /// Index into the recorded topics.
    pub topic: usize,
    /// Receipt time, ns.
    pub log_time: u64,
    /// Capture time, ns.
    pub publish_time: u64,
    /// The message's CDR.
    pub cdr: Vec<u8>,
}

/// An image's compressed form (`None`: the message is written as it is), or why it could not be compressed.
type Packed = Result<Option<Vec<u8>>, String>;

/// An item with its place in the order of arrival and its packed form.
type Ready = (u64, Item, Packed);

/// How images are recorded: the format and the JPEG quality.
pub type Images = Option<(ImageFormat, u8)>;

/// The running pipeline.
pub struct Pipeline {
    next: u64,
    to_compress: Option<Sender<(u64, Item)>>,
    to_write: Option<Sender<Ready>>,
    threads: Vec<JoinHandle<()>>,
    writer: JoinHandle<Result<McapWriter>>,
}

/// Compression threads: the recorder's own thread only takes samples, so the cores left serve the encoders.
fn compressors() -> usize {
    std::thread::available_parallelism().map_or(1, |n| n.get()).clamp(1, 4)
}

impl Pipeline {
    /// Starts the threads. `kinds` are the recorded topics' names and kinds; `give_back` returns the message
    /// buffers to the sampling thread; `capacity` bounds each queue.
    ///
    /// # Errors
    /// When a thread cannot start.
    pub fn start(
        writer: McapWriter,
        topics: Vec<(String, MessageKind)>,
        renderer: ViewRenderer,
        images: Images,
        give_back: Sender<Vec<u8>>,
        capacity: usize,
    ) -> Result<Self> {
        let (to_write, ready) = crossbeam::channel::bounded::<Ready>(capacity);
        let kinds: Vec<MessageKind> = topics.iter().map(|t| t.1).collect();
        let mut threads = Vec::new();
        let mut to_compress = None;
        if let Some((format, quality)) = images {
            let (tx, rx) = crossbeam::channel::bounded::<(u64, Item)>(capacity);
            for k in 0..compressors() {
                let (rx, out, kinds) = (rx.clone(), to_write.clone(), kinds.clone());
                let thread = std::thread::Builder::new()
                    .name(format!("image-encoder-{k}"))
                    .spawn(move || compress_loop(&rx, &out, &kinds, format, quality))
                    .context("cannot start an image encoder thread")?;
                threads.push(thread);
            }
            to_compress = Some(tx);
        }
        let writer = std::thread::Builder::new()
            .name("mcap-writer".into())
            .spawn(move || write_loop(writer, &ready, &topics, renderer, &give_back))
            .context("cannot start the recording's writer thread")?;
        Ok(Self {
            next: 0,
            to_write: Some(to_write),
            to_compress,
            threads,
            writer,
        })
    }

    /// Hands a message on (waits while the queues are full).
    ///
    /// # Errors
    /// When the writer has stopped (a write failed).
    pub fn send(&mut self, item: Item) -> Result<()> {
        let seq = self.next;
        self.next += 1;
        let sent = match &self.to_compress {
            Some(tx) => tx.send((seq, item)).is_ok(),
            None => self.to_write.as_ref().is_some_and(|tx| tx.send((seq, item, Ok(None))).is_ok()),
        };
        sent.then_some(()).ok_or_else(|| anyhow!("the recording's writer stopped"))
    }

    /// Lets every queued message be written, and returns the writer for the last records.
    ///
    /// # Errors
    /// The writer's error (a write or a compression failed).
    pub fn finish(mut self) -> Result<McapWriter> {
        drop(self.to_compress.take());
        for t in self.threads.drain(..) {
            let _ = t.join();
        }
        drop(self.to_write.take());
        self.writer.join().map_err(|_| anyhow!("the recording's writer panicked"))?
    }
}

fn compress_loop(rx: &Receiver<(u64, Item)>, out: &Sender<Ready>, kinds: &[MessageKind], format: ImageFormat, quality: u8) {
    let mut compressor = ImageCompressor::default();
    for (seq, item) in rx {
        let packed = (kinds[item.topic] == MessageKind::Image)
            .then(|| {
                let mut packed = Vec::new();
                compressor.compress(&item.cdr, format, quality, &mut packed).map(|()| packed)
            })
            .transpose()
            .map_err(|e| format!("{e:#}"));
        if out.send((seq, item, packed)).is_err() {
            return;
        }
    }
}

fn write_loop(
    mut writer: McapWriter,
    ready: &Receiver<Ready>,
    topics: &[(String, MessageKind)],
    mut renderer: ViewRenderer,
    give_back: &Sender<Vec<u8>>,
) -> Result<McapWriter> {
    // Encoders finish out of order: hold what comes early until its turn.
    let mut early: BTreeMap<u64, (Item, Packed)> = BTreeMap::new();
    let mut next = 0u64;
    for (seq, item, packed) in ready {
        early.insert(seq, (item, packed));
        while let Some((item, packed)) = early.remove(&next) {
            next += 1;
            let (topic, kind) = &topics[item.topic];
            let packed = packed.map_err(|e| anyhow!("cannot compress an image of '{topic}': {e}"))?;
            writer.write(topic, item.log_time, item.publish_time, packed.as_deref().unwrap_or(&item.cdr))?;
            for (suffix, bytes) in renderer.render(*kind, &item.cdr) {
                writer.write(&format!("{topic}/{suffix}"), item.log_time, item.publish_time, &bytes)?;
            }
            let _ = give_back.try_send(item.cdr);
        }
    }
    Ok(writer)
}
