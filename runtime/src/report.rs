//! A node's counters and their publication on the run's status service.
use std::cell::{Cell, RefCell};
use std::time::{Duration, Instant};

use iceoryx2::prelude::*;
use lineflow_messages::NodeStatus;

/// Publishes at most this often, except for the first message and at exit.
const PERIOD: Duration = Duration::from_millis(100);

/// Counts what a node receives and sends and reports it to the supervisor.
pub struct Reporter {
    status: RefCell<NodeStatus>,
    publisher: Option<iceoryx2::port::publisher::Publisher<ipc::Service, NodeStatus, ()>>,
    last_publish: Cell<Option<Instant>>,
    restarted: bool,
    /// Frames received but not yet known to be handled, per input slot.
    in_progress: RefCell<Vec<Option<u64>>>,
}

impl Reporter {
    pub(crate) fn new(
        node_index: u32,
        publisher: Option<iceoryx2::port::publisher::Publisher<ipc::Service, NodeStatus, ()>>,
        restarted: bool,
    ) -> Self {
        let status = NodeStatus {
            node_index,
            pid: std::process::id(),
            ..Default::default()
        };
        Self {
            status: RefCell::new(status),
            publisher,
            last_publish: Cell::new(None),
            restarted,
            in_progress: RefCell::default(),
        }
    }

    pub(crate) fn restarted(&self) -> bool {
        self.restarted
    }

    pub(crate) fn set_inputs(&self, n: usize) {
        self.status.borrow_mut().n_inputs = n.min(NodeStatus::MAX_INPUTS) as u32;
    }

    pub(crate) fn resume(&self, slot: usize, next_frame: u64) {
        if let Some(v) = self.status.borrow_mut().last_frame_plus1.get_mut(slot) {
            *v = next_frame;
        }
    }

    /// A message arrived; the frame counts as consumed once [`commit`](Self::commit) says the node is done with it,
    /// so a restart after a crash mid-frame processes that frame again instead of losing it.
    pub(crate) fn received(&self, slot: usize, frame: u64) {
        self.commit();
        self.status.borrow_mut().msgs_in += 1;
        let mut p = self.in_progress.borrow_mut();
        if p.len() <= slot {
            p.resize(slot + 1, None);
        }
        p[slot] = Some(frame);
    }

    /// Marks every received frame as handled and reports it. Called before the next receive and after each wake-up.
    pub(crate) fn commit(&self) {
        let mut changed = false;
        for (slot, f) in self.in_progress.borrow_mut().iter_mut().enumerate() {
            if let Some(frame) = f.take() {
                if let Some(v) = self.status.borrow_mut().last_frame_plus1.get_mut(slot) {
                    *v = (*v).max(frame + 1);
                }
                changed = true;
            }
        }
        if changed {
            self.flush(true);
        }
    }

    pub(crate) fn duplicate(&self) {
        self.status.borrow_mut().duplicates += 1;
    }

    pub(crate) fn missed(&self, first: u64, last: u64) {
        let mut s = self.status.borrow_mut();
        s.missed += last - first + 1;
        let n = s.n_missed_ranges as usize;
        if n < NodeStatus::MAX_RANGES {
            s.missed_ranges[n] = [first, last];
            s.n_missed_ranges += 1;
        }
        tracing::warn!(first, last, "missed frames {first}..={last}");
    }

    pub(crate) fn sent(&self, drops: u64) {
        {
            let mut s = self.status.borrow_mut();
            s.msgs_out += 1;
            s.drops += drops;
        }
        if drops > 0 {
            tracing::warn!(drops, "a message did not reach {drops} subscriber(s)");
        }
        self.flush(false);
    }

    pub(crate) fn input_ended(&self) {}

    pub(crate) fn finished(&self) {
        self.commit();
        self.status.borrow_mut().flags |= NodeStatus::FINISHED;
        self.flush(true);
    }

    /// Publishes the counters if `force`, if nothing was published yet, or if the period has passed.
    pub(crate) fn flush(&self, force: bool) {
        let due = match self.last_publish.get() {
            None => true,
            Some(t) => force || t.elapsed() >= PERIOD,
        };
        if !due {
            return;
        }
        if let Some(p) = &self.publisher {
            if let Err(e) = p.send_copy(*self.status.borrow()) {
                tracing::debug!("status not sent: {e:?}");
            }
        }
        self.last_publish.set(Some(Instant::now()));
    }

    /// The counters so far.
    pub fn snapshot(&self) -> NodeStatus {
        *self.status.borrow()
    }
}
