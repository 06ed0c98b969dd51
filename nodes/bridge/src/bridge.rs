//! A host's bridge at work: the topics it sends and receives, its peers, and the exchange that ends a run on every
//! host at once.
//!
//! A sending host puts a topic's messages as they come (at most a window ahead of each receiving host), then an
//! `end` tag once the topic has ended here; each receiving host publishes what arrives into its own graph, returns
//! credit, and on the `end` publishes the topic's end-of-stream and replies that it took it. A sender is done when
//! every receiver took the end of every topic; a receiver when every topic it receives has ended.
use std::collections::{BTreeMap, BTreeSet, VecDeque};
use std::path::PathBuf;
use std::time::{Duration, Instant};

use anyhow::{anyhow, bail, Context, Result};
use crossbeam::channel::{Receiver, Sender};
use lineflow_messages::image::ImageFormat;
use lineflow_messages::schema::{decode_view, encode, read_pod, Decoded};
use lineflow_messages::{MessageKind, NodeStatus, Stamp};
use lineflow_recordings::image_codec::{restore_parts, ImageCompressor};
use lineflow_runtime::host_reports::{report_path, HostReport, RemoteNode};
use lineflow_runtime::hosts::{BridgePlan, Crossing, BRIDGE};
use lineflow_runtime::launch::{EdgePolicy, Graph};
use lineflow_runtime::seen::Seen;
use lineflow_runtime::tap::{update_ended, Emit, Topic};
use lineflow_runtime::{NodeContext, StatusWatch};
use zenoh::bytes::ZBytes;
use zenoh::qos::CongestionControl;
use zenoh::sample::{Sample, SampleKind};
use zenoh::Wait;

use crate::credit::Window;
use crate::session;
use crate::wire::{check_topic, packing, Keys, Reply, Tag};

/// How long a host that left is given before the run ends: what it sent before leaving may still be on its way.
const GONE_GRACE: Duration = Duration::from_secs(1);
/// With restarting bridges, how long a restarted one takes to be back, besides its supervisor's wait.
const RESTART_GRACE: Duration = Duration::from_secs(5);
/// How long a host waits, once its own work is done, for the hosts that send to it to leave first: they wait for
/// its last replies, which closing its session at once could lose.
const PARTING: Duration = Duration::from_secs(5);
/// How long a host's bridge waits, at the end, for its nodes to report finishing before it reports them.
const REPORT_WAIT: Duration = Duration::from_secs(2);

/// What the Zenoh callbacks hand to the bridge's thread.
enum Event {
    /// A put on a data key: the index of the incoming topic, its CDR, its attachment read.
    Data {
        topic: usize,
        cdr: Vec<u8>,
        tag: Result<Tag, String>,
    },
    /// A receiving host's reply.
    Reply(Result<Reply, String>),
    /// A host was interrupted.
    Stop(String),
    /// A liveliness token appeared (`alive`) or went.
    Peer { key: String, alive: bool },
    /// Another host's nodes at the end of its run.
    Report(Result<HostReport, String>),
}

/// A topic published on this host and read on others.
struct Outgoing {
    hosts: Vec<String>,
    publisher: zenoh::pubsub::Publisher<'static>,
    window: Window,
    /// How its images are packed (raw for every other kind).
    packed: ImageFormat,
    /// The attachment of its messages.
    tag: Vec<u8>,
    /// Its last messages, to re-send to a restarted receiving bridge (`[bridge] restart`), at most `keep`.
    kept: VecDeque<ZBytes>,
    keep: usize,
    end_sent: bool,
    /// Hosts that took the end.
    taken: BTreeSet<String>,
}

/// A topic published on another host and read here.
pub struct Incoming {
    topic: String,
    kind: MessageKind,
    /// The tag its messages must carry.
    want: Tag,
    from: String,
    emit: Box<dyn Emit>,
    ended: bool,
    /// Published since the last reply: the credit owed to the sending host.
    owed: u64,
    /// What was published, to drop what a restarted sending bridge re-sends.
    seen: Seen,
    /// Dropped so.
    repeats: u64,
    /// This bridge was restarted and takes nothing until the sending host re-sends what it kept.
    awaiting_resend: bool,
}

impl Incoming {
    /// The topic `crossing` names, of `kind`, published here through `emit`.
    pub fn new(crossing: &Crossing, kind: MessageKind, emit: Box<dyn Emit>) -> Self {
        Self {
            topic: crossing.topic.clone(),
            kind,
            want: Tag::of(kind),
            from: crossing.hosts.first().cloned().unwrap_or_default(),
            emit,
            ended: false,
            owed: 0,
            seen: Seen::default(),
            repeats: 0,
            awaiting_resend: false,
        }
    }
}

/// A host's bridge.
pub struct Bridge {
    plan: BridgePlan,
    keys: Keys,
    session: zenoh::Session,
    topics: Vec<Topic>,
    outgoing: Vec<Outgoing>,
    incoming: Vec<Incoming>,
    /// Peers whose token is up.
    seen: BTreeSet<String>,
    /// Peers whose token went, and when.
    gone: BTreeMap<String, Instant>,
    events: Receiver<Event>,
    /// Events taken while waiting for the peers, handled once the graph here is connected.
    early: VecDeque<Event>,
    scratch: Decoded,
    /// Packs the images this host sends.
    compressor: ImageCompressor,
    /// This host's nodes (index in its part, name), the bridge left out: what its report names.
    nodes: Vec<(u32, String)>,
    /// The run's output folder, where the other hosts' reports are kept.
    out: PathBuf,
    /// Kept for their lifetime: dropping them undeclares them.
    _subscribers: Vec<zenoh::pubsub::Subscriber<()>>,
    _token: zenoh::liveliness::LivelinessToken,
}

fn zenoh_error(what: &'static str) -> impl Fn(zenoh::Error) -> anyhow::Error {
    move |e| anyhow!("{what}: {e}")
}

impl Bridge {
    /// Opens the Zenoh session and declares everything the bridge exchanges: a publisher per topic sent (`topics`,
    /// the bridge's subscriptions), a subscriber per topic received, the replies, the stops, the hosts' tokens and
    /// its own.
    ///
    /// # Errors
    /// A topic that cannot be a key, an endpoint that cannot be used, or a declaration Zenoh refuses.
    pub fn open(plan: BridgePlan, graph: &Graph, topics: Vec<Topic>, incoming: Vec<Incoming>, out: PathBuf) -> Result<Self> {
        for c in plan.send.iter().chain(&plan.receive) {
            check_topic(&c.topic).map_err(anyhow::Error::msg)?;
        }
        let keys = Keys::new(&plan.graph, &plan.hash);
        let session = zenoh::open(session::config(&plan)?)
            .wait()
            .map_err(|e| anyhow!("host '{}': cannot open the Zenoh session {}: {e}", plan.host, endpoints(&plan)))?;
        let mut outgoing = Vec::new();
        for t in &topics {
            let crossing = plan
                .send
                .iter()
                .find(|c| c.topic == t.name)
                .with_context(|| format!("the bridge subscribes to '{}', which its plan does not send", t.name))?;
            let edge = graph.input_edge(BRIDGE, &t.name).context("the bridge's input edge")?;
            let latest = edge.policy == EdgePolicy::Latest;
            let publisher = session
                .declare_publisher(keys.data(&t.name))
                .congestion_control(if latest {
                    CongestionControl::Drop
                } else {
                    CongestionControl::Block
                })
                .wait()
                .map_err(zenoh_error("cannot declare a Zenoh publisher"))?;
            outgoing.push(Outgoing {
                hosts: crossing.hosts.clone(),
                publisher,
                window: Window::new(&crossing.hosts, crossing.window.max(1)),
                packed: packing(t.kind, plan.images),
                tag: Tag::packed(t.kind, plan.images).to_bytes(),
                kept: VecDeque::new(),
                keep: crossing.keep,
                end_sent: false,
                taken: BTreeSet::new(),
            });
        }
        let (tx, events) = crossbeam::channel::unbounded();
        let subscribers = declare_subscribers(&session, &keys, &plan, &incoming, &tx)?;
        let token = session
            .liveliness()
            .declare_token(keys.token(&plan.host))
            .wait()
            .map_err(zenoh_error("cannot declare the host's liveliness token"))?;
        Ok(Self {
            plan,
            keys,
            session,
            topics,
            outgoing,
            incoming,
            seen: BTreeSet::new(),
            gone: BTreeMap::new(),
            events,
            early: VecDeque::new(),
            scratch: Decoded::default(),
            compressor: ImageCompressor::default(),
            nodes: graph
                .nodes
                .iter()
                .filter(|n| n.name != BRIDGE)
                .map(|n| (n.index, n.name.clone()))
                .collect(),
            out,
            _subscribers: subscribers,
            _token: token,
        })
    }

    /// One line on what this bridge carries.
    pub fn describe(&self) -> String {
        let packed: Vec<String> = self
            .topics
            .iter()
            .zip(&self.outgoing)
            .filter_map(|(t, o)| o.packed.name().map(|f| format!("{} as {f}", t.name)))
            .collect();
        format!(
            "host '{}': {} topics out{}, {} in, with {}",
            self.plan.host,
            self.outgoing.len(),
            if packed.is_empty() {
                String::new()
            } else {
                format!(" ({})", packed.join(", "))
            },
            self.incoming.len(),
            self.plan.peers.join(", ")
        )
    }

    /// Waits until every peer's token is up, within `timeout`; what else arrives meanwhile is kept for later.
    ///
    /// # Errors
    /// A peer of another graph, peers missing after `timeout` (named, with this host's endpoints), or an interrupt.
    pub fn wait_for_peers(&mut self, ctx: &NodeContext, timeout: Duration) -> Result<()> {
        let deadline = Instant::now() + timeout;
        loop {
            let missing: Vec<&str> = self
                .plan
                .peers
                .iter()
                .filter(|p| !self.seen.contains(*p))
                .map(String::as_str)
                .collect();
            if missing.is_empty() {
                return Ok(());
            }
            if ctx.should_stop() {
                bail!("interrupted while waiting for host {}", missing.join(", "));
            }
            if Instant::now() > deadline {
                let tls = if self.plan.tls.is_some() {
                    " With [bridge.tls] a host also stays unseen when its certificate is not signed by the `ca`, does not name the address it is reached at, or does not carry the common name of a host of the graph (Zenoh's log names the handshake that failed)."
                } else {
                    ""
                };
                bail!(
                    "host {} did not appear within {timeout:?} (this host '{}' is {}): is `lineflow run GRAPH --host NAME` running there, with the same launch file?{tls}",
                    missing.join(", "),
                    self.plan.host,
                    endpoints(&self.plan)
                );
            }
            match self.events.recv_timeout(Duration::from_millis(50)) {
                Ok(Event::Peer { key, alive }) => self.on_peer(&key, alive)?,
                Ok(other) => self.early.push_back(other),
                Err(_) => {}
            }
        }
    }

    fn on_peer(&mut self, key: &str, alive: bool) -> Result<()> {
        let Some((host, hash)) = self.keys.parse_token(key) else {
            return Ok(());
        };
        if host == self.plan.host {
            return Ok(());
        }
        if hash != self.plan.hash {
            if alive {
                bail!(
                    "host '{host}' runs another version of graph '{}' (hash {hash}, here {}): start every host from the same launch file with the same --set options",
                    self.plan.graph,
                    self.plan.hash
                );
            }
            return Ok(());
        }
        if !self.plan.peers.iter().any(|p| p == host) {
            return Ok(());
        }
        if alive {
            self.seen.insert(host.to_owned());
            if self.gone.remove(host).is_some() {
                // A restarted bridge there: it is owed nothing of the instance that left, and learns which of its
                // topics ended here already (their publishers may be gone, and their history with them).
                tracing::info!("host '{host}' is back");
                for i in 0..self.incoming.len() {
                    if self.incoming[i].from == host {
                        self.incoming[i].owed = 0;
                        if self.incoming[i].ended {
                            self.reply(i, true)?;
                        }
                    }
                }
            }
        } else {
            self.gone.entry(host.to_owned()).or_insert_with(Instant::now);
        }
        Ok(())
    }

    /// Publishes what arrived from other hosts into this host's graph and returns them their credit.
    ///
    /// # Errors
    /// A message of another type or version, one that does not decode, a stop from another host, or a transport
    /// error.
    pub fn receive(&mut self) -> Result<()> {
        while let Some(event) = self.early.pop_front().or_else(|| self.events.try_recv().ok()) {
            match event {
                Event::Data { topic, cdr, tag } => self.on_data(topic, &cdr, tag)?,
                Event::Reply(reply) => {
                    let r = reply.map_err(|e| anyhow!("a reply from another host: {e}"))?;
                    if r.resend {
                        self.resend_to(&r.from)?;
                    } else if let Some(i) = self.topics.iter().position(|t| t.name == r.topic) {
                        let out = &mut self.outgoing[i];
                        out.window.grant(&r.from, r.credit);
                        if r.ended {
                            out.taken.insert(r.from);
                        }
                    }
                }
                Event::Stop(host) => bail!("host '{host}' was interrupted; its part of the graph and this one stop"),
                Event::Peer { key, alive } => self.on_peer(&key, alive)?,
                Event::Report(report) => self.keep_report(report),
            }
        }
        for i in 0..self.incoming.len() {
            if self.incoming[i].owed > 0 {
                self.reply(i, false)?;
            }
        }
        Ok(())
    }

    fn on_data(&mut self, i: usize, cdr: &[u8], tag: Result<Tag, String>) -> Result<()> {
        let me = self.plan.host.as_str();
        let inc = &mut self.incoming[i];
        let sender = inc.from.clone();
        let from = |e: String| anyhow!("from host '{sender}': {e}");
        let tag = tag.map_err(|e| from(format!("topic '{}': {e}", inc.topic)))?;
        tag.check(&inc.want, &inc.topic).map_err(from)?;
        match tag {
            Tag::Resend { to } => {
                if to == me && inc.awaiting_resend {
                    tracing::info!("'{}': host '{}' re-sends what it kept", inc.topic, inc.from);
                    inc.awaiting_resend = false;
                }
                Ok(())
            }
            // Sent before the sending host knew of the restart: it re-sends it after the marker.
            _ if inc.awaiting_resend => Ok(()),
            Tag::End => {
                // A latched topic has no end-of-stream (a late subscriber still gets its message): it ends for
                // this host's nodes when the bridge finishes. A restarted sending bridge ends a topic again.
                if !inc.ended && !inc.kind.latched() {
                    inc.emit.end()?;
                }
                inc.ended = true;
                self.reply(i, true)
            }
            Tag::Message { packed, .. } => {
                // Credit for every message put, kept or not: the sending host counted it.
                inc.owed += 1;
                if inc.ended {
                    inc.repeats += 1;
                    return Ok(());
                }
                let context = || format!("topic '{}' from host '{}'", inc.topic, inc.from);
                // The stamp first: a repeat is dropped before a packed image is decoded.
                let (header, payload) = decode_view(inc.kind, cdr, &mut self.scratch).with_context(context)?;
                let stamp: Stamp = read_pod(header);
                if inc.seen.is_repeat(stamp.frame, stamp.revision) {
                    inc.repeats += 1;
                    return Ok(());
                }
                inc.seen.take(stamp.frame, stamp.revision);
                if packed == ImageFormat::Raw {
                    inc.emit.emit(header, payload)
                } else {
                    let (header, pixels) = restore_parts(cdr, &mut self.scratch).with_context(context)?;
                    inc.emit.emit(&header, &pixels)
                }
            }
        }
    }

    /// Asks every host that sends here to re-send what it kept: this bridge was restarted, and what the instance
    /// before it had taken but not yet published died with it.
    ///
    /// # Errors
    /// A transport error.
    pub fn ask_for_resend(&mut self) -> Result<()> {
        let senders: BTreeSet<String> = self.incoming.iter().map(|i| i.from.clone()).collect();
        for inc in &mut self.incoming {
            inc.awaiting_resend = true;
        }
        for host in senders {
            let ask = Reply {
                from: self.plan.host.clone(),
                topic: String::new(),
                credit: 0,
                ended: false,
                resend: true,
            };
            self.session
                .put(self.keys.back(&host), serde_json::to_vec(&ask)?)
                .congestion_control(CongestionControl::Block)
                .wait()
                .map_err(zenoh_error("cannot ask the sending host to re-send"))?;
        }
        Ok(())
    }

    /// Re-sends what this host kept of every topic to `host`, whose bridge was restarted: a marker, the messages
    /// kept, and the topic's end when it has ended.
    fn resend_to(&mut self, host: &str) -> Result<()> {
        for (t, out) in self.topics.iter().zip(&mut self.outgoing) {
            if !out.hosts.iter().any(|h| h == host) {
                continue;
            }
            tracing::info!(
                "'{}': re-sending the last {} messages to host '{host}', restarted",
                t.name,
                out.kept.len()
            );
            out.window.reset(host);
            out.taken.remove(host);
            let marker = Tag::Resend { to: host.to_owned() };
            out.publisher
                .put(Vec::<u8>::new())
                .attachment(marker.to_bytes())
                .wait()
                .map_err(zenoh_error("cannot put a re-send's marker"))?;
            for bytes in &out.kept {
                out.publisher
                    .put(bytes.clone())
                    .attachment(out.tag.clone())
                    .wait()
                    .map_err(zenoh_error("cannot re-send a message"))?;
                out.window.sent();
            }
            if out.end_sent {
                out.publisher
                    .put(Vec::<u8>::new())
                    .attachment(Tag::End.to_bytes())
                    .wait()
                    .map_err(zenoh_error("cannot put a topic's end"))?;
            }
        }
        Ok(())
    }

    fn reply(&mut self, i: usize, ended: bool) -> Result<()> {
        let inc = &mut self.incoming[i];
        let reply = Reply {
            from: self.plan.host.clone(),
            topic: inc.topic.clone(),
            credit: std::mem::take(&mut inc.owed),
            ended,
            resend: false,
        };
        self.session
            .put(self.keys.back(&inc.from), serde_json::to_vec(&reply)?)
            .congestion_control(CongestionControl::Block)
            .wait()
            .map_err(zenoh_error("cannot reply to the sending host"))
    }

    /// Puts what this host's graph published for other hosts, as far as their windows allow, and each topic's end
    /// once it has ended here.
    ///
    /// # Errors
    /// A transport error.
    pub fn send(&mut self, status: Option<&mut StatusWatch>) -> Result<()> {
        // Status first: what a finished publisher sent is already waiting, and the drain below takes it.
        update_ended(&mut self.topics, status);
        for (t, out) in self.topics.iter_mut().zip(&mut self.outgoing) {
            let room = out.window.room() as usize;
            let kind = t.kind;
            let (publisher, tag, packed) = (&out.publisher, &out.tag, out.packed);
            let (kept, keep) = (&mut out.kept, out.keep);
            let compressor = &mut self.compressor;
            let mut put = 0;
            t.messages += t.tap.drain_some(room, &mut |_, header, payload| {
                let mut cdr = Vec::new();
                if packed == ImageFormat::Raw {
                    encode(kind, header, payload, &mut cdr);
                } else {
                    compressor
                        .compress_parts(header, payload, packed, self.plan.jpeg_quality, &mut cdr)
                        .with_context(|| format!("cannot pack an image of '{}' as {packed:?}", t.name))?;
                }
                let bytes = ZBytes::from(cdr);
                if keep > 0 {
                    if kept.len() == keep {
                        kept.pop_front();
                    }
                    kept.push_back(bytes.clone());
                }
                publisher
                    .put(bytes)
                    .attachment(tag.clone())
                    .wait()
                    .map_err(zenoh_error("cannot put a message"))?;
                put += 1;
                Ok(())
            })? as u64;
            for _ in 0..put {
                out.window.sent();
            }
            if t.ended && put == 0 && room > 0 && !out.end_sent {
                out.publisher
                    .put(Vec::<u8>::new())
                    .attachment(Tag::End.to_bytes())
                    .wait()
                    .map_err(zenoh_error("cannot put a topic's end"))?;
                out.end_sent = true;
                tracing::debug!("'{}' ended after {} messages", t.name, t.messages);
            }
        }
        Ok(())
    }

    fn done_with(&self, host: &str) -> bool {
        let received = self.incoming.iter().filter(|i| i.from == host).all(|i| i.ended);
        let sent = self
            .outgoing
            .iter()
            .filter(|o| o.hosts.iter().any(|h| h == host))
            .all(|o| o.taken.contains(host));
        received && sent
    }

    /// Ends the run when a peer left before it was done with this host.
    ///
    /// # Errors
    /// The host that left and the topics it leaves unfinished.
    pub fn check_peers(&self) -> Result<()> {
        let grace = self
            .plan
            .restart_wait_ms
            .map_or(GONE_GRACE, |ms| Duration::from_millis(ms) + RESTART_GRACE);
        for (host, since) in &self.gone {
            if since.elapsed() < grace || self.done_with(host) {
                continue;
            }
            let open: Vec<&str> = self
                .incoming
                .iter()
                .filter(|i| &i.from == host && !i.ended)
                .map(|i| i.topic.as_str())
                .chain(
                    self.topics
                        .iter()
                        .zip(&self.outgoing)
                        .filter(|(_, o)| o.hosts.contains(host) && !o.taken.contains(host))
                        .map(|(t, _)| t.name.as_str()),
                )
                .collect();
            bail!(
                "host '{host}' is gone (its bridge left the Zenoh session{}) before these topics ended: {}",
                if self.plan.restart_wait_ms.is_some() {
                    " and was not back in time"
                } else {
                    ""
                },
                open.join(", ")
            );
        }
        Ok(())
    }

    /// Whether every topic has ended here and been taken by every host it goes to.
    pub fn done(&self) -> bool {
        self.plan.peers.iter().all(|p| self.done_with(p))
    }

    /// Keeps another host's report for the summary of this host's supervisor; one that does not read is named.
    fn keep_report(&self, report: Result<HostReport, String>) {
        let kept = report.and_then(|r| {
            let path = report_path(&self.out, &r.host);
            std::fs::create_dir_all(path.parent().unwrap_or(&self.out))
                .and_then(|()| std::fs::write(&path, serde_json::to_vec_pretty(&r).unwrap_or_default()))
                .map_err(|e| format!("cannot write {}: {e}", path.display()))
        });
        if let Err(e) = kept {
            tracing::warn!("another host's report is left out of the summary: {e}");
        }
    }

    /// Tells the other hosts what this host's nodes did, once they have all reported finishing (at most
    /// [`REPORT_WAIT`]: a node that did not is reported unfinished).
    pub fn send_report(&self, status: &mut StatusWatch) {
        let deadline = Instant::now() + REPORT_WAIT;
        loop {
            let latest = status.poll();
            let finished = |i: &u32| latest.get(i).is_some_and(|s| s.flags & NodeStatus::FINISHED != 0);
            if self.nodes.iter().all(|(i, _)| finished(i)) || Instant::now() > deadline {
                break;
            }
            std::thread::sleep(Duration::from_millis(20));
        }
        let latest = status.poll();
        let report = HostReport {
            host: self.plan.host.clone(),
            nodes: self
                .nodes
                .iter()
                .map(|(i, name)| {
                    let s = latest.get(i).copied().unwrap_or_default();
                    RemoteNode {
                        name: name.clone(),
                        finished: s.flags & NodeStatus::FINISHED != 0,
                        msgs_in: s.msgs_in,
                        msgs_out: s.msgs_out,
                        drops: s.drops,
                        duplicates: s.duplicates,
                        missed: s.missed,
                    }
                })
                .collect(),
        };
        let sent = serde_json::to_vec(&report).map_err(|e| e.to_string()).and_then(|bytes| {
            self.session
                .put(self.keys.report(&self.plan.host), bytes)
                .congestion_control(CongestionControl::Block)
                .wait()
                .map_err(|e| e.to_string())
        });
        if let Err(e) = sent {
            tracing::warn!("cannot send this host's report to the others: {e}");
        }
    }

    /// Tells the other hosts this one was interrupted.
    pub fn say_stopped(&self) {
        let _ = self.session.put(self.keys.stop(), self.plan.host.clone()).wait();
    }

    /// Closes the session; after a finished run, first waits (at most [`PARTING`]) for the hosts that send here
    /// to leave, as they wait for this host's last replies.
    pub fn close(mut self, finished: bool) {
        for inc in self.incoming.iter().filter(|i| i.repeats > 0) {
            tracing::info!(
                "'{}': dropped {} messages re-sent after a restart, already published",
                inc.topic,
                inc.repeats
            );
        }
        if finished {
            let senders: BTreeSet<String> = self.incoming.iter().map(|i| i.from.clone()).collect();
            let deadline = Instant::now() + PARTING;
            while senders.iter().any(|h| !self.gone.contains_key(h)) && Instant::now() < deadline {
                match self.events.recv_timeout(Duration::from_millis(20)) {
                    Ok(Event::Peer { key, alive }) => {
                        let _ = self.on_peer(&key, alive);
                    }
                    Ok(Event::Report(report)) => self.keep_report(report),
                    _ => {}
                }
            }
        }
        let _ = self.session.close().wait();
    }
}

/// Where a host's bridge meets the others, for messages.
fn endpoints(plan: &BridgePlan) -> String {
    if plan.listen.is_empty() {
        format!("connecting to {}", plan.connect.join(", "))
    } else {
        format!("listening on {}", plan.listen.join(", "))
    }
}

fn declare_subscribers(
    session: &zenoh::Session,
    keys: &Keys,
    plan: &BridgePlan,
    incoming: &[Incoming],
    tx: &Sender<Event>,
) -> Result<Vec<zenoh::pubsub::Subscriber<()>>> {
    let mut subscribers = Vec::new();
    for (i, inc) in incoming.iter().enumerate() {
        let tx = tx.clone();
        let sub = session
            .declare_subscriber(keys.data(&inc.topic))
            .callback(move |s: Sample| {
                let tag = s
                    .attachment()
                    .map(|a| Tag::parse(&a.to_bytes()))
                    .unwrap_or_else(|| Err("a put without the bridge's attachment".into()));
                let _ = tx.send(Event::Data {
                    topic: i,
                    cdr: s.payload().to_bytes().into_owned(),
                    tag,
                });
            })
            .wait()
            .map_err(zenoh_error("cannot declare a Zenoh subscriber"))?;
        subscribers.push(sub);
    }
    let replies = tx.clone();
    subscribers.push(
        session
            .declare_subscriber(keys.back(&plan.host))
            .callback(move |s: Sample| {
                let reply = serde_json::from_slice::<Reply>(&s.payload().to_bytes()).map_err(|e| e.to_string());
                let _ = replies.send(Event::Reply(reply));
            })
            .wait()
            .map_err(zenoh_error("cannot declare the replies' subscriber"))?,
    );
    let stops = tx.clone();
    subscribers.push(
        session
            .declare_subscriber(keys.stop())
            .callback(move |s: Sample| {
                let host = String::from_utf8_lossy(&s.payload().to_bytes()).into_owned();
                let _ = stops.send(Event::Stop(host));
            })
            .wait()
            .map_err(zenoh_error("cannot declare the stops' subscriber"))?,
    );
    let reports = tx.clone();
    let me = plan.host.clone();
    subscribers.push(
        session
            .declare_subscriber(keys.reports())
            .callback(move |s: Sample| {
                let report = serde_json::from_slice::<HostReport>(&s.payload().to_bytes()).map_err(|e| e.to_string());
                if report.as_ref().is_ok_and(|r| r.host == me) {
                    return;
                }
                let _ = reports.send(Event::Report(report));
            })
            .wait()
            .map_err(zenoh_error("cannot declare the reports' subscriber"))?,
    );
    let peers = tx.clone();
    subscribers.push(
        session
            .liveliness()
            .declare_subscriber(keys.tokens())
            .history(true)
            .callback(move |s: Sample| {
                let _ = peers.send(Event::Peer {
                    key: s.key_expr().as_str().to_owned(),
                    alive: s.kind() == SampleKind::Put,
                });
            })
            .wait()
            .map_err(zenoh_error("cannot declare the hosts' liveliness subscriber"))?,
    );
    Ok(subscribers)
}
