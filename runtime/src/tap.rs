//! Every topic of a graph as one list, whatever its message type: what the nodes that watch a whole run (the
//! recorder, the live viewer) subscribe to.
use anyhow::Result;
use lineflow_messages::{with_kind, Message, MessageKind, NodeStatus};

use crate::ports::Input;
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
    fn drain(&self, each: &mut Visit) -> Result<usize>;
    /// Whether the publisher sent end-of-stream.
    fn is_ended(&self) -> bool;
}

struct TypedTap<M: Message>(Input<M>);

impl<M: Message> Tap for TypedTap<M> {
    fn drain(&self, each: &mut Visit) -> Result<usize> {
        let mut n = 0;
        while let Some(msg) = self.0.receive()? {
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
