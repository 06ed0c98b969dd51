//! Launch graphs: the TOML files in `launch/`, their validation, and the resolved graph handed to every node.
//!
//! A launch file lists nodes and edges (`docs/launch.md`). [`load`] parses it, applies `--set` overrides,
//! resolves executables and payload sizes and checks everything that can be checked before a process starts;
//! every error names the file and the entry.

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

use lineflow_messages::image::{ImageFormat, DEFAULT_JPEG_QUALITY};
use lineflow_messages::MessageKind;
use serde::{Deserialize, Serialize};

use lineflow_messages::checksum::fnv1a64;

/// How long a lossless publisher waits for a full subscriber before dropping the sample, by default. Generous:
/// stages working on 12-MP frames take seconds each and back-pressure adds up along a chain, while a crashed
/// subscriber does not need it (the supervisor reaps dead nodes before restarting one, which frees the publisher).
pub const DEFAULT_TIMEOUT_MS: u64 = 60_000;

/// What may go wrong with a launch file.
#[derive(Debug, thiserror::Error)]
pub enum LaunchError {
    /// The file cannot be read.
    #[error("{path}: cannot read: {source}")]
    Read {
        /// The file.
        path: PathBuf,
        /// The cause.
        source: std::io::Error,
    },
    /// The TOML does not parse or has unknown keys.
    #[error("{path}: {message}")]
    Parse {
        /// The file.
        path: PathBuf,
        /// The parser's message, with line and column.
        message: String,
    },
    /// The graph is inconsistent.
    #[error("{path}: {entry}: {message}")]
    Invalid {
        /// The file.
        path: PathBuf,
        /// The entry at fault, e.g. `edge 'images'`.
        entry: String,
        /// What is wrong.
        message: String,
    },
}

/// How a node is restarted when it fails.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "kebab-case")]
pub enum RestartPolicy {
    /// A failed node fails the run.
    #[default]
    Never,
    /// A node that exits non-zero or dies of a signal is started again, up to `max_restarts` times.
    OnFailure,
}

/// What happens when a subscriber's buffer is full.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "kebab-case")]
pub enum EdgePolicy {
    /// The publisher waits (up to the edge's `timeout_ms`, then the sample is dropped and counted).
    #[default]
    Lossless,
    /// The oldest unread sample is overwritten (live previews).
    Latest,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct LaunchFile {
    #[serde(default)]
    graph: GraphMeta,
    #[serde(default)]
    node: Vec<NodeEntry>,
    #[serde(default)]
    edge: Vec<EdgeEntry>,
    /// Settings of the recorder; `enabled = false` turns it off, the other keys are its parameters.
    #[serde(default)]
    record: toml::Table,
    /// Settings of the live viewer; `enabled = true` adds it, the other keys are its parameters.
    #[serde(default)]
    view: toml::Table,
    /// The hosts of a graph on several machines and their Zenoh endpoints (`docs/hosts.md`).
    #[serde(default)]
    hosts: BTreeMap<String, HostEntry>,
    /// Settings of the bridges between hosts ([`BridgeSettings`], read once the `--set`s are applied).
    #[serde(default)]
    bridge: toml::Table,
}

#[derive(Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
struct HostEntry {
    #[serde(default)]
    listen: Vec<String>,
    #[serde(default)]
    connect: Vec<String>,
    certificate: Option<String>,
    key: Option<String>,
    common_name: Option<String>,
}

/// Name of the recorder node the supervisor adds to every graph (unless `[record] enabled = false`).
pub const RECORDER: &str = "recorder";
/// Stage of the recorder node.
pub const RECORDER_STAGE: &str = "record";
/// Name of the live viewer node the supervisor adds to a graph with `[view] enabled = true` (`lineflow run --view`).
pub const VIEWER: &str = "viewer";
/// Stage of the live viewer node.
pub const VIEWER_STAGE: &str = "view";

/// Whether a node is one the loader adds to watch the whole run (the recorder, the viewer): it subscribes to every
/// topic and does no work of the graph's own.
pub fn is_observer(node: &str) -> bool {
    node == RECORDER || node == VIEWER
}

#[derive(Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
struct GraphMeta {
    name: Option<String>,
    description: Option<String>,
    /// camera.toml whose size sets the default payload of image topics.
    camera: Option<String>,
    /// Seconds every node has to connect its ports before the run ends with an error naming those that did not.
    connect_timeout_s: Option<f64>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct NodeEntry {
    name: String,
    stage: Option<String>,
    #[serde(rename = "impl")]
    implementation: Option<String>,
    executable: Option<String>,
    #[serde(default)]
    args: Vec<String>,
    #[serde(default)]
    params: toml::Table,
    #[serde(default)]
    restart: RestartPolicy,
    #[serde(default = "default_max_restarts")]
    max_restarts: u32,
    #[serde(default = "default_backoff_ms")]
    backoff_ms: u64,
    #[serde(default)]
    remap: BTreeMap<String, String>,
    /// The host the node runs on (`[hosts]`); [`DEFAULT_HOST`] when not given.
    host: Option<String>,
}

fn default_max_restarts() -> u32 {
    3
}
fn default_backoff_ms() -> u64 {
    200
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct EdgeEntry {
    topic: String,
    #[serde(rename = "type")]
    message: String,
    from: String,
    to: Vec<String>,
    #[serde(default)]
    policy: EdgePolicy,
    max_payload_bytes: Option<u64>,
    depth: Option<usize>,
    history: Option<usize>,
    timeout_ms: Option<u64>,
}

/// A node of a resolved graph.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct NodeSpec {
    /// Unique name.
    pub name: String,
    /// Position in the graph, used as its event id.
    pub index: u32,
    /// Stage name, when the node is a stage binary.
    pub stage: Option<String>,
    /// Implementation, passed as the `impl` parameter.
    pub implementation: Option<String>,
    /// Program and arguments.
    pub command: Vec<String>,
    /// Parameters (JSON object), `impl` included.
    pub params: serde_json::Map<String, serde_json::Value>,
    /// Restart policy.
    pub restart: RestartPolicy,
    /// Restarts allowed under `on-failure`.
    pub max_restarts: u32,
    /// Delay before a restart, doubled each time.
    pub backoff_ms: u64,
    /// Port name to topic name.
    pub remap: BTreeMap<String, String>,
    /// The host it runs on.
    #[serde(default = "default_host")]
    pub host: String,
}

fn default_host() -> String {
    DEFAULT_HOST.into()
}

impl NodeSpec {
    /// The topic a port of this node is wired to.
    pub fn topic_of<'a>(&'a self, port: &'a str) -> &'a str {
        self.remap.get(port).map(String::as_str).unwrap_or(port)
    }
}

/// An edge (topic) of a resolved graph.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct EdgeSpec {
    /// Topic name; also the iceoryx2 service name.
    pub topic: String,
    /// Message type name.
    pub message: String,
    /// Publishing node.
    pub from: String,
    /// Subscribing nodes.
    pub to: Vec<String>,
    /// Flow control.
    pub policy: EdgePolicy,
    /// Initial payload size in bytes (larger samples grow the segment).
    pub max_payload_bytes: u64,
    /// Subscriber buffer depth.
    pub depth: usize,
    /// Samples kept for late or restarted subscribers.
    pub history: usize,
    /// How long a lossless publisher waits for a full subscriber before dropping, milliseconds.
    pub timeout_ms: u64,
}

impl EdgeSpec {
    /// The message kind (validated at load).
    pub fn kind(&self) -> MessageKind {
        MessageKind::from_name(&self.message).expect("validated at load")
    }
    /// Samples the publisher pre-allocates: every subscriber's buffer and borrows, the history, the loans.
    pub fn chunks(&self) -> u64 {
        (self.to.len() as u64 + 1) * (self.depth as u64 + 2) + self.history as u64 + 2
    }
    /// Worst-case shared memory of this edge in bytes.
    pub fn shm_bytes(&self) -> u64 {
        self.chunks() * (self.max_payload_bytes + self.kind().header_size() as u64 + 64)
    }
}

/// A validated launch graph.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct Graph {
    /// Graph name.
    pub name: String,
    /// Description.
    pub description: String,
    /// The launch file it came from.
    pub source: PathBuf,
    /// The launch file's text, for the recording's metadata.
    pub text: String,
    /// Nodes in file order.
    pub nodes: Vec<NodeSpec>,
    /// Edges in file order.
    pub edges: Vec<EdgeSpec>,
    /// Seconds every node has to connect its ports (`[graph] connect_timeout_s`; 60 when not given).
    #[serde(default)]
    pub connect_timeout_s: Option<f64>,
    /// Nodes of the launch file that a replay's player stands in for (`lineflow replay --rerun`); stages that need
    /// a source's parameters (eval regenerating the synthetic scene) find them here.
    #[serde(default)]
    pub replaced: Vec<NodeSpec>,
    /// The hosts of a graph on several machines (`[hosts]`); empty on one.
    #[serde(default)]
    pub hosts: Vec<HostSpec>,
    /// The host whose part of the graph this is ([`hosts::part`](crate::hosts::part)).
    #[serde(default = "default_host")]
    pub host: String,
    /// Settings of the bridges between hosts (`[bridge]`).
    #[serde(default)]
    pub bridge: BridgeSettings,
    /// Hash of the whole graph on every host ([`graph_hash`]): hosts of different graphs refuse each other.
    #[serde(default)]
    pub hash: String,
}

impl Graph {
    /// A node by name.
    pub fn node(&self, name: &str) -> Option<&NodeSpec> {
        self.nodes.iter().find(|n| n.name == name)
    }
    /// The edge a node publishes on `topic`.
    pub fn output_edge(&self, node: &str, topic: &str) -> Option<&EdgeSpec> {
        self.edges.iter().find(|e| e.topic == topic && e.from == node)
    }
    /// The edge that delivers `topic` to `node`.
    pub fn input_edge(&self, node: &str, topic: &str) -> Option<&EdgeSpec> {
        self.edges.iter().find(|e| e.topic == topic && e.to.iter().any(|t| t == node))
    }
    /// Whether a node has no inputs.
    pub fn is_source(&self, node: &str) -> bool {
        !self.edges.iter().any(|e| e.to.iter().any(|t| t == node))
    }
    /// Whether a node has no outputs.
    pub fn is_sink(&self, node: &str) -> bool {
        !self.edges.iter().any(|e| e.from == node)
    }
    /// Worst-case shared memory of the whole graph in bytes.
    pub fn shm_bytes(&self) -> u64 {
        self.edges.iter().map(EdgeSpec::shm_bytes).sum()
    }
}

// Graphs on several hosts (`docs/hosts.md`; each host's part: `crate::hosts`).

/// The host of nodes that name none, and the one `lineflow run` runs without `--host`.
pub const DEFAULT_HOST: &str = "main";
/// Name of the bridge node the loader adds to a host's part of a graph on several hosts.
pub const BRIDGE: &str = "bridge";
/// A host of a graph and its Zenoh endpoints (`[hosts.NAME]`).
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct HostSpec {
    /// Host name, as nodes name it in `host`.
    pub name: String,
    /// Endpoints this host's bridge listens on (`tcp/ADDRESS:PORT`).
    pub listen: Vec<String>,
    /// Endpoints it connects to; empty: every other host's `listen`.
    pub connect: Vec<String>,
    /// Its TLS certificate (PEM) as the launch file names it, relative to the launch file's folder (`[bridge.tls]`).
    #[serde(default)]
    pub certificate: Option<String>,
    /// The certificate's private key (PEM, PKCS#8).
    #[serde(default)]
    pub key: Option<String>,
    /// The common name its certificate carries, which access control admits; default the host's name.
    #[serde(default)]
    pub common_name: String,
}

/// `[bridge.tls]`: the bridges talk TLS with certificates both ways (mutual TLS), and admit only the hosts of the graph.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TlsSettings {
    /// The certificate (PEM) of the authority that signed every host's certificate, relative to the launch file's
    /// folder.
    pub ca: String,
}

/// The `[bridge]` table: settings of every host's bridge.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct BridgeSettings {
    /// Find the other hosts by Zenoh's multicast scouting besides the explicit endpoints.
    pub scouting: bool,
    /// How images cross: `raw` (the pixels as they are, the default: no encoding cost, the pace of a fast link),
    /// `png` (lossless: a run's bytes stay those of one host, a half of the bytes for the encoders' time) or `jpeg`
    /// (lossy, smallest, slowest).
    pub images: ImageFormat,
    /// JPEG quality (1-100) of `images = "jpeg"`.
    pub jpeg_quality: u8,
    /// TLS and access control (`[bridge.tls]`); without it the bridges talk plain TCP.
    pub tls: Option<TlsSettings>,
    /// Whether a host's supervisor restarts its bridge when it fails (`never` by default: a bridge that fails
    /// ends the run, as any node). With `on-failure` the lossless edges between hosts resume with nothing lost:
    /// the sending bridge keeps its last messages to re-send them, and the edges into it keep a history.
    pub restart: RestartPolicy,
    /// Restarts allowed with `restart = "on-failure"`.
    pub max_restarts: u32,
    /// The wait before the first restart, doubled for each further one.
    pub backoff_ms: u64,
}

impl Default for BridgeSettings {
    fn default() -> Self {
        Self {
            scouting: false,
            images: ImageFormat::Raw,
            jpeg_quality: DEFAULT_JPEG_QUALITY,
            tls: None,
            restart: RestartPolicy::Never,
            max_restarts: default_max_restarts(),
            backoff_ms: default_backoff_ms(),
        }
    }
}

/// The `[hosts]` table checked: names well-formed, endpoints well-formed, somebody listening when there are
/// several hosts. `used` are the hosts the nodes name.
///
/// # Errors
/// The entry at fault and what is wrong, as the loader reports it.
pub fn check_hosts(hosts: &[HostSpec], used: &BTreeSet<String>, tls: bool) -> Result<(), (String, String)> {
    let mut common_names = BTreeSet::new();
    for h in hosts {
        let entry = format!("[hosts.{}]", h.name);
        if h.name.is_empty() || !h.name.chars().all(|c| c.is_ascii_alphanumeric() || c == '_' || c == '-') {
            return Err((entry, "a host name is non-empty ASCII letters, digits, '_' or '-'".into()));
        }
        for e in h.listen.iter().chain(&h.connect) {
            check_endpoint(e, tls).map_err(|m| (entry.clone(), m))?;
        }
        if tls && (h.certificate.is_none() || h.key.is_none()) {
            return Err((
                entry,
                "with [bridge.tls] every host needs `certificate` and `key` (PEM files, signed by the `ca`)".into(),
            ));
        }
        if !tls && (h.certificate.is_some() || h.key.is_some()) {
            return Err((
                entry,
                "`certificate` and `key` need [bridge.tls] with the `ca` that signed them".into(),
            ));
        }
        if !common_names.insert(&h.common_name) {
            return Err((entry, format!("common name '{}' is another host's too", h.common_name)));
        }
    }
    for name in used {
        if tls && !hosts.iter().any(|h| &h.name == name) {
            return Err((
                format!("host '{name}'"),
                format!("with [bridge.tls] every host needs its certificate: add [hosts.{name}] with `certificate` and `key`"),
            ));
        }
        if name != DEFAULT_HOST && !hosts.iter().any(|h| &h.name == name) {
            let known: Vec<&str> = hosts.iter().map(|h| h.name.as_str()).collect();
            return Err((
                format!("host '{name}'"),
                format!(
                    "not declared: add [hosts.{name}] with its `listen` or `connect` endpoints (declared: {})",
                    if known.is_empty() { "none".into() } else { known.join(", ") }
                ),
            ));
        }
    }
    let several = used.len() > 1 || used.iter().any(|h| h != DEFAULT_HOST);
    if several && !hosts.iter().any(|h| !h.listen.is_empty()) {
        return Err((
            "[hosts]".into(),
            "a graph on several hosts needs `listen` on at least one host, e.g. listen = [\"tcp/127.0.0.1:7447\"]".into(),
        ));
    }
    Ok(())
}

/// A Zenoh endpoint the bridges can use: `tcp/ADDRESS:PORT`, or `tls/ADDRESS:PORT` with `[bridge.tls]` (and then only
/// that: a plain endpoint would bypass it).
fn check_endpoint(e: &str, tls: bool) -> Result<(), String> {
    let scheme = if tls { "tls" } else { "tcp" };
    let bad = || {
        let hint = if e.starts_with("tls/") {
            " (tls/ endpoints need [bridge.tls])"
        } else if tls && e.starts_with("tcp/") {
            " (with [bridge.tls] every endpoint is tls/)"
        } else {
            ""
        };
        format!("endpoint '{e}': expected {scheme}/ADDRESS:PORT, e.g. {scheme}/127.0.0.1:7447{hint}")
    };
    let rest = e.strip_prefix(&format!("{scheme}/")).ok_or_else(bad)?;
    let (address, port) = rest.rsplit_once(':').ok_or_else(bad)?;
    if address.is_empty() || port.parse::<u16>().is_err() {
        return Err(bad());
    }
    Ok(())
}

/// The hash of a whole graph: every node's name, host, stage, implementation, parameters and wiring, every
/// edge's topic, type, ends and policy, and the hosts. Not the executables' paths, which differ between machines.
pub fn graph_hash(nodes: &[NodeSpec], edges: &[EdgeSpec], hosts: &[HostSpec]) -> String {
    let nodes: Vec<_> = nodes
        .iter()
        .map(|n| (&n.name, &n.host, &n.stage, &n.implementation, &n.params, &n.remap))
        .collect();
    let edges: Vec<_> = edges
        .iter()
        .map(|e| (&e.topic, &e.message, &e.from, &e.to, e.policy, e.depth, e.history))
        .collect();
    let text = serde_json::to_string(&(nodes, edges, hosts)).expect("plain data serializes");
    format!("{:016x}", fnv1a64(text.as_bytes()))
}

/// Where stage binaries (`lineflow-<stage>`) are looked up.
#[derive(Debug, Clone)]
pub struct Resolver {
    /// Folder holding the stage binaries, normally the folder of the running `lineflow`.
    pub bin_dir: PathBuf,
}

impl Resolver {
    /// The binary of a stage, `lineflow-<stage>`.
    ///
    /// # Errors
    /// A message naming the missing binary.
    pub fn stage(&self, stage: &str) -> Result<String, String> {
        let exe = self.bin_dir.join(format!("lineflow-{stage}"));
        if !exe.is_file() {
            return Err(format!(
                "stage '{stage}' has no binary {} (build it with `cargo build`)",
                exe.display()
            ));
        }
        Ok(exe.display().to_string())
    }

    /// Stage binaries beside the running executable.
    pub fn beside_current_exe() -> Self {
        let bin_dir = std::env::current_exe()
            .ok()
            .and_then(|p| p.parent().map(Path::to_path_buf))
            .unwrap_or_else(|| PathBuf::from("."));
        Self { bin_dir }
    }
}

/// Reads, overrides and validates a launch file.
///
/// `overrides` are `NODE.PARAM=VALUE` strings (`--set`); a value parses as TOML (`3`, `true`, `"x"`, `[1,2]`) and
/// falls back to a plain string.
///
/// # Errors
/// A [`LaunchError`] naming the file and the entry at fault.
pub fn load(path: &Path, overrides: &[String], resolver: &Resolver) -> Result<Graph, LaunchError> {
    let text = std::fs::read_to_string(path).map_err(|source| LaunchError::Read {
        path: path.to_owned(),
        source,
    })?;
    parse(path, &text, overrides, resolver)
}

/// [`load`] on text already read.
///
/// # Errors
/// A [`LaunchError`] naming the file and the entry at fault.
pub fn parse(path: &Path, text: &str, overrides: &[String], resolver: &Resolver) -> Result<Graph, LaunchError> {
    let invalid = |(entry, message): Invalid| LaunchError::Invalid {
        path: path.to_owned(),
        entry,
        message,
    };
    let mut file: LaunchFile = toml::from_str(text).map_err(|e| LaunchError::Parse {
        path: path.to_owned(),
        message: e.to_string().trim().replace('\n', " "),
    })?;
    let base = path.parent().unwrap_or(Path::new(".")).to_path_buf();
    for item in overrides {
        apply_override(&mut file, item).map_err(|m| invalid((format!("--set {item}"), m)))?;
    }
    let names = node_names(&file).map_err(invalid)?;
    let mut nodes = Vec::new();
    for (index, n) in file.node.iter().enumerate() {
        nodes.push(node_spec(index, n, &base, resolver).map_err(invalid)?);
    }
    let record = observer_table(&file.record, "[record]", true).map_err(invalid)?;
    let view = observer_table(&file.view, "[view]", false).map_err(invalid)?;
    if let Some(t) = file.graph.connect_timeout_s.filter(|t| !(t.is_finite() && *t > 0.0 && *t < 1e9)) {
        return Err(invalid((
            "[graph]".into(),
            format!("`connect_timeout_s` must be a positive number of seconds, got {t}"),
        )));
    }
    let camera_bytes = default_image_bytes(&file, &base);
    let mut edges: Vec<EdgeSpec> = Vec::new();
    let mut topics = BTreeSet::new();
    for e in &file.edge {
        if !topics.insert(e.topic.clone()) {
            let entry = format!("edge '{}'", e.topic);
            return Err(invalid((
                entry,
                "duplicate topic: each topic has one edge with one publisher".into(),
            )));
        }
        edges.push(edge_spec(e, &names, &nodes, record.is_some(), &camera_bytes).map_err(invalid)?);
    }
    for (name, stage, table, params) in [(RECORDER, RECORDER_STAGE, "record", record), (VIEWER, VIEWER_STAGE, "view", view)] {
        let Some(mut params) = params else { continue };
        // Not `host`: the viewer's `host` is the address its server binds.
        let host = match params.remove("on_host") {
            None => DEFAULT_HOST.to_owned(),
            Some(toml::Value::String(h)) => h,
            Some(v) => return Err(invalid((format!("[{table}]"), format!("`on_host` must be a host name, got {v}")))),
        };
        if names.contains(name) {
            return Err(invalid((
                format!("node '{name}'"),
                format!("the name '{name}' is reserved; rename the node or set [{table}] enabled = false"),
            )));
        }
        let mut spec = observer_spec(name, stage, params, nodes.len(), resolver).map_err(|(_, m)| invalid((format!("[{table}]"), m)))?;
        spec.host = host;
        nodes.push(spec);
        for e in &mut edges {
            e.to.push(name.into());
        }
    }
    let hosts: Vec<HostSpec> = file
        .hosts
        .iter()
        .map(|(name, h)| HostSpec {
            name: name.clone(),
            listen: h.listen.clone(),
            connect: h.connect.clone(),
            certificate: h.certificate.clone(),
            key: h.key.clone(),
            common_name: h.common_name.clone().unwrap_or_else(|| name.clone()),
        })
        .collect();
    let bridge = bridge_settings(&file.bridge).map_err(invalid)?;
    check_hosts(&hosts, &nodes.iter().map(|n| n.host.clone()).collect(), bridge.tls.is_some()).map_err(invalid)?;
    let hash = graph_hash(&nodes, &edges, &hosts);
    Ok(Graph {
        name: file
            .graph
            .name
            .clone()
            .unwrap_or_else(|| path.file_stem().map(|s| s.to_string_lossy().into_owned()).unwrap_or_default()),
        description: file.graph.description.clone().unwrap_or_default(),
        source: path.to_owned(),
        text: text.to_owned(),
        connect_timeout_s: file.graph.connect_timeout_s,
        nodes,
        edges,
        replaced: Vec::new(),
        hosts,
        host: DEFAULT_HOST.into(),
        bridge,
        hash,
    })
}

/// An entry of the launch file (`node 'x'`, `edge 't'`, `[record]`) and what is wrong with it.
type Invalid = (String, String);

/// The `[bridge]` table read and checked.
fn bridge_settings(table: &toml::Table) -> Result<BridgeSettings, Invalid> {
    let entry = || "[bridge]".to_owned();
    let s = BridgeSettings::deserialize(toml::Value::Table(table.clone())).map_err(|e| (entry(), e.message().to_owned()))?;
    if !(1..=100).contains(&s.jpeg_quality) {
        return Err((entry(), format!("`jpeg_quality` must be 1 to 100, got {}", s.jpeg_quality)));
    }
    Ok(s)
}

/// The node names, checked: well-formed, unique, at least one.
fn node_names(file: &LaunchFile) -> Result<BTreeSet<String>, Invalid> {
    let mut names = BTreeSet::new();
    for n in &file.node {
        let entry = format!("node '{}'", n.name);
        if n.name.is_empty() || !n.name.chars().all(|c| c.is_ascii_alphanumeric() || c == '_' || c == '-') {
            return Err((entry, "a node name is non-empty ASCII letters, digits, '_' or '-'".into()));
        }
        if !names.insert(n.name.clone()) {
            return Err((entry, "duplicate node name".into()));
        }
        if n.name == BRIDGE {
            return Err((
                entry,
                format!("the name '{BRIDGE}' is reserved for the bridge between hosts; rename the node"),
            ));
        }
    }
    if file.node.is_empty() {
        return Err(("graph".into(), "no [[node]] entries".into()));
    }
    Ok(names)
}

/// A `[[node]]` entry as the supervisor runs it: its command (the stage's binary or an executable found from the
/// launch file's folder) and its parameters with `impl`.
fn node_spec(index: usize, n: &NodeEntry, base: &Path, resolver: &Resolver) -> Result<NodeSpec, Invalid> {
    let entry = format!("node '{}'", n.name);
    let command = match (&n.stage, &n.executable) {
        (Some(stage), None) => {
            let exe = resolver.stage(stage).map_err(|m| (entry.clone(), m))?;
            std::iter::once(exe).chain(n.args.iter().cloned()).collect()
        }
        (None, Some(exe)) => {
            let found = find_executable(exe, base).ok_or_else(|| {
                let where_ = base.display();
                (
                    entry.clone(),
                    format!("executable '{exe}' does not exist (relative paths are taken from {where_})"),
                )
            })?;
            std::iter::once(found).chain(n.args.iter().cloned()).collect()
        }
        _ => return Err((entry, "give exactly one of `stage` or `executable`".into())),
    };
    let mut params = serde_json::Map::new();
    for (k, v) in &n.params {
        let value = serde_json::to_value(v).map_err(|e| (entry.clone(), format!("param '{k}': {e}")))?;
        params.insert(k.clone(), value);
    }
    if let Some(i) = &n.implementation {
        params.insert("impl".into(), serde_json::Value::String(i.clone()));
    }
    Ok(NodeSpec {
        name: n.name.clone(),
        index: index as u32,
        stage: n.stage.clone(),
        implementation: n.implementation.clone(),
        command,
        params,
        restart: n.restart,
        max_restarts: n.max_restarts,
        backoff_ms: n.backoff_ms,
        remap: n.remap.clone(),
        host: n.host.clone().unwrap_or_else(default_host),
    })
}

/// An `[[edge]]` entry, checked against the nodes (`names`; `nodes` for the `gt/*` rule): topic, message type,
/// publisher and subscribers, queue sizes, and the payload bound (images from the camera, `camera_bytes`).
fn edge_spec(
    e: &EdgeEntry,
    names: &BTreeSet<String>,
    nodes: &[NodeSpec],
    recording: bool,
    camera_bytes: &Result<Option<u64>, String>,
) -> Result<EdgeSpec, Invalid> {
    let entry = format!("edge '{}'", e.topic);
    let fail = |message: String| Err((entry.clone(), message));
    if e.topic.is_empty() || !e.topic.is_ascii() || e.topic.starts_with("lineflow/") || e.topic.len() > 200 {
        return fail("a topic is 1-200 ASCII characters and does not start with 'lineflow/'".into());
    }
    let Some(kind) = MessageKind::from_name(&e.message) else {
        let known: Vec<_> = MessageKind::ALL.iter().map(|k| k.name()).collect();
        return fail(format!("unknown message type '{}' (known: {})", e.message, known.join(", ")));
    };
    if !names.contains(&e.from) {
        return fail(format!("publisher '{}' is not a node", e.from));
    }
    // With the recorder on, a topic may be recorded only.
    if e.to.is_empty() && !recording {
        return fail("no subscribers (`to` is empty) and the recorder is off".into());
    }
    for t in &e.to {
        if !names.contains(t) {
            return fail(format!("subscriber '{t}' is not a node"));
        }
        if t == &e.from {
            return fail(format!("node '{t}' subscribes to its own output"));
        }
    }
    if e.topic.starts_with("gt/") {
        let reader = |t: &&String| nodes.iter().any(|n| &n.name == *t && n.stage.as_deref() != Some("eval"));
        if let Some(t) = e.to.iter().find(reader) {
            return fail(format!("node '{t}' subscribes to ground truth; only `eval` may read gt/* topics"));
        }
    }
    let depth = e.depth.unwrap_or(4);
    let history = e.history.unwrap_or(if kind.latched() { 1 } else { 0 });
    if !(1..=1024).contains(&depth) {
        return fail(format!("depth must be in 1..=1024, got {depth}"));
    }
    if history > 1024 {
        return fail(format!("history must be in 0..=1024, got {history}"));
    }
    let max_payload_bytes = match (e.max_payload_bytes, kind) {
        (Some(b), _) => b,
        // 0: the producer declares the size through --describe (see `resolve_payloads`).
        (None, MessageKind::Image) => camera_bytes.clone().map_err(|m| (entry.clone(), m))?.unwrap_or(0),
        (None, _) => 1 << 20,
    };
    Ok(EdgeSpec {
        topic: e.topic.clone(),
        message: kind.name().into(),
        from: e.from.clone(),
        to: e.to.clone(),
        policy: e.policy,
        max_payload_bytes,
        depth: depth.max(history),
        history,
        timeout_ms: e.timeout_ms.unwrap_or(DEFAULT_TIMEOUT_MS),
    })
}

/// The parameters of an observer's table (`[record]`, `[view]`) less `enabled`, or `None` when it is off.
fn observer_table(table: &toml::Table, entry: &str, on_by_default: bool) -> Result<Option<toml::Table>, Invalid> {
    let mut params = table.clone();
    match params.remove("enabled") {
        None if on_by_default => Ok(Some(params)),
        None | Some(toml::Value::Boolean(false)) => Ok(None),
        Some(toml::Value::Boolean(true)) => Ok(Some(params)),
        Some(v) => Err((entry.into(), format!("`enabled` must be true or false, got {v}"))),
    }
}

/// A node the loader adds to watch the whole run (the recorder, the viewer), with its table as its parameters.
fn observer_spec(name: &str, stage: &str, table: toml::Table, index: usize, resolver: &Resolver) -> Result<NodeSpec, Invalid> {
    let mut params = serde_json::Map::new();
    for (k, v) in table {
        let value = serde_json::to_value(&v).map_err(|e| (String::new(), format!("{k}: {e}")))?;
        params.insert(k, value);
    }
    added_node(name, stage, params, index, resolver).map_err(|m| (String::new(), m))
}

/// A node the loader adds to a graph (the recorder, the viewer, a host's bridge): a stage binary with `params`,
/// never restarted, on the default host.
///
/// # Errors
/// A missing stage binary.
pub(crate) fn added_node(
    name: &str,
    stage: &str,
    params: serde_json::Map<String, serde_json::Value>,
    index: usize,
    resolver: &Resolver,
) -> Result<NodeSpec, String> {
    Ok(NodeSpec {
        name: name.into(),
        index: index as u32,
        stage: Some(stage.into()),
        implementation: None,
        command: vec![resolver.stage(stage)?],
        params,
        restart: RestartPolicy::Never,
        max_restarts: 0,
        backoff_ms: 0,
        remap: BTreeMap::new(),
        host: default_host(),
    })
}

/// Checks the ports each node declares (`--describe`) against the edges: every edge a node is wired to must be a
/// port of that node with the same message type, and every required port must be wired.
///
/// # Errors
/// A [`LaunchError::Invalid`] naming the edge or node.
pub fn check_ports(graph: &Graph, node: &NodeSpec, ports: &crate::describe::Ports) -> Result<(), LaunchError> {
    let invalid = |entry: String, message: String| LaunchError::Invalid {
        path: graph.source.clone(),
        entry,
        message,
    };
    for e in &graph.edges {
        let as_pub = e.from == node.name;
        let as_sub = e.to.iter().any(|t| t == &node.name);
        if !as_pub && !as_sub {
            continue;
        }
        let list = if as_pub { &ports.outputs } else { &ports.inputs };
        let role = if as_pub { "output" } else { "input" };
        let port = list.iter().find(|p| node.topic_of(&p.port) == e.topic);
        match port {
            None => {
                let have: Vec<_> = list.iter().map(|p| format!("{} ({})", p.port, p.message)).collect();
                return Err(invalid(
                    format!("edge '{}'", e.topic),
                    format!(
                        "node '{}' has no {role} port for this topic (its {role}s: {})",
                        node.name,
                        if have.is_empty() { "none".into() } else { have.join(", ") }
                    ),
                ));
            }
            Some(p) if p.message != e.message => {
                return Err(invalid(
                    format!("edge '{}'", e.topic),
                    format!(
                        "type mismatch: the edge carries {} but {role} port '{}' of node '{}' takes {}",
                        e.message, p.port, node.name, p.message
                    ),
                ));
            }
            Some(_) => {}
        }
    }
    for (p, role) in ports
        .inputs
        .iter()
        .map(|p| (p, "input"))
        .chain(ports.outputs.iter().map(|p| (p, "output")))
    {
        let topic = node.topic_of(&p.port);
        let wired = if role == "input" {
            graph.input_edge(&node.name, topic).is_some()
        } else {
            graph.output_edge(&node.name, topic).is_some()
        };
        if p.required && !wired {
            return Err(invalid(
                format!("node '{}'", node.name),
                format!("required {role} port '{}' ({}) is not wired to any edge", p.port, p.message),
            ));
        }
    }
    Ok(())
}

fn find_executable(exe: &str, base: &Path) -> Option<String> {
    let p = Path::new(exe);
    if p.components().count() > 1 || p.is_absolute() {
        let full = if p.is_absolute() { p.to_path_buf() } else { base.join(p) };
        return full.is_file().then(|| full.display().to_string());
    }
    std::env::var_os("PATH")
        .and_then(|paths| std::env::split_paths(&paths).map(|d| d.join(exe)).find(|c| c.is_file()))
        .map(|c| c.display().to_string())
}

/// Default payload of image topics: RGB8 at the size of the graph's camera.toml, or of `<folder>/camera.toml` of
/// the first node with a `folder` parameter; `None` when the graph names neither.
fn default_image_bytes(file: &LaunchFile, base: &Path) -> Result<Option<u64>, String> {
    let camera = file.graph.camera.as_ref().map(|c| base.join(c)).or_else(|| {
        file.node.iter().find_map(|n| {
            n.params
                .get("folder")
                .and_then(|f| f.as_str())
                .map(|f| resolve_param_path(base, f).join("camera.toml"))
        })
    });
    let Some(camera) = camera else { return Ok(None) };
    let text = std::fs::read_to_string(&camera).map_err(|e| format!("cannot read {} for the image size: {e}", camera.display()))?;
    #[derive(Deserialize)]
    struct Size {
        width: u64,
        height: u64,
    }
    let s: Size = toml::from_str(&text).map_err(|e| format!("{}: {}", camera.display(), e.to_string().trim()))?;
    Ok(Some(s.width * s.height * 3))
}

/// Sizes the edges the launch file left open (`max_payload_bytes` 0): from what their producer declared, or else,
/// for a node that transforms images (a converter, an edge detector), from the largest image edge it receives.
///
/// # Errors
/// When an edge's size can be found neither way.
pub fn resolve_payloads(graph: &mut Graph, ports: &std::collections::BTreeMap<String, crate::describe::Ports>) -> Result<(), LaunchError> {
    // Each pass settles at least one edge of a chain; a graph has no longer chain than it has edges.
    for _ in 0..=graph.edges.len() {
        let mut changed = false;
        for i in 0..graph.edges.len() {
            if graph.edges[i].max_payload_bytes != 0 {
                continue;
            }
            let edge = &graph.edges[i];
            let declared = graph.node(&edge.from).and_then(|spec| {
                ports
                    .get(&spec.name)?
                    .outputs
                    .iter()
                    .find(|p| spec.topic_of(&p.port) == edge.topic)?
                    .max_payload_bytes
            });
            let inherited = || {
                graph
                    .edges
                    .iter()
                    .filter(|e| e.message == edge.message && e.to.contains(&edge.from))
                    .map(|e| e.max_payload_bytes)
                    .max()
                    .filter(|&b| b > 0)
            };
            if let Some(bytes) = declared.or_else(inherited) {
                graph.edges[i].max_payload_bytes = bytes.max(1);
                changed = true;
            }
        }
        if !changed {
            break;
        }
    }
    match graph.edges.iter().find(|e| e.max_payload_bytes == 0) {
        None => Ok(()),
        Some(edge) => Err(LaunchError::Invalid {
            path: graph.source.clone(),
            entry: format!("edge '{}'", edge.topic),
            message: format!(
                "its size is unknown: give `max_payload_bytes`, a [graph] camera, or a node with a `folder` parameter (node '{}' declares none)",
                edge.from
            ),
        }),
    }
}

/// A path parameter as nodes see it: absolute, or relative to the current directory when it exists there, else to
/// the launch file's folder.
pub fn resolve_param_path(base: &Path, value: &str) -> PathBuf {
    let p = Path::new(value);
    if p.is_absolute() || p.exists() {
        p.to_path_buf()
    } else {
        base.join(p)
    }
}

/// The value of a `--set` override: TOML (`3`, `true`, `"x"`, `[1, 2]`) where it parses, else the text as a string.
pub fn override_value(value: &str) -> toml::Value {
    toml::from_str::<toml::Table>(&format!("v = {value}"))
        .ok()
        .and_then(|mut t| t.remove("v"))
        .unwrap_or_else(|| toml::Value::String(value.to_owned()))
}

/// Parameters of type `T` from `PARAM=VALUE` overrides (each VALUE as [`override_value`] reads it), the rest at
/// their serde defaults: what `lineflow model --set` and the benchmarks use to set a stage's parameters.
///
/// # Errors
/// An item without `=`, or values that do not deserialize into `T` (the message names the parameter).
pub fn params_from_overrides<T: serde::de::DeserializeOwned>(set: &[String]) -> anyhow::Result<T> {
    use anyhow::Context as _;
    let mut table = toml::Table::new();
    for item in set {
        let (k, v) = item
            .split_once('=')
            .with_context(|| format!("--set {item}: expected PARAM=VALUE"))?;
        table.insert(k.trim().to_string(), override_value(v));
    }
    toml::Value::Table(table).try_into().context("parameters")
}

fn apply_override(file: &mut LaunchFile, item: &str) -> Result<(), String> {
    let (key, value) = item.split_once('=').ok_or("expected NODE.PARAM=VALUE")?;
    let (node, param) = key.split_once('.').ok_or("expected NODE.PARAM=VALUE")?;
    let parsed = override_value(value);
    if !file.node.iter().any(|n| n.name == node) {
        let table = match node {
            RECORDER_STAGE => Some(&mut file.record),
            VIEWER_STAGE => Some(&mut file.view),
            BRIDGE => Some(&mut file.bridge),
            _ => None,
        };
        if let Some(table) = table {
            table.insert(param.to_owned(), parsed);
            return Ok(());
        }
    }
    let n = file
        .node
        .iter_mut()
        .find(|n| n.name == node)
        .ok_or_else(|| format!("no node '{node}' in the graph"))?;
    let text = || parsed.as_str().unwrap_or(value).to_owned();
    // `executable` and `stage` replace each other: a stage swapped for a node in another language on the command
    // line (or on replay) without a second launch file.
    if param == "impl" {
        n.implementation = Some(text());
    } else if param == "executable" {
        n.executable = Some(text());
        n.stage = None;
    } else if param == "stage" {
        n.stage = Some(text());
        n.executable = None;
    } else if param == "host" {
        n.host = Some(text());
    } else {
        n.params.insert(param.to_owned(), parsed);
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn resolver(dir: &Path) -> Resolver {
        for s in ["capture", "stats", "record", "view"] {
            std::fs::write(dir.join(format!("lineflow-{s}")), "").unwrap();
        }
        Resolver { bin_dir: dir.to_owned() }
    }

    const GOOD: &str = r#"
        [[node]]
        name = "cap"
        stage = "capture"
        impl = "folder"
        params = { fps = 2 }
        [[node]]
        name = "sink"
        stage = "stats"
        [[edge]]
        topic = "images"
        type = "Image"
        from = "cap"
        to = ["sink"]
        max_payload_bytes = 1000
    "#;

    #[test]
    fn a_valid_graph_resolves_stage_binaries_and_params() {
        let dir = tempfile::tempdir().unwrap();
        let sut = parse(&dir.path().join("g.toml"), GOOD, &["cap.fps=5".into()], &resolver(dir.path())).unwrap();
        assert_eq!(sut.nodes.len(), 3, "the recorder is added");
        assert!(sut.nodes[0].command[0].ends_with("lineflow-capture"));
        assert_eq!(sut.nodes[0].params["fps"], 5);
        assert_eq!(sut.nodes[0].params["impl"], "folder");
        assert!(sut.is_source("cap") && sut.is_sink("sink"));
        assert_eq!(sut.edges[0].to, ["sink", RECORDER]);
        assert_eq!(sut.nodes[2].index, 2);
    }

    #[test]
    fn the_recorder_takes_record_settings_and_can_be_turned_off() {
        let dir = tempfile::tempdir().unwrap();
        let r = resolver(dir.path());
        let p = dir.path().join("g.toml");
        let sut = parse(&p, GOOD, &["record.compression=\"zstd\"".into()], &r).unwrap();
        assert_eq!(sut.node(RECORDER).unwrap().params["compression"], "zstd");
        let off = parse(&p, GOOD, &["record.enabled=false".into()], &r).unwrap();
        assert!(off.node(RECORDER).is_none());
        assert_eq!(off.edges[0].to, ["sink"]);
        let err = parse(&p, &format!("[record]\nenabled = 3\n{GOOD}"), &[], &r)
            .unwrap_err()
            .to_string();
        assert!(err.contains("[record]: `enabled` must be true or false"), "{err}");
        let clash = GOOD
            .replace("name = \"sink\"", "name = \"recorder\"")
            .replace("to = [\"sink\"]", "to = [\"recorder\"]");
        let err = parse(&p, &clash, &[], &r).unwrap_err().to_string();
        assert!(err.contains("'recorder' is reserved"), "{err}");
    }

    #[test]
    fn bridge_settings_default_to_raw_and_take_set_and_refuse_nonsense() {
        let dir = tempfile::tempdir().unwrap();
        let r = resolver(dir.path());
        let p = dir.path().join("g.toml");
        let sut = parse(&p, GOOD, &[], &r).unwrap();
        assert_eq!(sut.bridge, BridgeSettings::default());
        assert_eq!(sut.bridge.images, ImageFormat::Raw);
        let sut = parse(&p, GOOD, &["bridge.images=jpeg".into(), "bridge.jpeg_quality=70".into()], &r).unwrap();
        assert_eq!((sut.bridge.images, sut.bridge.jpeg_quality), (ImageFormat::Jpeg, 70));
        let sut = parse(&p, &format!("[bridge]\nimages = \"png\"\n{GOOD}"), &[], &r).unwrap();
        assert_eq!(sut.bridge.images, ImageFormat::Png);
        for (table, want) in [
            ("images = \"gif\"", "unknown variant `gif`"),
            ("jpeg_quality = 0", "`jpeg_quality` must be 1 to 100"),
            ("jpeg_quality = 300", "[bridge]"),
            ("colour = true", "unknown field `colour`"),
        ] {
            let err = parse(&p, &format!("[bridge]\n{table}\n{GOOD}"), &[], &r).unwrap_err().to_string();
            assert!(err.contains("[bridge]") && err.contains(want), "{table}: {err}");
        }
    }

    #[test]
    fn the_viewer_is_added_only_when_asked_and_watches_every_topic() {
        let dir = tempfile::tempdir().unwrap();
        let r = resolver(dir.path());
        let p = dir.path().join("g.toml");
        assert!(parse(&p, GOOD, &[], &r).unwrap().node(VIEWER).is_none(), "off by default");
        let sut = parse(&p, GOOD, &["view.enabled=true".into(), "view.port=9000".into()], &r).unwrap();
        assert_eq!(sut.node(VIEWER).unwrap().params["port"], 9000);
        assert!(sut.node(VIEWER).unwrap().params.get("enabled").is_none());
        assert_eq!(sut.edges[0].to, ["sink", RECORDER, VIEWER]);
        let in_file = parse(&p, &format!("[view]\nenabled = true\n{GOOD}"), &["record.enabled=false".into()], &r).unwrap();
        assert_eq!(in_file.edges[0].to, ["sink", VIEWER]);
        let err = parse(&p, &format!("[view]\nenabled = \"yes\"\n{GOOD}"), &[], &r)
            .unwrap_err()
            .to_string();
        assert!(err.contains("[view]: `enabled` must be true or false"), "{err}");
    }

    #[test]
    fn errors_name_the_file_and_the_entry() {
        let dir = tempfile::tempdir().unwrap();
        let r = resolver(dir.path());
        let p = dir.path().join("g.toml");
        let cases = [
            (
                GOOD.replace("to = [\"sink\"]", "to = [\"sinc\"]"),
                "edge 'images': subscriber 'sinc' is not a node",
            ),
            (GOOD.replace("type = \"Image\"", "type = \"Imgae\""), "unknown message type 'Imgae'"),
            (GOOD.replace("name = \"sink\"", "name = \"cap\""), "node 'cap': duplicate node name"),
            (GOOD.replace("stage = \"stats\"", "stage = \"nope\""), "stage 'nope' has no binary"),
            (
                GOOD.replace("topic = \"images\"", "topic = \"gt/lines3d\""),
                "only `eval` may read gt/*",
            ),
            (GOOD.replace("[[edge]]", "[[edgez]]"), "unknown field `edgez`"),
        ];
        for (text, expected) in cases {
            let err = parse(&p, &text, &[], &r).unwrap_err().to_string();
            assert!(err.contains(expected), "{err}");
            assert!(err.starts_with(&p.display().to_string()), "{err}");
        }
        let err = parse(&p, GOOD, &["nobody.x=1".into()], &r).unwrap_err().to_string();
        assert!(err.contains("no node 'nobody'"), "{err}");
    }

    #[test]
    fn image_payload_defaults_from_camera_toml() {
        let dir = tempfile::tempdir().unwrap();
        std::fs::create_dir(dir.path().join("proj")).unwrap();
        std::fs::write(dir.path().join("proj/camera.toml"), "width = 10\nheight = 20\n").unwrap();
        let text = GOOD
            .replace("max_payload_bytes = 1000", "")
            .replace("params = { fps = 2 }", "params = { folder = \"proj\" }");
        let sut = parse(&dir.path().join("g.toml"), &text, &[], &resolver(dir.path())).unwrap();
        assert_eq!(sut.edges[0].max_payload_bytes, 600);
    }
}
