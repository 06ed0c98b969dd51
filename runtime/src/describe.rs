//! The ports a node declares: printed by `--describe` (or `LINEFLOW_DESCRIBE=1`) so the supervisor can type-check
//! the graph before starting anything.
use serde::{Deserialize, Serialize};

/// One declared port.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct Port {
    /// Port name (the topic, unless the launch file remaps it).
    pub port: String,
    /// Message type name.
    pub message: String,
    /// Whether the node refuses to run when the port is not wired.
    pub required: bool,
    /// Largest payload the node will publish on this output, in bytes, when it knows (e.g. the synthetic camera
    /// from its preset); sizes an edge whose launch entry gives no `max_payload_bytes`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub max_payload_bytes: Option<u64>,
}

/// Every port of a node.
#[derive(Debug, Clone, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct Ports {
    /// Subscribed ports.
    pub inputs: Vec<Port>,
    /// Published ports.
    pub outputs: Vec<Port>,
}
