//! The environment a supervisor gives each node (documented in `docs/nodes.md`).
use std::path::PathBuf;

use anyhow::{Context, Result};

/// Run id.
pub const RUN_ID: &str = "LINEFLOW_RUN_ID";
/// iceoryx2 prefix of the run's shared-memory files.
pub const IOX2_PREFIX: &str = "LINEFLOW_IOX2_PREFIX";
/// iceoryx2 root path of the run's service and node files.
pub const IOX2_ROOT: &str = "LINEFLOW_IOX2_ROOT";
/// Resolved graph (JSON).
pub const GRAPH: &str = "LINEFLOW_GRAPH";
/// This node's name in the graph.
pub const NODE: &str = "LINEFLOW_NODE";
/// Output folder of the run.
pub const OUT: &str = "LINEFLOW_OUT";
/// Set to 1: print the node's ports as JSON and exit.
pub const DESCRIBE: &str = "LINEFLOW_DESCRIBE";
/// How often this node was restarted (absent or 0 at the first start).
pub const RESTART: &str = "LINEFLOW_RESTART";
/// After a restart: `topic=NEXT@REPLAY,...` per input: NEXT is the frame after the last one the previous instance
/// consumed; frames from REPLAY on are processed again (their outputs may have been lost with the old process).
pub const RESUME: &str = "LINEFLOW_RESUME";
/// Seconds a node waits for its peers to connect (default 30).
pub const CONNECT_TIMEOUT_S: &str = "LINEFLOW_CONNECT_TIMEOUT_S";

/// What a node learns from its environment.
#[derive(Debug, Clone)]
pub struct RunEnv {
    /// Run id.
    pub run_id: String,
    /// iceoryx2 prefix.
    pub prefix: String,
    /// iceoryx2 root path.
    pub root: PathBuf,
    /// Resolved graph file.
    pub graph: PathBuf,
    /// Node name.
    pub node: String,
    /// Output folder.
    pub out: PathBuf,
    /// Restart count.
    pub restart: u32,
    /// Resume points after a restart: (topic, next frame, replay from).
    pub resume: Vec<(String, u64, u64)>,
}

fn var(name: &str) -> Result<String> {
    std::env::var(name).with_context(|| format!("{name} is not set: stage binaries are started by `lineflow run` (see docs/nodes.md)"))
}

impl RunEnv {
    /// Reads the environment.
    ///
    /// # Errors
    /// When a variable is missing or malformed.
    pub fn from_env() -> Result<Self> {
        let resume = std::env::var(RESUME)
            .unwrap_or_default()
            .split(',')
            .filter(|s| !s.is_empty())
            .map(|kv| {
                let (k, v) = kv.rsplit_once('=').with_context(|| format!("{RESUME}: malformed entry '{kv}'"))?;
                let (next, replay) = v.split_once('@').unwrap_or((v, v));
                let num = |s: &str| s.parse::<u64>().with_context(|| format!("{RESUME}: '{s}' is not a frame number"));
                Ok((k.to_owned(), num(next)?, num(replay)?))
            })
            .collect::<Result<_>>()?;
        Ok(Self {
            run_id: var(RUN_ID)?,
            prefix: var(IOX2_PREFIX)?,
            root: var(IOX2_ROOT)?.into(),
            graph: var(GRAPH)?.into(),
            node: var(NODE)?,
            out: std::env::var(OUT).unwrap_or_else(|_| ".".into()).into(),
            restart: std::env::var(RESTART).ok().and_then(|v| v.parse().ok()).unwrap_or(0),
            resume,
        })
    }

    /// Whether the node should only describe its ports.
    pub fn describe_requested() -> bool {
        std::env::var(DESCRIBE).is_ok_and(|v| v == "1") || std::env::args().any(|a| a == "--describe")
    }
}
