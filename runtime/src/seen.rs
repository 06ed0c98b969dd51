//! What a subscriber has taken of a topic, by frame and revision: what tells a message replayed after a restart
//! (history re-read by a restarted subscriber, or re-sent by a restarted bridge on another host) from a new one.
use std::collections::BTreeMap;

/// The frames (with their revisions) taken so far.
#[derive(Debug, Clone, Default)]
pub struct Seen {
    /// Largest (frame, revision) taken.
    last: Option<(u64, u32)>,
    /// Highest revision taken per frame: an earlier frame published again with a higher revision (a result improved
    /// later, e.g. after the end-of-stream adjustment) is new, not a repeat.
    revisions: BTreeMap<u64, u32>,
}

impl Seen {
    /// As if every revision of the frames before `frame` had been taken: a restarted instance resuming there.
    pub fn before(frame: u64) -> Self {
        Self {
            last: frame.checked_sub(1).map(|f| (f, u32::MAX)),
            revisions: BTreeMap::new(),
        }
    }

    /// The largest (frame, revision) taken.
    pub fn last(&self) -> Option<(u64, u32)> {
        self.last
    }

    /// Whether (`frame`, `revision`) was taken already (or precedes what was).
    pub fn is_repeat(&self, frame: u64, revision: u32) -> bool {
        let revised = self.revisions.get(&frame).is_some_and(|&r| revision > r);
        self.last.is_some_and(|last| (frame, revision) <= last) && !revised
    }

    /// Takes (`frame`, `revision`).
    pub fn take(&mut self, frame: u64, revision: u32) {
        let key = (frame, revision);
        self.last = Some(self.last.map_or(key, |l| l.max(key)));
        self.revisions.insert(frame, revision);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn repeats_are_told_from_new_frames_and_revisions() {
        let mut s = Seen::default();
        assert!(!s.is_repeat(0, 0));
        for f in 0..5 {
            s.take(f, 0);
        }
        assert!(s.is_repeat(3, 0) && s.is_repeat(4, 0));
        assert!(!s.is_repeat(5, 0));
        assert!(!s.is_repeat(2, 1), "a later revision of an earlier frame is new");
        s.take(2, 1);
        assert!(s.is_repeat(2, 1) && s.is_repeat(2, 0));
        assert_eq!(s.last(), Some((4, 0)));
    }

    #[test]
    fn resuming_skips_every_revision_of_the_frames_before() {
        let s = Seen::before(10);
        assert!(s.is_repeat(9, 7) && !s.is_repeat(10, 0));
        assert!(Seen::before(0).last().is_none());
    }
}
