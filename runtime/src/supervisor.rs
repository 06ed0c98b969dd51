//! The supervisor: validates a graph, starts every node as a child process, waits until all are connected, starts
//! the sources, reaps and restarts children by policy, and ends when every node has finished.

use std::collections::{BTreeMap, BTreeSet};
use std::path::PathBuf;
use std::process::{Command, Stdio};
use std::sync::Arc;
use std::time::{Duration, Instant};

use anyhow::{bail, Context, Result};
use iceoryx2::prelude::*;
use lineflow_messages::NodeStatus;

use crate::chaos::{Action, Fault};
use crate::console::{clear_logs, log_path, progress_line, relay, Console, NodeProgress};
use crate::describe::Ports;
use crate::env;
use crate::launch::{self, Graph, NodeSpec, RestartPolicy};
use crate::runs::RunRecord;
use crate::shm;
use crate::transport;

/// Options of one run.
#[derive(Debug, Clone, Default)]
pub struct RunOptions {
    /// Output folder handed to the nodes (`LINEFLOW_OUT`).
    pub out: PathBuf,
    /// Frames the source will produce, when known: enables progress with rate and ETA.
    pub expected_frames: Option<u64>,
    /// Print progress to stderr.
    pub progress: bool,
    /// Show the nodes' log lines on the terminal (they are kept in `out/logs/` either way).
    pub echo_logs: bool,
    /// The nodes' `LINEFLOW_LOG` (default: inherited).
    pub node_log_level: Option<String>,
    /// How long nodes may take to connect.
    pub connect_timeout: Option<Duration>,
    /// Faults to inject (`--chaos`).
    pub chaos: Vec<Fault>,
}

/// How one node ended.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum NodeEnd {
    /// Exited with status 0.
    Finished,
    /// Exited with a non-zero status.
    Failed(i32),
    /// Killed by a signal.
    Signalled(i32),
    /// Stopped by the supervisor (interrupt, or another node failed).
    Stopped,
    /// Never ended (should not happen).
    Unknown,
}

/// The per-node summary of a run.
#[derive(Debug, Clone)]
pub struct NodeSummary {
    /// Node name.
    pub name: String,
    /// How its last instance ended.
    pub end: NodeEnd,
    /// Messages received (all instances).
    pub msgs_in: u64,
    /// Messages published (all instances).
    pub msgs_out: u64,
    /// Deliveries that missed an expected subscriber.
    pub drops: u64,
    /// Messages discarded as already seen.
    pub duplicates: u64,
    /// Frames missed on the inputs.
    pub missed_ranges: Vec<(u64, u64)>,
    /// User plus system CPU time of all instances.
    pub cpu: Duration,
    /// Restarts.
    pub restarts: u32,
}

impl NodeSummary {
    /// Frames missed.
    pub fn missed(&self) -> u64 {
        self.missed_ranges.iter().map(|(a, b)| b - a + 1).sum()
    }
}

/// The outcome of a run.
#[derive(Debug, Clone)]
pub struct Outcome {
    /// Run id.
    pub run_id: String,
    /// Whether every node finished and nothing was interrupted.
    pub ok: bool,
    /// Why the run failed, when it did.
    pub error: Option<String>,
    /// Per-node summaries in graph order.
    pub nodes: Vec<NodeSummary>,
    /// Wall time.
    pub wall: Duration,
    /// The injected faults (`--chaos`), each with whether it struck (a node may finish before its frame).
    pub faults: Vec<(Fault, bool)>,
}

/// One row of the summary's table, its columns as [`Outcome::table`]'s header names them.
pub(crate) struct Row<'a> {
    pub name: &'a str,
    pub status: &'a str,
    pub msgs_in: u64,
    pub msgs_out: u64,
    pub drops: u64,
    pub duplicates: u64,
    pub missed: u64,
    pub cpu_s: Option<f64>,
    pub restarts: Option<u32>,
    pub missed_ranges: &'a [(u64, u64)],
}

impl Row<'_> {
    /// The row as a line of the table; a figure that is not known shows as `-`.
    pub(crate) fn line(&self) -> String {
        let ranges: Vec<String> = self
            .missed_ranges
            .iter()
            .map(|(a, b)| if a == b { a.to_string() } else { format!("{a}-{b}") })
            .collect();
        format!(
            "{:<14} {:>10} {:>8} {:>8} {:>6} {:>5} {:>8} {:>9} {:>8}  {}\n",
            self.name,
            self.status,
            self.msgs_in,
            self.msgs_out,
            self.drops,
            self.duplicates,
            self.missed,
            self.cpu_s.map_or("-".into(), |c| format!("{c:.2}")),
            self.restarts.map_or("-".into(), |r| r.to_string()),
            if ranges.is_empty() { "-".into() } else { ranges.join(",") }
        )
    }
}

impl Outcome {
    /// The summary as a text table.
    pub fn table(&self) -> String {
        let mut s = format!(
            "{:<14} {:>10} {:>8} {:>8} {:>6} {:>5} {:>8} {:>9} {:>8}  {}\n",
            "node", "status", "in", "out", "drops", "dups", "missed", "cpu s", "restarts", "frames missed"
        );
        for n in &self.nodes {
            s += &Row {
                name: &n.name,
                status: &n.end.status(),
                msgs_in: n.msgs_in,
                msgs_out: n.msgs_out,
                drops: n.drops,
                duplicates: n.duplicates,
                missed: n.missed(),
                cpu_s: Some(n.cpu.as_secs_f64()),
                restarts: Some(n.restarts),
                missed_ranges: &n.missed_ranges,
            }
            .line();
        }
        s
    }
}

impl NodeEnd {
    /// How it ended, in one word or two (the summary's status column).
    pub fn status(&self) -> String {
        match self {
            NodeEnd::Finished => "ok".to_string(),
            NodeEnd::Failed(c) => format!("exit {c}"),
            NodeEnd::Signalled(sig) => format!("signal {sig}"),
            NodeEnd::Stopped => "stopped".into(),
            NodeEnd::Unknown => "?".into(),
        }
    }
}

impl Outcome {
    /// The summary as one JSON object (`summary.json`, `--json`).
    pub fn json(&self, graph: &std::path::Path) -> serde_json::Value {
        let nodes: Vec<serde_json::Value> = self
            .nodes
            .iter()
            .map(|n| {
                serde_json::json!({
                    "name": n.name,
                    "status": n.end.status(),
                    "in": n.msgs_in,
                    "out": n.msgs_out,
                    "drops": n.drops,
                    "duplicates": n.duplicates,
                    "missed": n.missed(),
                    "missed_ranges": n.missed_ranges,
                    "cpu_s": n.cpu.as_secs_f64(),
                    "restarts": n.restarts,
                })
            })
            .collect();
        serde_json::json!({
            "run": self.run_id,
            "graph": graph.display().to_string(),
            "ok": self.ok,
            "error": self.error,
            "wall_s": self.wall.as_secs_f64(),
            "nodes": nodes,
            "chaos": self.faults.iter().map(|(f, struck)| serde_json::json!({
                "node": f.node,
                "frame": f.frame,
                "action": match f.action { Action::Kill => "kill", Action::Stop(_) => "stop" },
                "stop_s": match f.action { Action::Kill => None, Action::Stop(d) => Some(d.as_secs_f64()) },
                "struck": struck,
            })).collect::<Vec<_>>(),
        })
    }
}

/// Asks every node for its ports (`LINEFLOW_DESCRIBE=1`) and type-checks the graph against them. Also catches
/// nodes that cannot start at all or reject their parameters, before anything runs.
///
/// # Errors
/// The first node that fails to describe itself, or the first port mismatch.
pub fn describe_all(graph: &Graph, graph_file: &std::path::Path, timeout: Duration) -> Result<BTreeMap<String, Ports>> {
    let mut out = BTreeMap::new();
    for node in &graph.nodes {
        let child = Command::new(&node.command[0])
            .args(&node.command[1..])
            .env(env::DESCRIBE, "1")
            .env(env::GRAPH, graph_file)
            .env(env::NODE, &node.name)
            .env("LINEFLOW_LOG", "error")
            .stdin(Stdio::null())
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .spawn()
            .with_context(|| format!("node '{}': cannot start {}", node.name, node.command[0]))?;
        let output = output_within(child, timeout).with_context(|| {
            format!(
                "node '{}': {} did not describe its ports (`--describe`, docs/nodes.md)",
                node.name, node.command[0]
            )
        })?;
        let stderr = String::from_utf8_lossy(&output.stderr);
        if !output.status.success() {
            let why = stderr
                .lines()
                .rfind(|l| !l.trim().is_empty())
                .unwrap_or("no message")
                .trim()
                .to_owned();
            bail!(
                "node '{}': {} exited with {} before starting: {why}",
                node.name,
                node.command[0],
                output.status
            );
        }
        let stdout = String::from_utf8_lossy(&output.stdout);
        let line = stdout.lines().rev().find(|l| l.trim_start().starts_with('{')).unwrap_or("");
        let ports: Ports =
            serde_json::from_str(line).with_context(|| format!("node '{}': --describe printed no port list (docs/nodes.md)", node.name))?;
        launch::check_ports(graph, node, &ports)?;
        out.insert(node.name.clone(), ports);
    }
    Ok(out)
}

/// How long nodes have to describe themselves and to connect: the run's option, else the launch file's
/// `connect_timeout_s`, else 60 s.
fn connect_timeout(graph: &Graph, option: Option<Duration>) -> Duration {
    let from_graph = graph.connect_timeout_s.and_then(|s| Duration::try_from_secs_f64(s).ok());
    option.or(from_graph).unwrap_or(Duration::from_secs(60))
}

/// The child's exit status and output, or an error once `timeout` has passed (the child is killed then). Its
/// output is read beside it, so a chatty child cannot stall on a full pipe.
fn output_within(mut child: std::process::Child, timeout: Duration) -> Result<std::process::Output> {
    fn drain<R: std::io::Read + Send + 'static>(pipe: Option<R>) -> std::thread::JoinHandle<Vec<u8>> {
        std::thread::spawn(move || {
            let mut buf = Vec::new();
            if let Some(mut p) = pipe {
                let _ = p.read_to_end(&mut buf);
            }
            buf
        })
    }
    let stdout = drain(child.stdout.take());
    let stderr = drain(child.stderr.take());
    let deadline = Instant::now() + timeout;
    let status = loop {
        if let Some(status) = child.try_wait()? {
            break status;
        }
        if Instant::now() > deadline {
            let _ = child.kill();
            let _ = child.wait();
            bail!("no answer after {timeout:?}");
        }
        std::thread::sleep(Duration::from_millis(10));
    };
    Ok(std::process::Output {
        status,
        stdout: stdout.join().unwrap_or_default(),
        stderr: stderr.join().unwrap_or_default(),
    })
}

/// Checks that `/dev/shm` can hold the graph's worst case.
///
/// # Errors
/// When it cannot.
pub fn check_shm(graph: &Graph) -> Result<()> {
    let need = graph.shm_bytes();
    if let Some(free) = shm::free_bytes(std::path::Path::new(shm::SHM_DIR)) {
        if need > free {
            bail!(
                "{}: the graph may need {} of shared memory but {} has only {} free (lower edge depths or max_payload_bytes, or run `lineflow doctor --fix`)",
                graph.source.display(),
                shm::human_bytes(need),
                shm::SHM_DIR,
                shm::human_bytes(free)
            );
        }
    }
    Ok(())
}

struct Child {
    spec: NodeSpec,
    pid: Option<i32>,
    end: NodeEnd,
    restarts: u32,
    restart_at: Option<Instant>,
    cpu: Duration,
    /// Counters of finished instances plus the current one's latest.
    done: NodeStatus,
    current: NodeStatus,
    missed: Vec<(u64, u64)>,
    wired_inputs: Vec<String>,
    /// Deepest subscriber buffer among the node's outputs.
    output_depth: usize,
    /// The threads relaying the node's output (every instance's) to the terminal and its log file.
    relays: Vec<std::thread::JoinHandle<()>>,
}

impl Child {
    /// The furthest frame received on any input, plus 1 (0: none yet).
    fn frames(&self) -> u64 {
        let s = &self.current;
        s.last_frame_plus1[..(s.n_inputs as usize).min(NodeStatus::MAX_INPUTS)]
            .iter()
            .copied()
            .max()
            .unwrap_or(0)
    }

    /// Whether the node has reported its work finished, or exited cleanly.
    fn finished(&self) -> bool {
        self.current.flags & NodeStatus::FINISHED != 0 || self.end == NodeEnd::Finished
    }

    fn totals(&self) -> (u64, u64, u64, u64) {
        (
            self.done.msgs_in + self.current.msgs_in,
            self.done.msgs_out + self.current.msgs_out,
            self.done.drops + self.current.drops,
            self.done.duplicates + self.current.duplicates,
        )
    }

    fn absorb_current(&mut self) {
        let c = self.current;
        self.done.msgs_in += c.msgs_in;
        self.done.msgs_out += c.msgs_out;
        self.done.drops += c.drops;
        self.done.duplicates += c.duplicates;
        for r in &c.missed_ranges[..c.n_missed_ranges as usize] {
            self.missed.push((r[0], r[1]));
        }
        // Keep the resume points: the next instance continues after them.
        self.current = NodeStatus {
            last_frame_plus1: c.last_frame_plus1,
            n_inputs: c.n_inputs,
            ..Default::default()
        };
    }
}

/// Runs a validated graph to the end.
///
/// # Errors
/// Set-up failures (ports, shared memory, spawning); node failures are reported in the [`Outcome`].
pub fn run(graph: &Graph, opts: &RunOptions) -> Result<Outcome> {
    let started = Instant::now();
    if let Some(f) = opts.chaos.iter().find(|f| !graph.nodes.iter().any(|n| n.name == f.node)) {
        let names: Vec<&str> = graph.nodes.iter().map(|n| n.name.as_str()).collect();
        bail!(
            "--chaos {}@{}: the graph has no node '{}' (its nodes: {})",
            f.node,
            f.frame,
            f.node,
            names.join(", ")
        );
    }
    raise_open_files_limit();
    let run = RunRecord::create(&opts.out)?;
    let mut graph = graph.clone();
    let described = (|| -> Result<BTreeMap<String, Ports>> {
        std::fs::write(&run.graph, serde_json::to_vec(&graph)?).with_context(|| format!("cannot write {}", run.graph.display()))?;
        let ports = describe_all(&graph, &run.graph, connect_timeout(&graph, opts.connect_timeout))?;
        // Edges sized by their producers: the nodes read the graph with the sizes filled in.
        launch::resolve_payloads(&mut graph, &ports)?;
        std::fs::write(&run.graph, serde_json::to_vec(&graph)?).with_context(|| format!("cannot write {}", run.graph.display()))?;
        check_shm(&graph)?;
        Ok(ports)
    })();
    let ports = match described {
        Ok(p) => p,
        Err(e) => {
            run.remove();
            return Err(e);
        }
    };
    let graph = &graph;
    std::fs::create_dir_all(&opts.out).with_context(|| format!("cannot create output folder {}", opts.out.display()))?;
    let result = supervise(graph, &run, &ports, opts, started);
    cleanup(&run);
    // Nothing of a finished run remains: its shared memory, iceoryx2 files and registry entry are gone.
    run.remove();
    result
}

fn cleanup(run: &RunRecord) {
    if let Ok(cfg) = transport::config(&run.prefix, &run.root) {
        let _ = Node::<ipc::Service>::list(&cfg, |state| {
            if let NodeState::Dead(view) = state {
                let _ = view.try_remove_stale_resources();
            }
            CallbackProgression::Continue
        });
    }
    shm::remove_prefixed(&run.prefix);
    let _ = std::fs::remove_dir_all(&run.root);
}

fn supervise(graph: &Graph, run: &RunRecord, ports: &BTreeMap<String, Ports>, opts: &RunOptions, started: Instant) -> Result<Outcome> {
    let cfg = transport::config(&run.prefix, &run.root)?;
    let node = transport::create_node(&cfg, "supervisor")?;
    let status_sub = transport::open_status(&node)?
        .subscriber_builder()
        .buffer_size(256)
        .create()
        .map_err(|e| anyhow::anyhow!("cannot subscribe to status: {e:?}"))?;
    let ready = transport::open_event(&node, transport::READY_SERVICE)?
        .listener_builder()
        .create()
        .map_err(|e| anyhow::anyhow!("{e:?}"))?;
    let start = transport::open_event(&node, transport::START_SERVICE)?
        .notifier_builder()
        .create()
        .map_err(|e| anyhow::anyhow!("{e:?}"))?;

    let console = Console::new(opts.echo_logs);
    clear_logs(&opts.out);
    let mut children: Vec<Child> = graph
        .nodes
        .iter()
        .map(|spec| {
            let wired_inputs = ports[&spec.name]
                .inputs
                .iter()
                .map(|p| spec.topic_of(&p.port).to_owned())
                .filter(|t| graph.input_edge(&spec.name, t).is_some())
                .collect();
            Child {
                spec: spec.clone(),
                pid: None,
                end: NodeEnd::Unknown,
                restarts: 0,
                restart_at: None,
                cpu: Duration::ZERO,
                done: NodeStatus::default(),
                current: NodeStatus::default(),
                missed: Vec::new(),
                wired_inputs,
                // A bridge's messages wait on another host, not in its outputs: it re-reads its inputs' whole
                // history, and the receiving bridge drops what it already has.
                output_depth: if spec.name == crate::launch::BRIDGE {
                    usize::MAX
                } else {
                    graph
                        .edges
                        .iter()
                        .filter(|e| e.from == spec.name)
                        .map(|e| e.depth + 2)
                        .max()
                        .unwrap_or(0)
                },
                relays: Vec::new(),
            }
        })
        .collect();

    let mut error: Option<String> = None;
    // The node whose failure `error` reports, if one did.
    let mut failed: Option<String> = None;
    for c in &mut children {
        match spawn(c, run, opts, &console) {
            Ok(pid) => c.pid = Some(pid),
            Err(e) => {
                error = Some(format!("{e:#}"));
                break;
            }
        }
    }

    // Readiness: every node announces itself once its ports are connected.
    let connect_timeout = connect_timeout(graph, opts.connect_timeout);
    let mut ready_set = BTreeSet::new();
    let ready_deadline = Instant::now() + connect_timeout;
    while error.is_none() && ready_set.len() < children.len() {
        let _ = ready.timed_wait(
            |ev| {
                ready_set.insert(ev.id.as_value());
            },
            Duration::from_millis(20),
        );
        if let Some(f) = reap(&mut children, false) {
            error = Some(format!("{} before the graph was connected", f.message));
            failed = Some(f.node);
        }
        if node.wait(Duration::ZERO).is_err() {
            error = Some("interrupted".into());
        }
        if Instant::now() > ready_deadline {
            let missing: Vec<_> = children
                .iter()
                .filter(|c| !ready_set.contains(&(c.spec.index as usize)))
                .map(|c| c.spec.name.clone())
                .collect();
            error = Some(format!("nodes not connected after {connect_timeout:?}: {}", missing.join(", ")));
        }
    }
    if error.is_none() {
        start.notify().map_err(|e| anyhow::anyhow!("cannot send start: {e:?}"))?;
        tracing::debug!("all {} nodes connected; sources started", children.len());
    }

    let mut progress = opts.progress.then(|| Progress::new(opts.expected_frames, console.is_tty()));
    let mut chaos = Injector::new(&opts.chaos);
    loop {
        drain_status(&status_sub, &mut children);
        if error.is_none() {
            chaos.strike(&children, graph);
            if let Some(f) = reap(&mut children, true) {
                error = Some(f.message);
                failed = Some(f.node);
            }
            if node.wait(Duration::ZERO).is_err() {
                error = Some("interrupted".into());
            }
        }
        if error.is_some() {
            chaos.continue_stopped();
            stop_all(&mut children);
            break;
        }
        // Restarts whose back-off has passed; dead nodes are cleaned first so blocked publishers continue.
        for c in children.iter_mut().filter(|c| c.restart_at.is_some_and(|t| Instant::now() >= t)) {
            node.try_cleanup_dead_nodes();
            c.restart_at = None;
            match spawn(c, run, opts, &console) {
                Ok(pid) => c.pid = Some(pid),
                Err(e) => error = Some(format!("{e:#}")),
            }
        }
        if children.iter().all(|c| c.pid.is_none() && c.restart_at.is_none()) {
            break;
        }
        if let Some(p) = progress.as_mut() {
            p.show(&children, graph, &console);
        }
        std::thread::sleep(Duration::from_millis(20));
    }
    drain_status(&status_sub, &mut children);
    // The nodes' last lines before the summary. A pipe that a node's own child process still holds open would
    // keep its relay waiting: such a relay is left behind after a few seconds.
    let relays: Vec<_> = children.iter_mut().flat_map(|c| c.relays.drain(..)).collect();
    let deadline = Instant::now() + Duration::from_secs(5);
    while relays.iter().any(|t| !t.is_finished()) && Instant::now() < deadline {
        std::thread::sleep(Duration::from_millis(10));
    }
    for t in relays.into_iter().filter(std::thread::JoinHandle::is_finished) {
        let _ = t.join();
    }
    if let Some(p) = progress.as_mut() {
        p.finish(&children, graph, &console);
    }

    let nodes = children
        .iter_mut()
        .map(|c| {
            c.absorb_current();
            let (msgs_in, msgs_out, drops, duplicates) = c.totals();
            NodeSummary {
                name: c.spec.name.clone(),
                end: c.end.clone(),
                msgs_in,
                msgs_out,
                drops,
                duplicates,
                missed_ranges: merge_ranges(&c.missed),
                cpu: c.cpu,
                restarts: c.restarts,
            }
        })
        .collect::<Vec<_>>();
    let ok = error.is_none() && nodes.iter().all(|n| n.end == NodeEnd::Finished);
    if error.is_none() && !ok {
        error = Some("a node did not finish".into());
    }
    let error = error.map(|e| with_cause(e, failed.as_deref(), &opts.out));
    Ok(Outcome {
        run_id: run.id.clone(),
        ok,
        error,
        nodes,
        wall: started.elapsed(),
        faults: chaos.faults,
    })
}

/// The `--chaos` faults of a run: each strikes once, when its node has received its frame.
struct Injector {
    faults: Vec<(Fault, bool)>,
    /// Stopped processes and when to continue them.
    stopped: Vec<(i32, Instant)>,
}

impl Injector {
    fn new(faults: &[Fault]) -> Self {
        Self {
            faults: faults.iter().map(|f| (f.clone(), false)).collect(),
            stopped: Vec::new(),
        }
    }

    fn strike(&mut self, children: &[Child], graph: &Graph) {
        // A source has no inputs to count: it has sent what the furthest stage received.
        let furthest = children
            .iter()
            .filter(|c| !graph.is_source(&c.spec.name))
            .map(Child::frames)
            .max()
            .unwrap_or(0);
        for (fault, struck) in self.faults.iter_mut().filter(|(_, struck)| !*struck) {
            let Some(c) = children.iter().find(|c| c.spec.name == fault.node) else {
                continue;
            };
            let frames = if graph.is_source(&c.spec.name) { furthest } else { c.frames() };
            let Some(pid) = c.pid.filter(|_| frames > fault.frame) else {
                continue;
            };
            tracing::warn!("chaos: {fault} (pid {pid})");
            // SAFETY: signalling our own child.
            match fault.action {
                Action::Kill => unsafe {
                    libc::kill(pid, libc::SIGKILL);
                },
                Action::Stop(pause) => {
                    unsafe { libc::kill(pid, libc::SIGSTOP) };
                    self.stopped.push((pid, Instant::now() + pause));
                }
            }
            *struck = true;
        }
        let now = Instant::now();
        self.stopped.retain(|&(pid, until)| {
            if now < until {
                return true;
            }
            tracing::warn!("chaos: SIGCONT to pid {pid}");
            // SAFETY: as above.
            unsafe { libc::kill(pid, libc::SIGCONT) };
            false
        });
    }

    /// Continues every stopped node at once: a run that ends must not leave one stopped.
    fn continue_stopped(&mut self) {
        for (pid, _) in self.stopped.drain(..) {
            // SAFETY: signalling our own child, stopped and so not yet reaped.
            unsafe { libc::kill(pid, libc::SIGCONT) };
        }
    }
}

/// A run's error with the cause the failed node gave: the last line of its log (`out/logs/NODE.log`), which the
/// message naming the node does not carry; and, where the limit of open files is low (shared-memory ports that
/// could not be made look like any other failure), that limit.
fn with_cause(error: String, failed: Option<&str>, out: &std::path::Path) -> String {
    let Some(name) = failed else { return error };
    let log = std::fs::read_to_string(log_path(out, name)).unwrap_or_default();
    let Some(last) = log.lines().rev().map(str::trim).find(|l| !l.is_empty()) else {
        return error;
    };
    let mut text = format!("{error}: {last}");
    if let Some(limit) = open_files_limit().filter(|&n| n < FILES_PER_GRAPH) {
        text += &format!(
            " (open files are limited to {limit} here, `ulimit -n`; a node needs up to about 15 per topic it uses: if \
             the node could not open a port, raise the limit)"
        );
    }
    text
}

/// Open files a default graph's busiest node (the recorder) can use, with room to spare.
const FILES_PER_GRAPH: u64 = 1024;

/// The soft limit of open files, if known.
fn open_files_limit() -> Option<u64> {
    let mut r = libc::rlimit { rlim_cur: 0, rlim_max: 0 };
    // SAFETY: a valid out-pointer.
    (unsafe { libc::getrlimit(libc::RLIMIT_NOFILE, &mut r) } == 0).then_some(r.rlim_cur)
}

/// Raises the soft limit of open files to the hard one, for this process and the nodes it starts: every port of a
/// node holds shared-memory and event files, and the recorder subscribes to every topic.
fn raise_open_files_limit() {
    let mut r = libc::rlimit { rlim_cur: 0, rlim_max: 0 };
    // SAFETY: valid pointers to a local rlimit.
    unsafe {
        if libc::getrlimit(libc::RLIMIT_NOFILE, &mut r) == 0 && r.rlim_cur < r.rlim_max {
            r.rlim_cur = r.rlim_max;
            libc::setrlimit(libc::RLIMIT_NOFILE, &r);
        }
    }
}

fn spawn(c: &mut Child, run: &RunRecord, opts: &RunOptions, console: &Arc<Console>) -> Result<i32> {
    // Outputs the dead instance sent but its subscribers had not yet taken die with its shared memory: replay up to
    // one output buffer's worth of frames (subscribers drop what they already have).
    let replay = c.output_depth as u64;
    let resume: Vec<String> = c
        .wired_inputs
        .iter()
        .enumerate()
        .filter(|_| c.restarts > 0)
        .filter_map(|(i, topic)| {
            c.current
                .last_frame_plus1
                .get(i)
                .filter(|&&f| f > 0)
                .map(|f| format!("{topic}={f}@{}", f.saturating_sub(replay)))
        })
        .collect();
    let mut cmd = Command::new(&c.spec.command[0]);
    cmd.args(&c.spec.command[1..])
        .env(env::RUN_ID, &run.id)
        .env(env::IOX2_PREFIX, &run.prefix)
        .env(env::IOX2_ROOT, &run.root)
        .env(env::GRAPH, &run.graph)
        .env(env::NODE, &c.spec.name)
        .env(env::OUT, &opts.out)
        .env(env::RESTART, c.restarts.to_string())
        .env(env::RESUME, resume.join(","))
        .env_remove(env::DESCRIBE)
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped());
    if let Some(level) = &opts.node_log_level {
        cmd.env("LINEFLOW_LOG", level);
    }
    if let Some(t) = opts.connect_timeout {
        cmd.env(env::CONNECT_TIMEOUT_S, t.as_secs().max(1).to_string());
    }
    let mut child = cmd
        .spawn()
        .with_context(|| format!("node '{}': cannot start {}", c.spec.name, c.spec.command[0]))?;
    c.relays.extend(relay(&mut child, &log_path(&opts.out, &c.spec.name), console));
    if c.restarts > 0 {
        tracing::warn!(
            "node '{}' restarted ({} of {}), resuming at {}",
            c.spec.name,
            c.restarts,
            c.spec.max_restarts,
            if resume.is_empty() { "the start".into() } else { resume.join(",") }
        );
    }
    Ok(child.id() as i32)
}

/// A node that failed for good, and the message naming it.
struct Failure {
    node: String,
    message: String,
}

/// Reaps exited children; schedules restarts. Returns the first node that failed for good (only when `restart`
/// is allowed; before the graph is connected every failure is final).
fn reap(children: &mut [Child], restart: bool) -> Option<Failure> {
    let mut failure = None;
    for c in children.iter_mut() {
        let Some(pid) = c.pid else { continue };
        let mut status = 0;
        let mut usage: libc::rusage = unsafe { std::mem::zeroed() };
        // SAFETY: pid is our own child; status and usage are valid out-pointers.
        let r = unsafe { libc::wait4(pid, &mut status, libc::WNOHANG, &mut usage) };
        if r != pid {
            continue;
        }
        c.pid = None;
        c.cpu += tv(usage.ru_utime) + tv(usage.ru_stime);
        c.end = if libc::WIFEXITED(status) {
            match libc::WEXITSTATUS(status) {
                0 => NodeEnd::Finished,
                code => NodeEnd::Failed(code),
            }
        } else if libc::WIFSIGNALED(status) {
            NodeEnd::Signalled(libc::WTERMSIG(status))
        } else {
            NodeEnd::Unknown
        };
        if c.end == NodeEnd::Finished {
            continue;
        }
        let can_restart = restart && c.spec.restart == RestartPolicy::OnFailure && c.restarts < c.spec.max_restarts;
        let what = match c.end {
            NodeEnd::Failed(code) => format!("exited with status {code}"),
            NodeEnd::Signalled(sig) => format!("was killed by signal {sig}"),
            _ => "ended abnormally".into(),
        };
        if can_restart {
            c.absorb_current();
            c.restarts += 1;
            let backoff = c.spec.backoff_ms.saturating_mul(1 << (c.restarts - 1).min(10));
            c.restart_at = Some(Instant::now() + Duration::from_millis(backoff));
            tracing::warn!("node '{}' {what}; restarting in {backoff} ms", c.spec.name);
        } else if failure.is_none() {
            failure = Some(Failure {
                node: c.spec.name.clone(),
                message: format!("node '{}' {what}", c.spec.name),
            });
        }
    }
    failure
}

fn tv(t: libc::timeval) -> Duration {
    Duration::from_secs(t.tv_sec as u64) + Duration::from_micros(t.tv_usec as u64)
}

/// SIGTERM to every running child, SIGKILL after 5 s. Only these end as `Stopped`: a node killed before (the one
/// whose failure stops the run) keeps its signal in the summary.
fn stop_all(children: &mut [Child]) {
    let running: Vec<bool> = children.iter().map(|c| c.pid.is_some()).collect();
    for c in children.iter_mut() {
        c.restart_at = None;
        if let Some(pid) = c.pid {
            // SAFETY: signalling our own child.
            unsafe { libc::kill(pid, libc::SIGTERM) };
        }
    }
    let deadline = Instant::now() + Duration::from_secs(5);
    while children.iter().any(|c| c.pid.is_some()) && Instant::now() < deadline {
        reap(children, false);
        std::thread::sleep(Duration::from_millis(10));
    }
    for c in children.iter_mut() {
        if let Some(pid) = c.pid {
            // SAFETY: as above.
            unsafe { libc::kill(pid, libc::SIGKILL) };
        }
    }
    while children.iter().any(|c| c.pid.is_some()) {
        reap(children, false);
        std::thread::sleep(Duration::from_millis(5));
    }
    for (c, _) in children.iter_mut().zip(running).filter(|(_, running)| *running) {
        if matches!(c.end, NodeEnd::Signalled(libc::SIGTERM) | NodeEnd::Signalled(libc::SIGKILL)) {
            c.end = NodeEnd::Stopped;
        }
    }
}

fn drain_status(sub: &iceoryx2::port::subscriber::Subscriber<ipc::Service, NodeStatus, ()>, children: &mut [Child]) {
    while let Ok(Some(sample)) = sub.receive() {
        let s = *sample.payload();
        if let Some(c) = children.get_mut(s.node_index as usize) {
            // Only the live instance's reports count; a late report from a dead instance is already absorbed.
            if c.pid == Some(s.pid as i32) {
                c.current = s;
            }
        }
    }
}

fn merge_ranges(ranges: &[(u64, u64)]) -> Vec<(u64, u64)> {
    let mut v = ranges.to_vec();
    v.sort_unstable();
    let mut out: Vec<(u64, u64)> = Vec::new();
    for (a, b) in v {
        match out.last_mut() {
            Some(last) if a <= last.1 + 1 => last.1 = last.1.max(b),
            _ => out.push((a, b)),
        }
    }
    out
}

/// The progress line, redrawn four times a second on a terminal and every ten seconds (when it changed) in a log.
struct Progress {
    total: Option<u64>,
    start: Instant,
    period: Duration,
    last: Option<(Instant, String)>,
}

impl Progress {
    fn new(total: Option<u64>, tty: bool) -> Self {
        Self {
            total,
            start: Instant::now(),
            period: Duration::from_millis(if tty { 250 } else { 10_000 }),
            last: None,
        }
    }

    fn line(&self, children: &[Child], graph: &Graph) -> String {
        let nodes: Vec<NodeProgress> = children
            .iter()
            .map(|c| NodeProgress {
                name: c.spec.name.clone(),
                frames: c.frames(),
                finished: c.finished(),
                tracked: !graph.is_source(&c.spec.name) && !launch::is_observer(&c.spec.name),
            })
            .collect();
        // Sources that have ended have published every frame: the furthest stage's count is the total.
        let sources_ended = children.iter().filter(|c| graph.is_source(&c.spec.name)).all(Child::finished);
        let furthest = nodes.iter().filter(|n| n.tracked).map(|n| n.frames).max();
        let total = self.total.or(furthest.filter(|_| sources_ended));
        progress_line(&nodes, total, self.start.elapsed())
    }

    fn show(&mut self, children: &[Child], graph: &Graph, console: &Console) {
        if self.last.as_ref().is_some_and(|(t, _)| t.elapsed() < self.period) {
            return;
        }
        let line = self.line(children, graph);
        // In a log, an unchanged line says nothing new.
        let changed = self.last.as_ref().is_none_or(|(_, l)| *l != line) || console.is_tty();
        if changed {
            console.progress(&line);
        }
        self.last = Some((Instant::now(), line));
    }

    /// The last line, always: a short run may end before the first periodic one.
    fn finish(&mut self, children: &[Child], graph: &Graph, console: &Console) {
        console.progress(&self.line(children, graph));
        console.end_progress();
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn missed_ranges_merge_when_adjacent_or_overlapping() {
        assert_eq!(
            merge_ranges(&[(5, 6), (1, 2), (3, 3), (6, 9), (12, 12)]),
            vec![(1, 3), (5, 9), (12, 12)]
        );
    }
}
