//! iceoryx2 services of a run, built from the graph so that every process opens them with the same settings.
use std::time::Duration;

use anyhow::{Context, Result};
use iceoryx2::config::Config;
use iceoryx2::prelude::*;
use lineflow_messages::{Message, NodeStatus};

use crate::launch::{EdgePolicy, EdgeSpec};

/// A typed publish-subscribe service.
pub type PubSub<M> =
    iceoryx2::service::port_factory::publish_subscribe::PortFactory<ipc::Service, [<M as Message>::Element], <M as Message>::Header>;
/// An event service.
pub type Event = iceoryx2::service::port_factory::event::PortFactory<ipc::Service>;

/// Service carrying every node's [`NodeStatus`].
pub const STATUS_SERVICE: &str = "lineflow/status";
/// Event service on which nodes announce they are connected (event id = node index).
pub const READY_SERVICE: &str = "lineflow/ready";
/// Event service on which the supervisor tells sources to start.
pub const START_SERVICE: &str = "lineflow/start";
/// Most nodes a graph may have (event ids and status publishers are sized for it).
pub const MAX_NODES: usize = 64;

/// The iceoryx2 configuration of a run: its own prefix and root, so runs never see each other's resources.
///
/// # Errors
/// When the prefix or root is not a valid iceoryx2 file name or path.
pub fn config(prefix: &str, root: &std::path::Path) -> Result<Config> {
    let mut cfg = Config::default();
    cfg.global.prefix =
        iceoryx2::prelude::FileName::new(prefix.as_bytes()).with_context(|| format!("invalid iceoryx2 prefix '{prefix}'"))?;
    let mut root = root.display().to_string();
    if !root.ends_with('/') {
        root.push('/');
    }
    cfg.global
        .set_root_path(&iceoryx2::prelude::Path::new(root.as_bytes()).with_context(|| format!("invalid iceoryx2 root '{root}'"))?);
    Ok(cfg)
}

/// Whether no node of the run (`cfg`) has died: a process that crashed or was killed leaves its node dead until the
/// supervisor cleans it up.
pub fn no_dead_node(cfg: &Config) -> bool {
    let mut alive = true;
    let listed = Node::<ipc::Service>::list(cfg, |state| {
        if matches!(state, NodeState::Dead(_)) {
            alive = false;
            CallbackProgression::Stop
        } else {
            CallbackProgression::Continue
        }
    });
    alive && listed.is_ok()
}

/// Creates this process's iceoryx2 node in the run.
///
/// # Errors
/// When iceoryx2 cannot create the node.
pub fn create_node(cfg: &Config, name: &str) -> Result<Node<ipc::Service>> {
    NodeBuilder::new()
        .name(&name.try_into().with_context(|| format!("invalid node name '{name}'"))?)
        .config(cfg)
        .create::<ipc::Service>()
        .with_context(|| format!("node '{name}': cannot create iceoryx2 node"))
}

fn service_name(topic: &str) -> Result<ServiceName> {
    topic
        .try_into()
        .with_context(|| format!("topic '{topic}' is not a valid iceoryx2 service name"))
}

/// Opens (or creates) the publish-subscribe service of an edge.
///
/// # Errors
/// When the service exists with another type or incompatible settings (a different message type on the same topic).
pub fn open_pubsub<M: Message>(node: &Node<ipc::Service>, edge: &EdgeSpec, extra_subscribers: usize) -> Result<PubSub<M>> {
    node.service_builder(&service_name(&edge.topic)?)
        .publish_subscribe::<[M::Element]>()
        .user_header::<M::Header>()
        .enable_safe_overflow(edge.policy == EdgePolicy::Latest)
        .subscriber_max_buffer_size(edge.depth)
        .subscriber_max_borrowed_samples(2)
        .history_size(edge.history)
        .max_publishers(2)
        .max_subscribers(edge.to.len() + 1 + extra_subscribers)
        .max_nodes(edge.to.len() + 4 + extra_subscribers)
        .open_or_create()
        .map_err(|e| anyhow::anyhow!("topic '{}': cannot open service for {}: {e:?}", edge.topic, M::KIND.name()))
}

/// Opens (or creates) the event service that wakes an edge's subscribers.
///
/// # Errors
/// When iceoryx2 refuses the service.
pub fn open_event(node: &Node<ipc::Service>, topic: &str) -> Result<Event> {
    node.service_builder(&service_name(topic)?)
        .event()
        .max_notifiers(MAX_NODES)
        .max_listeners(MAX_NODES)
        .max_nodes(MAX_NODES * 2)
        .event_id_max_value(MAX_NODES * 2)
        .open_or_create()
        .map_err(|e| anyhow::anyhow!("topic '{topic}': cannot open event service: {e:?}"))
}

/// Opens (or creates) the run's status service.
///
/// # Errors
/// When iceoryx2 refuses the service.
pub fn open_status(
    node: &Node<ipc::Service>,
) -> Result<iceoryx2::service::port_factory::publish_subscribe::PortFactory<ipc::Service, NodeStatus, ()>> {
    node.service_builder(&service_name(STATUS_SERVICE)?)
        .publish_subscribe::<NodeStatus>()
        .enable_safe_overflow(true)
        .subscriber_max_buffer_size(256)
        .history_size(0)
        .max_publishers(MAX_NODES * 2)
        .max_subscribers(4)
        .max_nodes(MAX_NODES * 2 + 4)
        .open_or_create()
        .map_err(|e| anyhow::anyhow!("cannot open the run's status service: {e:?}"))
}

/// Polls `ready` every 2 ms until it holds or `timeout` passes.
pub fn wait_until(timeout: Duration, mut ready: impl FnMut() -> bool) -> bool {
    let start = std::time::Instant::now();
    loop {
        if ready() {
            return true;
        }
        if start.elapsed() > timeout {
            return false;
        }
        std::thread::sleep(Duration::from_millis(2));
    }
}
