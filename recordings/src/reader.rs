//! Reading a recording from its file without holding it in memory: the summary by seeking to the footer, metadata
//! records by their index, messages streamed a chunk at a time. Memory follows the largest chunk (4 MB as the
//! recorder writes them) or record, never the file.
use std::collections::BTreeMap;
use std::fs::File;
use std::io::{BufReader, Read, Seek, SeekFrom};
use std::path::Path;

use anyhow::{Context, Result};
use mcap::sans_io::{LinearReadEvent, LinearReader, LinearReaderOptions, SummaryReadEvent, SummaryReader, SummaryReaderOptions};

/// Read buffer of the message stream: large enough for sequential throughput, small beside a chunk.
const READ_BUFFER: usize = 1 << 20;

/// The longest record (or decompressed chunk) believed in a file of `file_len` bytes. A streaming reader allocates
/// what a record's length field claims before it reads the record, so a damaged length (`lineflow bench fuzz`
/// found one claiming 232 GB) must be refused first. Chunks decompress to at most 16 times their file's size
/// here (the writer closes a chunk at 4 MiB of records, so 16 MiB covers a small file's chunks at any ratio).
fn record_length_limit(file_len: u64) -> usize {
    usize::try_from(file_len.saturating_mul(16).clamp(16 << 20, 4 << 30)).unwrap_or(usize::MAX)
}

fn options(path: &Path) -> LinearReaderOptions {
    let len = std::fs::metadata(path).map_or(0, |m| m.len());
    LinearReaderOptions::default()
        .with_skip_end_magic(true)
        .with_record_length_limit(record_length_limit(len))
}

/// The summary section of a finished file.
pub(crate) fn summary(path: &Path, file_len: u64) -> mcap::McapResult<Option<mcap::Summary>> {
    let mut file = File::open(path)?;
    let mut reader = SummaryReader::new_with_options(SummaryReaderOptions::default().with_file_size(file_len));
    while let Some(event) = reader.next_event() {
        match event? {
            SummaryReadEvent::ReadRequest(n) => {
                let read = file.read(reader.insert(n))?;
                reader.notify_read(read);
            }
            SummaryReadEvent::SeekRequest(to) => {
                let pos = file.seek(to)?;
                reader.notify_seeked(pos);
            }
        }
    }
    Ok(reader.finish())
}

/// The metadata records the summary indexes.
pub(crate) fn indexed_metadata(path: &Path, summary: &mcap::Summary) -> Result<BTreeMap<String, BTreeMap<String, String>>> {
    let mut file = File::open(path)?;
    let file_len = file.metadata()?.len();
    let mut out = BTreeMap::new();
    for index in &summary.metadata_indexes {
        // Checked before allocating: a damaged index may claim any length.
        if index.offset.checked_add(index.length).is_none_or(|end| end > file_len) {
            anyhow::bail!("the index of metadata '{}' points beyond the end of the file", index.name);
        }
        let len = usize::try_from(index.length).context("a metadata record longer than memory")?;
        let mut record = vec![0u8; len];
        file.seek(SeekFrom::Start(index.offset))?;
        file.read_exact(&mut record)
            .with_context(|| format!("metadata '{}' lies beyond the end of the file", index.name))?;
        let m = match mcap::read::LinearReader::sans_magic(&record).next() {
            Some(Ok(mcap::records::Record::Metadata(m))) => m,
            _ => anyhow::bail!("the index of metadata '{}' points at another record", index.name),
        };
        out.insert(m.name, m.metadata);
    }
    Ok(out)
}

/// Every metadata record, by a linear scan that skips over the chunks without decompressing them (an unfinished
/// file has no index). Stops quietly at the first damaged record: what came before it is what the file holds.
pub(crate) fn scanned_metadata(path: &Path) -> BTreeMap<String, BTreeMap<String, String>> {
    let mut out = BTreeMap::new();
    let Ok(file) = File::open(path) else {
        return out;
    };
    let mut source = BufReader::with_capacity(READ_BUFFER, file);
    let mut reader = LinearReader::new_with_options(options(path).with_emit_chunks(true));
    // A panic inside the mcap crate is a damaged record, as an error would be; what was read stays.
    let _ = catch_quietly(|| {
        while let Some(Ok(event)) = reader.next_event() {
            match event {
                LinearReadEvent::ReadRequest(n) => match source.read(reader.insert(n)) {
                    Ok(read) => reader.notify_read(read),
                    Err(_) => return,
                },
                LinearReadEvent::Record { data, opcode } => {
                    if let Ok(mcap::records::Record::Metadata(m)) = mcap::parse_record(opcode, data) {
                        out.insert(m.name, m.metadata);
                    }
                }
            }
        }
    });
    out
}

/// Messages in file order, read a buffer at a time. Lenient about a missing end (unfinished files), strict about
/// chunk checksums (corrupt files).
pub(crate) fn messages(path: &Path) -> std::io::Result<Guarded<mcap::io::MessageReader<BufReader<File>>>> {
    let file = BufReader::with_capacity(READ_BUFFER, File::open(path)?);
    let options = options(path).with_validate_chunk_crcs(true);
    Ok(Guarded(Some(mcap::io::MessageReader::new_with_options(file, options))))
}

/// Why a record could not be read.
#[derive(Debug)]
pub(crate) enum ReadError {
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
pub(crate) struct Guarded<I>(Option<I>);

impl<T, I: Iterator<Item = mcap::McapResult<T>>> Iterator for Guarded<I> {
    type Item = Result<T, ReadError>;

    fn next(&mut self) -> Option<Self::Item> {
        let inner = self.0.as_mut()?;
        match catch_quietly(|| inner.next()) {
            Some(item) => item.map(|r| r.map_err(ReadError::Mcap)),
            None => {
                self.0 = None;
                Some(Err(ReadError::Panicked))
            }
        }
    }
}

thread_local! {
    /// Set while [`catch_quietly`] runs on this thread.
    static QUIET: std::cell::Cell<bool> = const { std::cell::Cell::new(false) };
}

/// Runs `f`; a panic inside the mcap crate (a damaged or still growing file, see [`ReadError::Panicked`]) becomes
/// `None`, without the panic's message on the terminal: the caller reports it as an error of the file.
///
/// One panic hook, installed at the first call, stays silent while this thread is inside `f` and hands every other
/// panic to the hook it replaced. Swapping the process's hook around each call instead (the first version) cost a
/// global lock per message and, with two threads reading, could leave the silent hook in place for good.
pub(crate) fn catch_quietly<T>(f: impl FnOnce() -> T) -> Option<T> {
    static INSTALL: std::sync::Once = std::sync::Once::new();
    INSTALL.call_once(|| {
        let previous = std::panic::take_hook();
        std::panic::set_hook(Box::new(move |info| {
            if !QUIET.with(std::cell::Cell::get) {
                previous(info);
            }
        }));
    });
    let was = QUIET.with(|q| q.replace(true));
    let result = std::panic::catch_unwind(std::panic::AssertUnwindSafe(f));
    QUIET.with(|q| q.set(was));
    result.ok()
}
