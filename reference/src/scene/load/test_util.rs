//! Helpers shared by the loaders' unit tests (compiled for tests only).

use crate::scene::builtin::Species;

/// Asserts that the error text `e` mentions every one of `needles`.
pub(super) fn assert_mentions(e: &str, needles: &[&str]) {
    assert!(needles.iter().all(|n| e.contains(n)), "{e}");
}

pub(super) fn names() -> Vec<String> {
    Species::ALL.iter().map(|s| s.name().to_string()).collect()
}
