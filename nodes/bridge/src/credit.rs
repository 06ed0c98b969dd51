//! Flow control between hosts. A lossless edge must hold its publisher back while a subscriber on another host is
//! busy, for as long as it is busy (a full-size map takes minutes). Zenoh's own blocking congestion control
//! closes the session once a put has waited 5 s, so the bridges keep a window of their own: the sending host puts
//! at most `size` messages of a topic that a receiving host has not yet published into its graph, and leaves the
//! rest in its iceoryx2 subscriber, where the back-pressure reaches the publisher as on one host. The receiving
//! host returns credit as it publishes, so nothing waits inside Zenoh and no receiving queue grows without bound.
use std::collections::BTreeMap;

/// The credit of one topic at each host that receives it.
#[derive(Debug, Clone)]
pub struct Window {
    left: BTreeMap<String, u64>,
    size: u64,
}

impl Window {
    /// A full window of `size` messages for each of `hosts`.
    pub fn new<'a>(hosts: impl IntoIterator<Item = &'a String>, size: u64) -> Self {
        Self {
            left: hosts.into_iter().map(|h| (h.clone(), size)).collect(),
            size,
        }
    }
    /// How many messages may be put now: the least credit of any receiving host.
    pub fn room(&self) -> u64 {
        self.left.values().copied().min().unwrap_or(0)
    }
    /// One message was put to every receiving host.
    pub fn sent(&mut self) {
        for c in self.left.values_mut() {
            *c = c.saturating_sub(1);
        }
    }
    /// `host` owes nothing: a restarted bridge there starts afresh.
    pub fn reset(&mut self, host: &str) {
        if let Some(c) = self.left.get_mut(host) {
            *c = self.size;
        }
    }
    /// `host` published `n` more messages; a reply from a host this topic does not go to is ignored. Credit never
    /// exceeds the window (a duplicated reply cannot open it wider).
    pub fn grant(&mut self, host: &str, n: u64) {
        if let Some(c) = self.left.get_mut(host) {
            *c = (*c + n).min(self.size);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_slowest_receiver_sets_the_room_and_credit_never_exceeds_the_window() {
        let hosts = ["a".to_owned(), "b".to_owned()];
        let mut w = Window::new(&hosts, 3);
        assert_eq!(w.room(), 3);
        for _ in 0..3 {
            w.sent();
        }
        assert_eq!(w.room(), 0, "both hosts owe three");
        w.grant("a", 3);
        assert_eq!(w.room(), 0, "b has published none yet");
        w.grant("b", 1);
        assert_eq!(w.room(), 1);
        w.grant("b", 10);
        w.grant("nobody", 5);
        assert_eq!(w.room(), 3, "capped at the window");
        w.sent();
        w.reset("a");
        assert_eq!(w.room(), 2, "b still owes one");
    }
}
