//! What the integration tests of magstand-logs share.
use std::path::PathBuf;

/// The path of a public log in the repository's tests/data/real-logs (provenance in its
/// README).
pub fn real_log(name: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("../../tests/data/real-logs")
        .join(name)
}
