//! The node SDK: what a stage's `main` uses to talk to the graph.
//!
//! ```no_run
//! use lineflow_messages::kinds::Image;
//! # fn main() -> anyhow::Result<()> {
//! let ctx = lineflow_runtime::NodeContext::from_env()?;
//! let images = ctx.input::<Image>("images")?;
//! let out = ctx.output::<Image>("gray")?;
//! ctx.connect()?;
//! ctx.run(|| {
//!     while let Some(msg) = images.receive()? {
//!         out.publish(*msg.user_header(), msg.payload())?;
//!     }
//!     Ok(if images.is_ended() { lineflow_runtime::Flow::Stop } else { lineflow_runtime::Flow::Continue })
//! })?;
//! out.end_of_stream()?;
//! # Ok(()) }
//! ```

use std::cell::RefCell;
use std::rc::Rc;
use std::time::Duration;

use anyhow::{bail, Context, Result};
use iceoryx2::prelude::*;
use lineflow_messages::Message;
use serde::de::DeserializeOwned;

use crate::describe::{Port, Ports};
use crate::env::{self, RunEnv};
use crate::launch::{Graph, NodeSpec};
use crate::ports::{Connect, Input, Output, RUN_TICK};
use crate::report::Reporter;
use crate::transport;

/// What the loop callback wants next.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Flow {
    /// Wait for more input.
    Continue,
    /// Leave the loop.
    Stop,
}

/// How [`NodeContext::run`] ended.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum RunEnd {
    /// The callback returned [`Flow::Stop`].
    Finished,
    /// SIGINT or SIGTERM arrived.
    Interrupted,
}

/// Longest wait in [`NodeContext::finish`] for the subscribers to leave.
pub const LINGER: Duration = Duration::from_secs(30);

type Listener = iceoryx2::port::listener::Listener<ipc::Service>;

/// A running node: its place in the graph, parameters, ports and counters.
pub struct NodeContext {
    env: Option<RunEnv>,
    graph: Graph,
    spec: NodeSpec,
    node: Option<Node<ipc::Service>>,
    ports: RefCell<Ports>,
    listeners: RefCell<Vec<Rc<Listener>>>,
    connects: RefCell<Vec<Rc<dyn Connect>>>,
    reporter: Rc<Reporter>,
    ready: Option<iceoryx2::port::notifier::Notifier<ipc::Service>>,
    start: Option<Listener>,
    /// The process that started this node (the supervisor), as it was at the start.
    supervisor: u32,
}

impl NodeContext {
    /// Sets up logging and joins the run named by the environment (`docs/nodes.md`). In describe mode
    /// (`--describe`), ports are only recorded and [`connect`](Self::connect) prints them and exits.
    ///
    /// # Errors
    /// When the environment is incomplete, the graph file unreadable, or iceoryx2 refuses the node.
    pub fn from_env() -> Result<Self> {
        let describe = RunEnv::describe_requested();
        let node_name = std::env::var(env::NODE).unwrap_or_else(|_| "node".into());
        crate::logging::init(&node_name);
        let graph_path = std::env::var(env::GRAPH).with_context(|| {
            format!(
                "{} is not set: start stage binaries with `lineflow run` (docs/nodes.md)",
                env::GRAPH
            )
        })?;
        let graph: Graph = serde_json::from_slice(&std::fs::read(&graph_path).with_context(|| format!("cannot read graph {graph_path}"))?)
            .with_context(|| format!("malformed graph {graph_path}"))?;
        let spec = graph
            .node(&node_name)
            .cloned()
            .with_context(|| format!("node '{node_name}' is not in graph {graph_path}"))?;
        if describe {
            return Ok(Self {
                env: None,
                graph,
                spec,
                node: None,
                ports: RefCell::default(),
                listeners: RefCell::default(),
                connects: RefCell::default(),
                reporter: Rc::new(Reporter::new(0, None, false)),
                ready: None,
                start: None,
                supervisor: std::os::unix::process::parent_id(),
            });
        }
        let env = RunEnv::from_env()?;
        let cfg = transport::config(&env.prefix, &env.root)?;
        let node = transport::create_node(&cfg, &spec.name)?;
        let status = transport::open_status(&node)?
            .publisher_builder()
            .max_loaned_samples(1)
            .create()
            .map_err(|e| anyhow::anyhow!("cannot publish status: {e:?}"))?;
        let ready = transport::open_event(&node, transport::READY_SERVICE)?
            .notifier_builder()
            .default_event_id(EventId::new(spec.index as usize))
            .create()
            .map_err(|e| anyhow::anyhow!("cannot create readiness notifier: {e:?}"))?;
        let start = if graph.is_source(&spec.name) && env.restart == 0 {
            Some(
                transport::open_event(&node, transport::START_SERVICE)?
                    .listener_builder()
                    .create()
                    .map_err(|e| anyhow::anyhow!("cannot listen for start: {e:?}"))?,
            )
        } else {
            None
        };
        let reporter = Rc::new(Reporter::new(spec.index, Some(status), env.restart > 0));
        Ok(Self {
            env: Some(env),
            graph,
            spec,
            node: Some(node),
            ports: RefCell::default(),
            listeners: RefCell::default(),
            connects: RefCell::default(),
            reporter,
            ready: Some(ready),
            start,
            supervisor: std::os::unix::process::parent_id(),
        })
    }

    /// This node's name.
    pub fn name(&self) -> &str {
        &self.spec.name
    }

    /// The resolved graph.
    pub fn graph(&self) -> &Graph {
        &self.graph
    }

    /// How often the supervisor restarted this node (0 for its first instance).
    pub fn restarts(&self) -> u32 {
        self.env.as_ref().map_or(0, |e| e.restart)
    }

    /// The run's output folder.
    pub fn out_dir(&self) -> std::path::PathBuf {
        self.env.as_ref().map(|e| e.out.clone()).unwrap_or_else(|| ".".into())
    }

    /// The parameters as a typed struct. Unknown keys are errors when the struct has `#[serde(deny_unknown_fields)]`
    /// (it should: a typo in a launch file must not pass silently). `impl` is removed first.
    ///
    /// # Errors
    /// A message naming the node and the offending parameter.
    pub fn params<P: DeserializeOwned>(&self) -> Result<P> {
        let mut map = self.spec.params.clone();
        map.remove("impl");
        serde_json::from_value(serde_json::Value::Object(map)).with_context(|| format!("node '{}': invalid parameters", self.spec.name))
    }

    /// The parameters as a typed struct, checked against their ranges ([`StageParams::validate`]).
    ///
    /// # Errors
    /// As [`NodeContext::params`], or the first value out of range, named with the node.
    pub fn stage_params<P: crate::StageParams>(&self) -> Result<P> {
        let p: P = self.params()?;
        p.validate().map_err(|e| anyhow::anyhow!("node '{}': {e}", self.spec.name))?;
        Ok(p)
    }

    /// The `impl` parameter, or `default`.
    pub fn implementation<'a>(&'a self, default: &'a str) -> &'a str {
        self.spec.implementation.as_deref().unwrap_or(default)
    }

    fn declare(&self, port: &str, kind: &str, input: bool, required: bool) {
        let p = Port {
            port: port.into(),
            message: kind.into(),
            required,
            max_payload_bytes: None,
        };
        let mut ports = self.ports.borrow_mut();
        if input {
            ports.inputs.push(p)
        } else {
            ports.outputs.push(p)
        }
    }

    /// Subscribes to port `port` (the topic of the same name unless remapped). Required: the node fails at startup
    /// when it is not wired.
    ///
    /// # Errors
    /// When the port is not wired, carries another message type, or iceoryx2 refuses the subscriber.
    pub fn input<M: Message>(&self, port: &str) -> Result<Input<M>> {
        self.input_opt::<M>(port, true)?.with_context(|| {
            format!(
                "node '{}': input port '{port}' ({}) is not wired in the launch graph",
                self.spec.name,
                M::KIND.name()
            )
        })
    }

    /// Subscribes to `port` if the graph wires it.
    ///
    /// # Errors
    /// As [`input`](Self::input), except that an unwired port gives `Ok(None)`.
    pub fn optional_input<M: Message>(&self, port: &str) -> Result<Option<Input<M>>> {
        self.input_opt::<M>(port, false)
    }

    fn input_opt<M: Message>(&self, port: &str, required: bool) -> Result<Option<Input<M>>> {
        self.declare(port, M::KIND.name(), true, required);
        let Some(node) = &self.node else {
            return Ok(Some(Input::declared()));
        };
        let topic = self.spec.topic_of(port);
        let Some(edge) = self.graph.input_edge(&self.spec.name, topic) else {
            return Ok(None);
        };
        check_kind::<M>(edge, &self.spec.name, port)?;
        let slot = self.listeners.borrow().len();
        let resume = self.env.as_ref().and_then(|e| {
            e.resume
                .iter()
                .find(|(t, _, _)| t == topic)
                .map(|(_, next, replay)| (*next, *replay))
        });
        if let Some((next, _)) = resume {
            self.reporter.resume(slot, next);
        }
        let input = Input::<M>::open(node, &self.spec.name, edge, slot, self.reporter.clone(), resume)?;
        let listener = transport::open_event(node, topic)?
            .listener_builder()
            .create()
            .map_err(|e| anyhow::anyhow!("topic '{topic}': cannot create listener: {e:?}"))?;
        self.listeners.borrow_mut().push(Rc::new(listener));
        self.connects.borrow_mut().extend(input.inner.clone().map(|i| i as Rc<dyn Connect>));
        self.reporter.set_inputs(slot + 1);
        Ok(Some(input))
    }

    /// Declares the largest payload (bytes) the node will publish on output `port`. The supervisor sizes the edge
    /// from it when the launch file does not; call it before [`connect`](Self::connect).
    pub fn declare_max_payload(&self, port: &str, bytes: u64) {
        if let Some(p) = self.ports.borrow_mut().outputs.iter_mut().find(|p| p.port == port) {
            p.max_payload_bytes = Some(bytes);
        }
    }

    /// Publishes on port `port`. Required: the node fails at startup when it is not wired.
    ///
    /// # Errors
    /// When the port is not wired, carries another message type, or iceoryx2 refuses the publisher.
    pub fn output<M: Message>(&self, port: &str) -> Result<Output<M>> {
        self.output_opt::<M>(port, true)?.with_context(|| {
            format!(
                "node '{}': output port '{port}' ({}) is not wired in the launch graph",
                self.spec.name,
                M::KIND.name()
            )
        })
    }

    /// Publishes on `port` if the graph wires it.
    ///
    /// # Errors
    /// As [`output`](Self::output), except that an unwired port gives `Ok(None)`.
    pub fn optional_output<M: Message>(&self, port: &str) -> Result<Option<Output<M>>> {
        self.output_opt::<M>(port, false)
    }

    fn output_opt<M: Message>(&self, port: &str, required: bool) -> Result<Option<Output<M>>> {
        self.declare(port, M::KIND.name(), false, required);
        let Some(node) = &self.node else {
            return Ok(Some(Output::declared()));
        };
        let topic = self.spec.topic_of(port);
        let Some(edge) = self.graph.output_edge(&self.spec.name, topic) else {
            return Ok(None);
        };
        check_kind::<M>(edge, &self.spec.name, port)?;
        let output = Output::<M>::open(node, &self.spec.name, edge, self.reporter.clone())?;
        self.connects
            .borrow_mut()
            .extend(output.inner.clone().map(|i| i as Rc<dyn Connect>));
        Ok(Some(output))
    }

    /// Connects every port (waiting for the peers the graph promises) and tells the supervisor this node is ready.
    /// A source then waits for the supervisor's start signal. In describe mode, prints the ports and exits.
    ///
    /// # Errors
    /// When peers do not appear in time, or the run is interrupted while waiting.
    pub fn connect(&self) -> Result<()> {
        let Some(env) = &self.env else {
            println!("{}", serde_json::to_string(&*self.ports.borrow())?);
            std::process::exit(0);
        };
        let timeout = Duration::from_secs(
            std::env::var(env::CONNECT_TIMEOUT_S)
                .ok()
                .and_then(|v| v.parse().ok())
                .unwrap_or(30),
        );
        for c in self.connects.borrow().iter() {
            c.connect(timeout, env.restart > 0)?;
        }
        if let Some(ready) = &self.ready {
            ready.notify().map_err(|e| anyhow::anyhow!("cannot notify readiness: {e:?}"))?;
        }
        if let Some(start) = &self.start {
            let mut started = false;
            while !started {
                if self.should_stop() {
                    bail!("interrupted before the start signal");
                }
                start
                    .timed_wait(|_| started = true, Duration::from_millis(100))
                    .map_err(|e| anyhow::anyhow!("waiting for the start signal: {e:?}"))?;
            }
        }
        self.reporter.flush(true);
        tracing::debug!("connected");
        Ok(())
    }

    /// Whether SIGINT or SIGTERM arrived or the supervisor is gone; sources check it between frames.
    pub fn should_stop(&self) -> bool {
        self.supervisor_gone() || self.node.as_ref().is_some_and(|n| n.wait(Duration::ZERO).is_err())
    }

    /// Whether the supervisor that started this node has died (SIGKILL, a crash, a closed terminal): the node was
    /// handed to another parent. Nothing would ever stop the node then, and nobody reads its results; it ends as
    /// on SIGTERM, writing what it has (the recorder closes its file).
    pub fn supervisor_gone(&self) -> bool {
        let gone = self.env.is_some() && std::os::unix::process::parent_id() != self.supervisor;
        if gone {
            static SAID: std::sync::Once = std::sync::Once::new();
            SAID.call_once(|| tracing::error!("the supervisor (pid {}) is gone: stopping as on SIGTERM", self.supervisor));
        }
        gone
    }

    /// Blocks until input arrives and calls `on_wake`, until it returns [`Flow::Stop`] or a signal arrives. Never
    /// busy-polls: the process sleeps in a WaitSet on the inputs' event services. `on_wake` is also called once at
    /// the start, for messages that arrived before the loop (history, latched topics).
    ///
    /// # Errors
    /// The first error `on_wake` returns, or a WaitSet failure.
    pub fn run(&self, on_wake: impl FnMut() -> Result<Flow>) -> Result<RunEnd> {
        self.run_every(RUN_TICK, on_wake)
    }

    /// [`run`](Self::run), woken at least every `tick` besides on input: for a node whose work also comes from
    /// outside iceoryx2 (the bridge's messages from other hosts), which no event service announces.
    ///
    /// # Errors
    /// As [`run`](Self::run).
    pub fn run_every(&self, tick: Duration, mut on_wake: impl FnMut() -> Result<Flow>) -> Result<RunEnd> {
        let first = on_wake()?;
        self.reporter.commit();
        if first == Flow::Stop {
            return Ok(RunEnd::Finished);
        }
        let waitset = WaitSetBuilder::new()
            .create::<ipc::Service>()
            .map_err(|e| anyhow::anyhow!("cannot create WaitSet: {e:?}"))?;
        let listeners = self.listeners.borrow().clone();
        let mut guards = Vec::with_capacity(listeners.len());
        for l in &listeners {
            guards.push(
                waitset
                    .attach_notification(&**l)
                    .map_err(|e| anyhow::anyhow!("cannot attach listener: {e:?}"))?,
            );
        }
        let _tick = waitset
            .attach_interval(tick)
            .map_err(|e| anyhow::anyhow!("cannot attach interval: {e:?}"))?;
        let mut result = Ok(Flow::Continue);
        let mut orphaned = false;
        let mut on_event = |_id| {
            if self.supervisor_gone() {
                orphaned = true;
                return CallbackProgression::Stop;
            }
            for l in &listeners {
                let _ = l.try_wait(|_| {});
            }
            for c in self.connects.borrow().iter() {
                c.refresh();
            }
            self.reporter.flush(false);
            result = on_wake();
            self.reporter.commit();
            match result {
                Ok(Flow::Continue) => CallbackProgression::Continue,
                _ => CallbackProgression::Stop,
            }
        };
        let outcome = loop {
            let outcome = waitset
                .wait_and_process(&mut on_event)
                .map_err(|e| anyhow::anyhow!("WaitSet failed: {e:?}"))?;
            // A stop signal and SIGCONT (Ctrl-Z and `fg`, a debugger, a suspended laptop) end the WaitSet's epoll
            // with EINTR, which it reports as an interrupt although no SIGINT came: the node would quit mid-run and
            // its subscriptions would vanish under lossless publishers. A real SIGINT or SIGTERM is still seen: the
            // WaitSet checks for one before it waits again, and returns a termination request.
            if matches!(outcome, iceoryx2::waitset::WaitSetRunResult::Interrupt) {
                tracing::debug!("woken by a signal that asks nothing (SIGCONT after a stop); waiting on");
                continue;
            }
            break outcome;
        };
        result?;
        Ok(match outcome {
            _ if orphaned => RunEnd::Interrupted,
            iceoryx2::waitset::WaitSetRunResult::Interrupt | iceoryx2::waitset::WaitSetRunResult::TerminationRequest => RunEnd::Interrupted,
            _ => RunEnd::Finished,
        })
    }

    /// Subscribes to every node's counters (what the supervisor reports); `None` in describe mode.
    ///
    /// # Errors
    /// When iceoryx2 refuses the subscriber.
    pub fn watch_status(&self) -> Result<Option<StatusWatch>> {
        let Some(node) = &self.node else {
            return Ok(None);
        };
        let sub = transport::open_status(node)?
            .subscriber_builder()
            .buffer_size(256)
            .create()
            .map_err(|e| anyhow::anyhow!("cannot subscribe to the run's status: {e:?}"))?;
        Ok(Some(StatusWatch {
            sub,
            latest: std::collections::BTreeMap::new(),
        }))
    }

    /// The counters so far.
    pub fn status(&self) -> lineflow_messages::NodeStatus {
        self.reporter.snapshot()
    }

    /// Reports the final counters; call after the last end-of-stream is published. Then stays until the
    /// subscribers of every output have left (at most [`LINGER`]): iceoryx2 drops the samples of a publisher that
    /// exits before its subscribers took them, which would lose the last messages and the end-of-stream of a node
    /// that finishes quickly. Meanwhile whatever still arrives on the inputs is taken and dropped: a node may finish
    /// before an input's end (it had what it needed), and an upstream node blocked on it would keep every node in
    /// between waiting here, each for `LINGER` (a restarted `gray` made the demo graph take 30 s more that way).
    pub fn finish(&self) {
        self.reporter.finished();
        if self.env.is_none() {
            return;
        }
        let connects = self.connects.borrow();
        let mut dropped = 0;
        let drained = crate::transport::wait_until(LINGER, || {
            dropped += connects.iter().map(|c| c.discard()).sum::<usize>();
            self.should_stop() || connects.iter().all(|c| c.drained())
        });
        if dropped > 0 {
            tracing::debug!("{dropped} messages arrived after the node had finished; dropped");
        }
        if !drained {
            let held: Vec<&str> = connects.iter().filter(|c| !c.drained()).map(|c| c.topic()).collect();
            tracing::warn!("subscribers of {} still connected after {LINGER:?}; exiting", held.join(", "));
        }
    }
}

fn check_kind<M: Message>(edge: &crate::launch::EdgeSpec, node: &str, port: &str) -> Result<()> {
    if edge.message != M::KIND.name() {
        bail!(
            "node '{node}': port '{port}' takes {} but edge '{}' carries {}",
            M::KIND.name(),
            edge.topic,
            edge.message
        );
    }
    Ok(())
}

/// The latest counters of every node of the run, by node index.
pub struct StatusWatch {
    sub: iceoryx2::port::subscriber::Subscriber<ipc::Service, lineflow_messages::NodeStatus, ()>,
    latest: std::collections::BTreeMap<u32, lineflow_messages::NodeStatus>,
}

impl StatusWatch {
    /// Takes the reports that arrived and returns the latest per node. A restarted node's new instance starts its
    /// counters from zero; the latest report is that of the live instance.
    pub fn poll(&mut self) -> &std::collections::BTreeMap<u32, lineflow_messages::NodeStatus> {
        while let Ok(Some(sample)) = self.sub.receive() {
            let s = *sample.payload();
            self.latest.insert(s.node_index, s);
        }
        &self.latest
    }
}
