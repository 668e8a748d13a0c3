//! Job identifiers: short, unguessable, URL-safe strings.
//!
//! An id is 16 lowercase hex digits drawn from the standard library's randomly keyed hasher mixed
//! with a process-wide counter, so ids never repeat within a process and are not predictable from
//! one another. Parsing checks the shape, so a malformed id is refused before any store lookup.

use std::collections::hash_map::RandomState;
use std::fmt;
use std::hash::{BuildHasher, Hasher};
use std::sync::LazyLock;
use std::sync::atomic::{AtomicU64, Ordering};

/// The id of one job.
#[derive(Clone, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct JobId(String);

const LENGTH: usize = 16;

impl JobId {
    /// A fresh id, distinct from every other id made by this process.
    pub fn new() -> Self {
        static KEYS: LazyLock<RandomState> = LazyLock::new(RandomState::new);
        static COUNTER: AtomicU64 = AtomicU64::new(0);
        let mut hasher = KEYS.build_hasher();
        hasher.write_u64(COUNTER.fetch_add(1, Ordering::Relaxed));
        Self(format!("{:016x}", hasher.finish()))
    }

    /// Reads an id as it appears in a URL; `None` if it cannot be one.
    pub fn parse(text: &str) -> Option<Self> {
        let valid =
            text.len() == LENGTH && text.bytes().all(|b| b.is_ascii_digit() || (b'a'..=b'f').contains(&b));
        valid.then(|| Self(text.to_string()))
    }

    /// The id as text.
    pub fn as_str(&self) -> &str {
        &self.0
    }
}

impl Default for JobId {
    fn default() -> Self {
        Self::new()
    }
}

impl fmt::Display for JobId {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(&self.0)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fresh_ids_differ_and_parse_back() {
        let (a, b) = (JobId::new(), JobId::new());
        assert_ne!(a, b);
        assert_eq!(JobId::parse(a.as_str()), Some(a));
    }

    #[test]
    fn malformed_ids_are_refused() {
        for text in
            ["", "abc", "0123456789abcdeg", "0123456789ABCDEF", "0123456789abcdef0", "../etc/passwd0000"]
        {
            assert_eq!(JobId::parse(text), None, "{text:?}");
        }
    }
}
