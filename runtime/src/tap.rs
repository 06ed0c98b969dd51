//! Every topic of a graph as one list, whatever its message type: what the nodes that watch a whole run (the
//! recorder, the live viewer, the bridge to other hosts) subscribe to, and what the nodes that stand in for others
//! (the player, the bridge from other hosts) publish on.
use anyhow::{bail, Result};
use lineflow_messages::schema::read_pod;
use lineflow_messages::{with_kind, Message, MessageKind, NodeStatus};

use crate::ports::{Input, Output};
use crate::{NodeContext, StatusWatch};

/// A received message as its parts: capture time (ns), header bytes, payload bytes. The slices borrow the
/// shared-memory sample, which is released when the visitor returns.
pub type Visit<'a> = dyn FnMut(u64, &[u8], &[u8]) -> Result<()> + 'a;

/// A subscribed topic of any message type.
pub trait Tap {
    /// Calls `each` with every waiting message, in order; returns how many.
    ///
    /// # Errors
    /// A transport error, or the first error of `each`.
    fn drain(&self, each: &mut Visit) -> Result<usize> {
        self.drain_some(usize::MAX, each)
    }
    /// [`drain`](Self::drain), taking at most `max` messages: the rest wait, and hold their publisher back.
    ///
    /// # Errors
    /// As [`drain`](Self::drain).
    fn drain_some(&self, max: usize, each: &mut Visit) -> Result<usize>;
    /// Whether the publisher sent end-of-stream.
    fn is_ended(&self) -> bool;
}

struct TypedTap<M: Message>(Input<M>);

impl<M: Message> Tap for TypedTap<M> {
    fn drain_some(&self, max: usize, each: &mut Visit) -> Result<usize> {
        let mut n = 0;
        while n < max {
            let Some(msg) = self.0.receive()? else { break };
            let header = lineflow_messages::schema::bytes_of(msg.user_header());
            each(
                M::stamp(msg.user_header()).capture_time_ns,
                header,
                lineflow_messages::schema::slice_bytes(msg.payload()),
            )?;
            n += 1;
        }
        Ok(n)
    }
    fn is_ended(&self) -> bool {
        self.0.is_ended()
    }
}

/// One topic the node subscribes to.
pub struct Topic {
    /// Topic name.
    pub name: String,
    /// Its message type.
    pub kind: MessageKind,
    /// The subscription.
    pub tap: Box<dyn Tap>,
    /// Messages received so far.
    pub messages: u64,
    /// Index of the publishing node.
    pub from: u32,
    /// Whether the topic has ended (see [`update_ended`]).
    pub ended: bool,
}

/// Subscribes to every edge the graph wires to this node.
///
/// # Errors
/// A subscription that cannot be made.
pub fn subscribe_all(ctx: &NodeContext) -> Result<Vec<Topic>> {
    let graph = ctx.graph();
    let mut topics = Vec::new();
    for e in graph.edges.iter().filter(|e| e.to.iter().any(|t| t == ctx.name())) {
        let kind = e.kind();
        let tap: Box<dyn Tap> = with_kind!(kind, M => Box::new(TypedTap(ctx.input::<M>(&e.topic)?)));
        topics.push(Topic {
            name: e.topic.clone(),
            kind,
            tap,
            messages: 0,
            from: graph.node(&e.from).map_or(u32::MAX, |n| n.index),
            ended: false,
        });
    }
    Ok(topics)
}

/// Marks the topics that have ended. Latched topics (camera, control, site) carry no end-of-stream, so that a late
/// subscriber still gets the message: they end when their publisher has finished.
pub fn update_ended(topics: &mut [Topic], status: Option<&mut StatusWatch>) {
    let latest = status.map(|s| s.poll());
    for t in topics {
        let publisher_finished = latest
            .and_then(|l| l.get(&t.from))
            .is_some_and(|s| s.flags & NodeStatus::FINISHED != 0);
        t.ended = t.tap.is_ended() || (t.kind.latched() && publisher_finished);
    }
}

/// Whether every topic has ended.
pub fn all_ended(topics: &[Topic]) -> bool {
    topics.iter().all(|t| t.ended || t.tap.is_ended())
}

/// A published topic of any message type.
pub trait Emit {
    /// Publishes a message from its header and payload bytes (as `schema::decode_view` gives them).
    ///
    /// # Errors
    /// A header or payload that is not of this topic's type, or a transport error.
    fn emit(&self, header: &[u8], payload: &[u8]) -> Result<()>;
    /// Publishes end-of-stream.
    ///
    /// # Errors
    /// A transport error.
    fn end(&self) -> Result<()>;
}

struct TypedEmit<M: Message> {
    output: Output<M>,
    /// Keep the stamps' sequence numbers (messages of another host) instead of numbering them here.
    forward: bool,
}

impl<M: Message> Emit for TypedEmit<M> {
    fn emit(&self, header: &[u8], payload: &[u8]) -> Result<()> {
        if header.len() != size_of::<M::Header>() {
            bail!("{}: decoded header of {} bytes", M::KIND.name(), header.len());
        }
        let header: M::Header = read_pod(header);
        let size = size_of::<M::Element>().max(1);
        if !payload.len().is_multiple_of(size) {
            bail!("{}: payload of {} bytes is not whole elements", M::KIND.name(), payload.len());
        }
        let fill = |out: &mut [M::Element]| {
            // SAFETY: `out` holds exactly payload.len() bytes of plain-old-data elements.
            let bytes = unsafe { std::slice::from_raw_parts_mut(out.as_mut_ptr().cast::<u8>(), payload.len()) };
            bytes.copy_from_slice(payload);
        };
        if self.forward {
            self.output.forward_with(header, payload.len() / size, fill)
        } else {
            self.output.publish_with(header, payload.len() / size, fill)
        }
    }
    fn end(&self) -> Result<()> {
        self.output.end_of_stream()
    }
}

/// An output of any message type on `topic`. With `forward`, the messages keep the sequence numbers their stamps
/// carry (a bridge passing on another host's messages); without, this node numbers them (the player).
///
/// # Errors
/// When the node cannot publish on the topic.
pub fn emitter(ctx: &NodeContext, topic: &str, kind: MessageKind, forward: bool) -> Result<Box<dyn Emit>> {
    Ok(with_kind!(kind, M => Box::new(TypedEmit { output: ctx.output::<M>(topic)?, forward })))
}
