//! The run registry: where a supervisor records its running run so that the CLI (`topics`, `echo`, `hz`) and nodes
//! in other languages can attach to it.
//!
//! Layout: `$LINEFLOW_STATE_DIR` (default `/tmp/lineflow`)`/runs/<id>/` holds `run.json` ([`RunRecord`]),
//! `graph.json` (the resolved graph) and `iox2/` (the run's iceoryx2 root).
use std::path::{Path, PathBuf};

use anyhow::{Context, Result};
use serde::{Deserialize, Serialize};

/// A run as the registry records it.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct RunRecord {
    /// Run id.
    pub id: String,
    /// iceoryx2 prefix.
    pub prefix: String,
    /// iceoryx2 root path.
    pub root: PathBuf,
    /// The resolved graph file.
    pub graph: PathBuf,
    /// The supervisor's process id.
    pub pid: u32,
    /// Start time, seconds since the Unix epoch.
    pub started_unix_s: u64,
    /// Whether the supervisor has ended the run.
    pub ended: bool,
    /// The run's output folder (absolute; absent in records of older versions).
    #[serde(default)]
    pub out: Option<PathBuf>,
}

/// The registry folder.
pub fn state_dir() -> PathBuf {
    std::env::var_os("LINEFLOW_STATE_DIR")
        .map(PathBuf::from)
        .unwrap_or_else(|| PathBuf::from("/tmp/lineflow"))
}

impl RunRecord {
    /// A new run writing into `out`, with a fresh id and prefix, its folder created.
    ///
    /// # Errors
    /// When the folder cannot be created.
    pub fn create(out: &Path) -> Result<Self> {
        let now = std::time::SystemTime::now()
            .duration_since(std::time::UNIX_EPOCH)
            .unwrap_or_default();
        let pid = std::process::id();
        // Unique per process and start instant; short, because iceoryx2 file names are length-limited.
        let id = format!("{:x}{:05x}", now.as_secs() & 0xff_ffff, (pid ^ now.subsec_micros()) & 0xfffff);
        let dir = state_dir().join("runs").join(&id);
        std::fs::create_dir_all(dir.join("iox2")).with_context(|| format!("cannot create run folder {}", dir.display()))?;
        let rec = Self {
            prefix: format!("lf{id}_"),
            root: dir.join("iox2"),
            graph: dir.join("graph.json"),
            id,
            pid,
            started_unix_s: now.as_secs(),
            ended: false,
            out: Some(std::path::absolute(out).unwrap_or_else(|_| out.to_owned())),
        };
        rec.save()?;
        Ok(rec)
    }

    /// The run's folder.
    pub fn dir(&self) -> PathBuf {
        state_dir().join("runs").join(&self.id)
    }

    /// Writes `run.json`.
    ///
    /// # Errors
    /// On I/O failure.
    pub fn save(&self) -> Result<()> {
        let path = self.dir().join("run.json");
        let tmp = path.with_extension("tmp");
        std::fs::write(&tmp, serde_json::to_vec_pretty(self)?)?;
        std::fs::rename(&tmp, &path).with_context(|| format!("cannot write {}", path.display()))
    }

    /// Whether the supervisor process still lives and has not ended the run.
    pub fn is_running(&self) -> bool {
        !self.ended && pid_alive(self.pid)
    }

    /// The run's resolved graph.
    ///
    /// # Errors
    /// When its file is missing or malformed.
    pub fn load_graph(&self) -> Result<crate::launch::Graph> {
        let bytes = std::fs::read(&self.graph).with_context(|| format!("run {}: graph file missing", self.id))?;
        serde_json::from_slice(&bytes).with_context(|| format!("run {}: malformed {}", self.id, self.graph.display()))
    }

    /// Asks the run's supervisor to stop as Ctrl-C does (SIGINT). Returns whether the signal was delivered.
    pub fn interrupt(&self) -> bool {
        // SAFETY: kill only sends a signal to the process the registry names.
        unsafe { libc::kill(self.pid as libc::pid_t, libc::SIGINT) == 0 }
    }

    /// Reads one run.
    ///
    /// # Errors
    /// When the run does not exist or its record is malformed.
    pub fn load(id: &str) -> Result<Self> {
        let path = state_dir().join("runs").join(id).join("run.json");
        let text = std::fs::read(&path).with_context(|| format!("no run '{id}' ({} not found)", path.display()))?;
        serde_json::from_slice(&text).with_context(|| format!("malformed {}", path.display()))
    }

    /// Every recorded run, newest first.
    pub fn list() -> Vec<Self> {
        let mut runs: Vec<Self> = std::fs::read_dir(state_dir().join("runs"))
            .into_iter()
            .flatten()
            .flatten()
            .filter_map(|e| std::fs::read(e.path().join("run.json")).ok())
            .filter_map(|t| serde_json::from_slice(&t).ok())
            .collect();
        runs.sort_by(|a: &Self, b: &Self| b.started_unix_s.cmp(&a.started_unix_s).then(b.id.cmp(&a.id)));
        runs
    }

    /// The run `id`, or the newest running one.
    ///
    /// # Errors
    /// When there is no such run, or none is running.
    pub fn find(id: Option<&str>) -> Result<Self> {
        match id {
            Some(id) => Self::load(id),
            None => Self::list()
                .into_iter()
                .find(Self::is_running)
                .context("no lineflow run is running (start one with `lineflow run`, or name one with --run ID)"),
        }
    }

    /// Removes the run's folder.
    pub fn remove(&self) {
        let _ = std::fs::remove_dir_all(self.dir());
    }
}

/// Whether a process exists.
pub fn pid_alive(pid: u32) -> bool {
    // SAFETY: kill with signal 0 only checks for existence and permission.
    let r = unsafe { libc::kill(pid as libc::pid_t, 0) };
    r == 0 || std::io::Error::last_os_error().raw_os_error() == Some(libc::EPERM)
}

/// Whether `path` is inside the registry (guards removals).
pub fn in_state_dir(path: &Path) -> bool {
    path.starts_with(state_dir())
}
