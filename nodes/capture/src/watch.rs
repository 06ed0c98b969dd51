//! Watching a folder that a tethered camera fills: a file is handed out once, when it is complete.
use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

/// Finds new image files in a folder and reports each once it is complete: its size has not changed for the
/// settle time and, for JPEG and PNG, it ends with the format's trailer. Writers that write in chunks or
/// pre-allocate are therefore never read half-written.
#[derive(Debug)]
pub struct Watcher {
    dir: PathBuf,
    settle: Duration,
    seen: BTreeSet<PathBuf>,
    pending: BTreeMap<PathBuf, (u64, Instant)>,
}

impl Watcher {
    /// Watches `dir`; `already` are files handed out before (they are not reported again).
    pub fn new(dir: &Path, settle: Duration, already: impl IntoIterator<Item = PathBuf>) -> Self {
        Self {
            dir: dir.to_owned(),
            settle,
            seen: already.into_iter().collect(),
            pending: BTreeMap::new(),
        }
    }

    /// Files that became complete since the last call, in natural file-name order.
    pub fn poll(&mut self) -> Vec<PathBuf> {
        let now = Instant::now();
        let Ok(files) = lineflow_formats::project::list_images(&self.dir) else {
            return Vec::new();
        };
        let mut ready = Vec::new();
        for f in files {
            if self.seen.contains(&f) {
                continue;
            }
            let Ok(size) = std::fs::metadata(&f).map(|m| m.len()) else {
                continue;
            };
            let entry = self.pending.entry(f.clone()).or_insert((size, now));
            if entry.0 != size {
                *entry = (size, now);
                continue;
            }
            if size == 0 || now.duration_since(entry.1) < self.settle {
                continue;
            }
            match std::fs::read(&f) {
                Ok(bytes) if crate::decode::looks_complete(&bytes) => {
                    self.pending.remove(&f);
                    self.seen.insert(f.clone());
                    ready.push(f);
                }
                // Stable but incomplete: the writer paused; the size change will reset the clock.
                _ => entry.1 = now,
            }
        }
        ready.sort_by(|a, b| {
            lineflow_formats::natural::natural_cmp(&lineflow_formats::project::file_name(a), &lineflow_formats::project::file_name(b))
        });
        ready
    }
}
