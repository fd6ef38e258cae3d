//! A small store of computed values by key, bounded by a count of entries
//! and shared between threads: the solves of working copies that one
//! photograph's pipeline would otherwise repeat (see
//! [`SolveMemo`](super::problem::SolveMemo)). A leaf: it knows nothing of
//! what it stores.

use std::collections::VecDeque;
use std::sync::Mutex;

/// At most `capacity` values, each under a key compared by equality (keys
/// of floats that cannot be hashed); the oldest goes first when full.
pub(crate) struct Memo<K, V> {
    capacity: usize,
    entries: Mutex<VecDeque<(K, V)>>,
}

impl<K: PartialEq, V: Clone> Memo<K, V> {
    /// An empty store of at most `capacity` entries.
    pub(crate) fn new(capacity: usize) -> Self {
        Memo {
            capacity,
            entries: Mutex::new(VecDeque::new()),
        }
    }

    /// A copy of the value kept under `key`.
    pub(crate) fn get(&self, key: &K) -> Option<V> {
        // A thread that panicked while holding the lock left whole entries
        // (pushes and pops do not panic halfway): still readable.
        let entries = self.entries.lock().unwrap_or_else(|e| e.into_inner());
        entries
            .iter()
            .find(|(k, _)| k == key)
            .map(|(_, v)| v.clone())
    }

    /// Keeps `value` under `key` (replacing an equal key's), dropping the
    /// oldest entry when full.
    pub(crate) fn insert(&self, key: K, value: V) {
        if self.capacity == 0 {
            return;
        }
        let mut entries = self.entries.lock().unwrap_or_else(|e| e.into_inner());
        entries.retain(|(k, _)| *k != key);
        while entries.len() >= self.capacity {
            entries.pop_front();
        }
        entries.push_back((key, value));
    }

    /// How many entries are kept.
    #[cfg(test)]
    pub(crate) fn len(&self) -> usize {
        self.entries.lock().unwrap_or_else(|e| e.into_inner()).len()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn keeps_the_newest_entries_and_finds_them_by_equality() {
        let memo = Memo::new(2);
        memo.insert(1.5, "a");
        memo.insert(2.5, "b");
        assert_eq!(memo.get(&1.5), Some("a"));
        memo.insert(3.5, "c");
        assert_eq!(memo.get(&1.5), None, "the oldest went first");
        assert_eq!(memo.get(&2.5), Some("b"));
        assert_eq!(memo.get(&3.5), Some("c"));
        memo.insert(3.5, "d");
        assert_eq!((memo.get(&3.5), memo.len()), (Some("d"), 2));
        // NaN equals nothing: never found, never a wrong value.
        memo.insert(f64::NAN, "n");
        assert_eq!(memo.get(&f64::NAN), None);
    }

    #[test]
    fn a_store_of_no_entries_keeps_nothing() {
        let memo = Memo::new(0);
        memo.insert(1, 1);
        assert_eq!((memo.get(&1), memo.len()), (None, 0));
    }
}
