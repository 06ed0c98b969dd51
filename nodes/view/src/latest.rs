//! The last message of every channel, for a client that subscribes after it was sent: the model, the 3-D lines
//! and the cameras change only now and then, and a viewer opened mid-run (or after the graph ended) must show them
//! at once, not at the next update.
use std::collections::BTreeMap;
use std::sync::Mutex;

/// One channel's last message.
#[derive(Debug, Clone, PartialEq)]
pub struct Last {
    /// The message's bytes.
    pub bytes: Vec<u8>,
    /// Its log time, ns.
    pub log_time: u64,
}

/// The last message per channel, shared between the publishing thread and the server's subscribe callback.
#[derive(Debug, Default)]
pub struct Latest<K: Ord> {
    last: Mutex<BTreeMap<K, Last>>,
}

impl<K: Ord + Clone> Latest<K> {
    /// Keeps `bytes` as `key`'s last message, in place of the one before.
    pub fn keep(&self, key: &K, bytes: &[u8], log_time: u64) {
        let mut last = self.last.lock().unwrap_or_else(std::sync::PoisonError::into_inner);
        match last.get_mut(key) {
            // The buffer is reused: previews arrive every frame at the same size.
            Some(l) => {
                l.bytes.clear();
                l.bytes.extend_from_slice(bytes);
                l.log_time = log_time;
            }
            None => {
                last.insert(
                    key.clone(),
                    Last {
                        bytes: bytes.to_vec(),
                        log_time,
                    },
                );
            }
        }
    }

    /// `key`'s last message, if one was sent.
    pub fn get(&self, key: &K) -> Option<Last> {
        self.last
            .lock()
            .unwrap_or_else(std::sync::PoisonError::into_inner)
            .get(key)
            .cloned()
    }

    /// How many channels have a message.
    pub fn len(&self) -> usize {
        self.last.lock().unwrap_or_else(std::sync::PoisonError::into_inner).len()
    }

    /// Whether no channel has a message yet.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn each_channel_keeps_only_its_last_message() {
        let sut = Latest::<u64>::default();
        assert!(sut.get(&1).is_none() && sut.is_empty());
        sut.keep(&1, b"first model", 10);
        sut.keep(&2, b"lines", 11);
        sut.keep(&1, b"second", 12);
        assert_eq!(
            sut.get(&1),
            Some(Last {
                bytes: b"second".to_vec(),
                log_time: 12
            })
        );
        assert_eq!(sut.get(&2).unwrap().bytes, b"lines");
        assert_eq!(sut.len(), 2);
    }
}
