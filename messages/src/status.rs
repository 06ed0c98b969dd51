//! `NodeStatus`: what each node reports to the supervisor on the run's status service.
use iceoryx2::prelude::ZeroCopySend;

/// Counters of one node instance, published on every change (at most every 100 ms) and at exit.
#[derive(Debug, Default, Clone, Copy, PartialEq, Eq, ZeroCopySend)]
#[repr(C)]
#[type_name("lineflow/NodeStatus/v1")]
pub struct NodeStatus {
    /// Index of the node in the launch graph.
    pub node_index: u32,
    /// Process id.
    pub pid: u32,
    /// Messages received (duplicates excluded).
    pub msgs_in: u64,
    /// Messages published.
    pub msgs_out: u64,
    /// Deliveries that did not reach an expected subscriber.
    pub drops: u64,
    /// Received messages discarded as already seen (history replayed after a restart).
    pub duplicates: u64,
    /// Frames missed on the inputs (gaps in frame numbers).
    pub missed: u64,
    /// The first missed frame ranges, `[first, last]`, inclusive.
    pub missed_ranges: [[u64; 2]; NodeStatus::MAX_RANGES],
    /// Number of valid `missed_ranges`.
    pub n_missed_ranges: u32,
    /// Number of valid `last_frame`.
    pub n_inputs: u32,
    /// Last frame seen on each input, in subscription order, plus 1 (0 = nothing yet).
    pub last_frame_plus1: [u64; NodeStatus::MAX_INPUTS],
    /// Bit 0: end-of-stream seen on every input; bit 1: finished.
    pub flags: u32,
    /// Padding, zero.
    pub reserved: u32,
}

impl NodeStatus {
    /// Missed ranges kept per status.
    pub const MAX_RANGES: usize = 8;
    /// Inputs tracked per node.
    pub const MAX_INPUTS: usize = 8;
    /// Flag: the node has finished its work.
    pub const FINISHED: u32 = 2;
}
