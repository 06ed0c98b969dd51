//! Typed inputs and outputs of a node: iceoryx2 publish-subscribe paired with an event service.
use std::cell::{Cell, RefCell};
use std::rc::Rc;
use std::time::Duration;

use anyhow::{bail, Context, Result};
use iceoryx2::port::update_connections::UpdateConnections;
use iceoryx2::port::{BackpressureAction, BackpressureInfo};
use iceoryx2::prelude::*;
use lineflow_messages::{Message, Stamp, StampFlags};

use crate::launch::EdgeSpec;
use crate::report::Reporter;
use crate::seen::Seen;
use crate::transport::{self, PubSub};

/// How often a waiting node wakes without input: to publish its status and pick up restarted publishers.
pub const RUN_TICK: Duration = Duration::from_millis(100);

/// A received message: zero-copy view into shared memory (`user_header()`, `payload()`).
pub type Received<M> = iceoryx2::sample::Sample<ipc::Service, [<M as Message>::Element], <M as Message>::Header>;

/// Something that takes part in the readiness handshake.
pub(crate) trait Connect {
    /// Waits for the peers the graph promises, then establishes the connections.
    fn connect(&self, timeout: Duration, restarted: bool) -> Result<()>;
    /// Picks up publishers that appeared since (a restarted upstream node).
    fn refresh(&self) {}
    /// Whether nothing this port sent can still be lost by the process exiting: an output whose subscribers have
    /// all gone (iceoryx2 discards the samples of a publisher that left before the subscriber took them).
    fn drained(&self) -> bool {
        true
    }
    /// The topic, for messages.
    fn topic(&self) -> &str;
    /// Takes and drops what waits on an input; how many. Called once the node has finished: a lossless publisher
    /// would otherwise wait for a node that no longer reads, while that node waits for its own subscribers to
    /// leave (each up to [`LINGER`](crate::node::LINGER)).
    fn discard(&self) -> usize {
        0
    }
}

/// A subscribed topic.
pub struct Input<M: Message> {
    /// `None` in describe mode, where ports are only declared.
    pub(crate) inner: Option<Rc<InputInner<M>>>,
}

pub(crate) struct InputInner<M: Message> {
    topic: String,
    node: String,
    service: PubSub<M>,
    subscriber: iceoryx2::port::subscriber::Subscriber<ipc::Service, [M::Element], M::Header>,
    slot: usize,
    reporter: Rc<Reporter>,
    ended: Cell<bool>,
    /// What was taken, for duplicate detection.
    seen: RefCell<Seen>,
    /// Frames up to this one were received by an earlier instance: a gap below it is not a miss.
    received_before: Option<u64>,
    /// Since when the topic has had no publisher while the input has not ended.
    orphaned_since: Cell<Option<std::time::Instant>>,
}

/// An input whose publisher has been gone this long without an end-of-stream is ended: longer than a restart's
/// back-off, so a restarting upstream node is waited for.
pub const ORPHAN_GRACE: Duration = Duration::from_secs(10);

impl<M: Message> Input<M> {
    pub(crate) fn open(
        node: &Node<ipc::Service>,
        name: &str,
        edge: &EdgeSpec,
        slot: usize,
        reporter: Rc<Reporter>,
        resume: Option<(u64, u64)>,
    ) -> Result<Self> {
        let service = transport::open_pubsub::<M>(node, edge, 0)?;
        let subscriber = service
            .subscriber_builder()
            .buffer_size(edge.depth)
            .create()
            .map_err(|e| anyhow::anyhow!("node '{name}': cannot subscribe to '{}': {e:?}", edge.topic))?;
        let seen = resume.map_or_else(Seen::default, |(_, replay)| Seen::before(replay));
        let received_before = resume.and_then(|(next, _)| next.checked_sub(1));
        Ok(Self {
            inner: Some(Rc::new(InputInner {
                topic: edge.topic.clone(),
                node: name.to_owned(),
                service,
                subscriber,
                slot,
                reporter,
                ended: Cell::new(false),
                seen: RefCell::new(seen),
                received_before,
                orphaned_since: Cell::new(None),
            })),
        })
    }

    pub(crate) fn declared() -> Self {
        Self { inner: None }
    }

    /// The topic.
    pub fn topic(&self) -> &str {
        self.inner.as_ref().map(|i| i.topic.as_str()).unwrap_or("")
    }

    /// Whether end-of-stream has arrived on this input.
    pub fn is_ended(&self) -> bool {
        self.inner.as_ref().is_none_or(|i| i.ended.get())
    }

    /// The next message, or `None` when nothing is waiting. End-of-stream is not returned: it sets
    /// [`is_ended`](Self::is_ended). Messages already seen (history replayed after a restart) are skipped and counted
    /// as duplicates; gaps in frame numbers are counted as missed frames.
    ///
    /// # Errors
    /// When the subscriber's connection to shared memory fails.
    pub fn receive(&self) -> Result<Option<Received<M>>> {
        let inner = self.inner.as_deref().ok_or_else(describe_only)?;
        loop {
            let Some(sample) = inner
                .subscriber
                .receive()
                .map_err(|e| anyhow::anyhow!("topic '{}': receive failed: {e:?}", inner.topic))?
            else {
                return Ok(None);
            };
            let stamp = *M::stamp(sample.user_header());
            if stamp.is_end_of_stream() {
                tracing::debug!("end-of-stream on '{}'", inner.topic);
                inner.ended.set(true);
                inner.reporter.input_ended();
                continue;
            }
            let last = inner.seen.borrow().last();
            if let Some(last) = last {
                if inner.seen.borrow().is_repeat(stamp.frame, stamp.revision) {
                    inner.reporter.duplicate();
                    continue;
                }
                let first_unseen = (last.0 + 1).max(inner.received_before.map_or(0, |f| f + 1));
                if !M::KIND.latched() && stamp.frame > first_unseen {
                    inner.reporter.missed(first_unseen, stamp.frame - 1);
                }
            } else if !M::KIND.latched() && stamp.frame > 0 && inner.reporter.restarted() {
                let first_unseen = inner.received_before.map_or(0, |f| f + 1);
                if stamp.frame > first_unseen {
                    inner.reporter.missed(first_unseen, stamp.frame - 1);
                }
            }
            inner.seen.borrow_mut().take(stamp.frame, stamp.revision);
            inner.reporter.received(inner.slot, stamp.frame);
            return Ok(Some(sample));
        }
    }
}

impl Input<lineflow_messages::kinds::Lines2D> {
    /// Drains the pending 2-D line sets, each split into its segments and their pixel chains.
    ///
    /// # Errors
    /// When receiving fails, a payload is shorter than its header says (the error names the frame), or `each` fails.
    pub fn for_each_segments(
        &self,
        mut each: impl FnMut(&lineflow_messages::Lines2DHeader, &[lineflow_messages::Segment2], &[[u16; 2]]) -> Result<()>,
    ) -> Result<()> {
        while let Some(m) = self.receive()? {
            let h = m.user_header();
            let (segments, chain) = h.split(m.payload()).map_err(anyhow::Error::msg)?;
            each(h, segments, chain)?;
        }
        Ok(())
    }
}

impl<M: Message> Connect for InputInner<M> {
    fn topic(&self) -> &str {
        &self.topic
    }
    fn discard(&self) -> usize {
        let _ = self.subscriber.update_connections();
        let mut n = 0;
        while let Ok(Some(_)) = self.subscriber.receive() {
            n += 1;
        }
        n
    }

    /// Connects publishers that appeared since, and ends an input whose publisher left without end-of-stream (its
    /// end-of-stream was dropped, or it exited abnormally and will not be restarted): otherwise the node, and
    /// everything downstream, would wait forever.
    fn refresh(&self) {
        // A restarted publisher is connected on every wake (at most RUN_TICK apart), whether or not the node's code
        // reads this input now: the publisher's samples wait in the connection instead of being dropped (pitfall P1).
        let _ = self.subscriber.update_connections();
        // Latched topics carry one message and never an end-of-stream: their publisher leaving is normal.
        if self.ended.get() || M::KIND.latched() {
            return;
        }
        let pending = self.subscriber.has_samples().unwrap_or(true);
        if self.service.dynamic_config().number_of_publishers() > 0 || pending {
            self.orphaned_since.set(None);
            return;
        }
        let since = self.orphaned_since.get().unwrap_or_else(std::time::Instant::now);
        self.orphaned_since.set(Some(since));
        if since.elapsed() >= ORPHAN_GRACE {
            tracing::warn!(
                "the publisher of '{}' left without end-of-stream {:?} ago; the input is taken as ended",
                self.topic,
                ORPHAN_GRACE
            );
            self.ended.set(true);
            self.reporter.input_ended();
        }
    }

    fn connect(&self, timeout: Duration, _restarted: bool) -> Result<()> {
        if !transport::wait_until(timeout, || self.service.dynamic_config().number_of_publishers() > 0) {
            bail!(
                "node '{}': no publisher appeared on '{}' within {:?}",
                self.node,
                self.topic,
                timeout
            );
        }
        self.subscriber
            .update_connections()
            .map_err(|e| anyhow::anyhow!("topic '{}': {e:?}", self.topic))
    }
}

/// A published topic.
pub struct Output<M: Message> {
    /// `None` in describe mode, where ports are only declared.
    pub(crate) inner: Option<Rc<OutputInner<M>>>,
}

fn describe_only() -> anyhow::Error {
    anyhow::anyhow!("port used in describe mode (NodeContext::connect exits before any message flows)")
}

pub(crate) struct OutputInner<M: Message> {
    topic: String,
    node: String,
    service: PubSub<M>,
    publisher: iceoryx2::port::publisher::Publisher<ipc::Service, [M::Element], M::Header>,
    notifier: iceoryx2::port::notifier::Notifier<ipc::Service>,
    expected: usize,
    seq: Cell<u64>,
    reporter: Rc<Reporter>,
    last_stamp: RefCell<Stamp>,
}

/// What a lossless publisher does while a subscriber's buffer stays full. A slow stage (a full-size map taking
/// minutes) is waited for as long as every node of the run is alive, with a warning each `timeout`: a lossless
/// edge loses nothing to a slow subscriber. A crashed subscriber never empties its buffer: once the run has a dead
/// node, the message is dropped (and counted) after `timeout` instead of hanging.
fn backpressure_handler(
    cfg: iceoryx2::config::Config,
    topic: String,
    timeout: Duration,
) -> impl Fn(&BackpressureInfo) -> BackpressureAction + Send + 'static {
    use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
    let last_check_s = AtomicU64::new(u64::MAX);
    let all_alive = AtomicBool::new(true);
    move |i: &BackpressureInfo| {
        if i.elapsed_time <= timeout {
            return BackpressureAction::Retry;
        }
        let s = i.elapsed_time.as_secs();
        // Listing the nodes reads the run's iceoryx2 root: once a second at most.
        if last_check_s.swap(s, Ordering::Relaxed) != s {
            let alive = transport::no_dead_node(&cfg);
            all_alive.store(alive, Ordering::Relaxed);
            let every = timeout.as_secs().max(1);
            if alive && s > 0 && s.is_multiple_of(every) {
                tracing::warn!("'{topic}': a subscriber has taken no message for {s} s; waiting, every node is alive");
            }
        }
        if all_alive.load(Ordering::Relaxed) {
            BackpressureAction::Retry
        } else {
            BackpressureAction::DiscardData
        }
    }
}

impl<M: Message> Output<M> {
    pub(crate) fn open(node: &Node<ipc::Service>, name: &str, edge: &EdgeSpec, reporter: Rc<Reporter>) -> Result<Self> {
        let service = transport::open_pubsub::<M>(node, edge, 0)?;
        let event = transport::open_event(node, &edge.topic)?;
        let element = size_of::<M::Element>().max(1);
        let timeout = Duration::from_millis(edge.timeout_ms);
        let publisher = service
            .publisher_builder()
            .initial_max_slice_len((edge.max_payload_bytes as usize).div_ceil(element).max(1))
            .allocation_strategy(AllocationStrategy::PowerOfTwo)
            .max_loaned_samples(2)
            .backpressure_strategy(BackpressureStrategy::RetryUntilDelivered)
            .set_backpressure_handler(backpressure_handler(node.config().clone(), edge.topic.clone(), timeout))
            .create()
            .map_err(|e| anyhow::anyhow!("node '{name}': cannot publish on '{}': {e:?}", edge.topic))?;
        let notifier = event
            .notifier_builder()
            .create()
            .map_err(|e| anyhow::anyhow!("topic '{}': cannot create notifier: {e:?}", edge.topic))?;
        Ok(Self {
            inner: Some(Rc::new(OutputInner {
                topic: edge.topic.clone(),
                node: name.to_owned(),
                service,
                publisher,
                notifier,
                expected: edge.to.len(),
                seq: Cell::new(0),
                reporter,
                last_stamp: RefCell::new(Stamp::default()),
            })),
        })
    }

    pub(crate) fn declared() -> Self {
        Self { inner: None }
    }

    /// The topic.
    pub fn topic(&self) -> &str {
        self.inner.as_ref().map(|i| i.topic.as_str()).unwrap_or("")
    }

    /// Publishes a message of `len` elements: `header` as given (its stamp's `seq` is set to this output's count),
    /// the payload filled in place by `fill`, zero-copy.
    ///
    /// # Errors
    /// When no sample can be loaned (the payload exceeds what shared memory can grow to) or sending fails.
    pub fn publish_with(&self, header: M::Header, len: usize, fill: impl FnOnce(&mut [M::Element])) -> Result<()> {
        self.send(header, len, fill, false)
    }

    /// Publishes a message another host's node published (the bridge between hosts), as it was sent there: its
    /// stamp's `seq` is kept, and this output counts on from it, so that sequence numbers hold end to end.
    ///
    /// # Errors
    /// As [`publish_with`](Self::publish_with).
    pub fn forward_with(&self, header: M::Header, len: usize, fill: impl FnOnce(&mut [M::Element])) -> Result<()> {
        self.send(header, len, fill, true)
    }

    fn send(&self, mut header: M::Header, len: usize, fill: impl FnOnce(&mut [M::Element]), keep_seq: bool) -> Result<()> {
        let inner = self.inner.as_deref().ok_or_else(describe_only)?;
        let mut sample = inner
            .publisher
            .loan_slice(len)
            .map_err(|e| anyhow::anyhow!("topic '{}': cannot loan {len} elements: {e:?}", inner.topic))?;
        if !keep_seq {
            M::stamp_mut(&mut header).seq = inner.seq.get();
        }
        *sample.user_header_mut() = header;
        fill(sample.payload_mut());
        let delivered = sample
            .send()
            .map_err(|e| anyhow::anyhow!("topic '{}': send failed: {e:?}", inner.topic))?;
        inner
            .notifier
            .notify()
            .map_err(|e| anyhow::anyhow!("topic '{}': notify failed: {e:?}", inner.topic))?;
        inner.seq.set(M::stamp(&header).seq + 1);
        *inner.last_stamp.borrow_mut() = *M::stamp(&header);
        inner.reporter.sent(inner.expected.saturating_sub(delivered) as u64);
        Ok(())
    }

    /// Publishes a copy of `payload`.
    ///
    /// # Errors
    /// As [`publish_with`](Self::publish_with).
    pub fn publish(&self, header: M::Header, payload: &[M::Element]) -> Result<()> {
        self.publish_with(header, payload.len(), |out| out.copy_from_slice(payload))
    }

    /// Publishes end-of-stream: an empty message whose stamp has the end-of-stream flag, after the last one sent.
    ///
    /// # Errors
    /// As [`publish_with`](Self::publish_with).
    pub fn end_of_stream(&self) -> Result<()> {
        let last = *self.inner.as_deref().ok_or_else(describe_only)?.last_stamp.borrow();
        let mut header = M::Header::default();
        *M::stamp_mut(&mut header) = Stamp {
            frame: last.frame + 1,
            capture_time_ns: last.capture_time_ns,
            seq: 0,
            flags: StampFlags::END_OF_STREAM,
            revision: 0,
        };
        self.publish_with(header, 0, |_| {})
    }
}

impl<M: Message<Element = u8>> Output<M> {
    /// Publishes a two-part byte payload (`a`, then `b` at the next 8-byte boundary; `lineflow_messages::parts`),
    /// written straight into the loaned sample.
    ///
    /// # Errors
    /// As [`publish_with`](Self::publish_with).
    pub fn publish_parts<A: ZeroCopySend + Copy, B: ZeroCopySend + Copy>(&self, header: M::Header, a: &[A], b: &[B]) -> Result<()> {
        let len = lineflow_messages::parts::two_part_len::<A, B>(a.len(), b.len());
        self.publish_with(header, len, |buf| lineflow_messages::parts::write(buf, a, b))
    }
}

impl<M: Message> Connect for OutputInner<M> {
    fn topic(&self) -> &str {
        &self.topic
    }
    fn drained(&self) -> bool {
        self.service.dynamic_config().number_of_subscribers() == 0
    }

    fn connect(&self, timeout: Duration, restarted: bool) -> Result<()> {
        // After a restart the subscribers are long connected; at the first start, wait for every one of them so
        // that nothing a source sends is lost before they listen.
        if !restarted && !transport::wait_until(timeout, || self.service.dynamic_config().number_of_subscribers() >= self.expected) {
            bail!(
                "node '{}': only {} of {} subscribers connected to '{}' within {:?}",
                self.node,
                self.service.dynamic_config().number_of_subscribers(),
                self.expected,
                self.topic,
                timeout
            );
        }
        if restarted {
            // Subscribers connect to a new publisher on their next wake-up (at most RUN_TICK apart); samples sent
            // before that would be dropped (iceoryx2 pitfall P1). Give them four ticks.
            let _ = self.publisher.update_connections();
            std::thread::sleep(RUN_TICK * 4);
        }
        self.publisher
            .update_connections()
            .with_context(|| format!("topic '{}'", self.topic))
            .map_err(|e| anyhow::anyhow!("{e:?}"))
    }
}

/// For a stage that publishes one state (every set holds everything so far) after draining several messages:
/// the stamps to publish that state under, in order: every frame seen for the first time (recorded in
/// `published`), so that subscribers see no frame missing, and the newest stamp if it is a revision of a frame
/// already out. Revisions in between (a burst of re-estimates) share the newest's message.
pub fn frames_to_publish(received: &[Stamp], published: &mut std::collections::HashSet<u64>) -> Vec<Stamp> {
    let mut out: Vec<Stamp> = received.iter().filter(|s| published.insert(s.frame)).copied().collect();
    if let Some(newest) = received.last() {
        if out.last() != Some(newest) {
            out.push(*newest);
        }
    }
    out
}

#[cfg(test)]
mod frames_to_publish_tests {
    use super::frames_to_publish;
    use lineflow_messages::Stamp;

    fn stamp(frame: u64, revision: u32) -> Stamp {
        Stamp {
            frame,
            revision,
            ..Stamp::default()
        }
    }

    #[test]
    fn new_frames_each_get_a_message_and_revisions_share_the_newest() {
        let mut published = std::collections::HashSet::new();
        let got = frames_to_publish(&[stamp(0, 0), stamp(1, 0), stamp(2, 0)], &mut published);
        assert_eq!(got.iter().map(|s| s.frame).collect::<Vec<_>>(), [0, 1, 2]);
        // The final re-estimation: every frame again with a higher revision, then a new one.
        let got = frames_to_publish(&[stamp(0, 1), stamp(1, 2), stamp(2, 3)], &mut published);
        assert_eq!(got, [stamp(2, 3)]);
        let got = frames_to_publish(&[stamp(1, 4), stamp(3, 5)], &mut published);
        assert_eq!(got, [stamp(3, 5)]);
        assert!(frames_to_publish(&[], &mut published).is_empty());
    }
}

#[cfg(test)]
mod backpressure_tests {
    use super::*;

    fn waited(elapsed: Duration) -> BackpressureInfo {
        BackpressureInfo {
            service_id: 0,
            sender_port_id: 0,
            receiver_port_id: 0,
            retries: 1000,
            elapsed_time: elapsed,
        }
    }

    #[test]
    fn a_slow_but_living_subscriber_is_waited_for_past_the_timeout() {
        let root = tempfile::tempdir().unwrap();
        let cfg = transport::config("lfbp_test_", root.path()).unwrap();
        let _publisher = transport::create_node(&cfg, "publisher").unwrap();
        let _subscriber = transport::create_node(&cfg, "subscriber").unwrap();
        assert!(transport::no_dead_node(&cfg));
        let handler = backpressure_handler(cfg, "images".into(), Duration::from_millis(100));
        for ms in [50, 100, 150, 5000, 60_000] {
            assert!(
                matches!(handler(&waited(Duration::from_millis(ms))), BackpressureAction::Retry),
                "gave up after {ms} ms on a living subscriber"
            );
        }
    }
}
