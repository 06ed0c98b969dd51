//! `lineflow-bridge`: one host's end of the edges that cross between hosts (`docs/hosts.md`). The loader adds it to
//! each host's part of a graph on several machines. It subscribes to the topics published here and read on other
//! hosts and puts each message on Zenoh as its CDR encoding, with its type and version in the attachment; it
//! publishes the topics of other hosts read here, checking the type on arrival and keeping the sequence numbers.
//! Lossless edges use Zenoh's reliable, blocking congestion control under a window of the bridges' own
//! (`credit.rs`); `latest` edges may drop. The hosts find each other by liveliness tokens that carry the graph's
//! hash: a host of another graph is refused, and a host that leaves before its topics have ended ends the run with
//! an error naming it.
#![warn(missing_docs)]

mod bridge;
mod credit;
pub mod session;
mod wire;

use std::time::Duration;

use anyhow::{Context, Result};
use bridge::{Bridge, Incoming};
use lineflow_runtime::hosts::BridgePlan;
use lineflow_runtime::tap::{emitter, subscribe_all};
use lineflow_runtime::{Flow, NodeContext, RunEnd};

/// How often the bridge looks for messages from other hosts, which no iceoryx2 event announces.
const TICK: Duration = Duration::from_millis(1);
/// Initial payload of an edge whose size only its publisher on another host knows; the segment grows as needed.
const UNKNOWN_PAYLOAD_BYTES: u64 = 1 << 20;

/// The bridge's process body (implementation `zenoh`).
///
/// # Errors
/// A plan that does not fit the graph, a Zenoh session that cannot be opened, hosts that do not appear or are of
/// another graph, a message of another type, a host gone before its topics ended.
pub fn run(ctx: NodeContext) -> Result<()> {
    let plan: BridgePlan = ctx.params()?;
    let graph = ctx.graph().clone();
    let topics = subscribe_all(&ctx)?;
    let mut incoming = Vec::new();
    for c in &plan.receive {
        let edge = graph
            .output_edge(ctx.name(), &c.topic)
            .with_context(|| format!("the bridge's plan names topic '{}', which it does not publish", c.topic))?;
        let kind = edge.kind();
        let emit = emitter(&ctx, &c.topic, kind, true)?;
        if edge.max_payload_bytes == 0 {
            ctx.declare_max_payload(&c.topic, UNKNOWN_PAYLOAD_BYTES);
        }
        incoming.push(Incoming::new(c, kind, emit));
    }
    let mut status = ctx.watch_status()?;
    if lineflow_runtime::env::RunEnv::describe_requested() {
        return ctx.connect();
    }
    let mut bridge = Bridge::open(plan, &graph, topics, incoming, ctx.out_dir())?;
    bridge.wait_for_peers(&ctx, connect_timeout(&graph))?;
    if ctx.restarts() > 0 {
        bridge.ask_for_resend()?;
    }
    ctx.connect()?;
    tracing::info!("{}", bridge.describe());
    let ended = ctx.run_every(TICK, || {
        bridge.receive()?;
        bridge.send(status.as_mut())?;
        bridge.check_peers()?;
        Ok(if bridge.done() { Flow::Stop } else { Flow::Continue })
    });
    match ended {
        // At once: the supervisor stops this host's part, and the other hosts see this one leave.
        Err(e) => {
            bridge.close(false);
            Err(e)
        }
        Ok(end) => {
            let finished = end == RunEnd::Finished;
            if !finished {
                // The other hosts end their parts too, with the reason, instead of taking this one for vanished.
                bridge.say_stopped();
            }
            ctx.finish();
            if let (true, Some(status)) = (finished, status.as_mut()) {
                bridge.send_report(status);
            }
            bridge.close(finished);
            Ok(())
        }
    }
}

/// How long the other hosts get to appear: half the launch file's `connect_timeout_s` (the supervisor's own deadline
/// for every node to connect), so that the bridge names the hosts missing before the supervisor gives up on it with
/// "not connected"; without it, the nodes' connect timeout (30 s).
fn connect_timeout(graph: &lineflow_runtime::launch::Graph) -> Duration {
    if let Some(half) = graph.connect_timeout_s.and_then(|s| Duration::try_from_secs_f64(s / 2.0).ok()) {
        return half;
    }
    let s = std::env::var(lineflow_runtime::env::CONNECT_TIMEOUT_S)
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(30);
    Duration::from_secs(s)
}
