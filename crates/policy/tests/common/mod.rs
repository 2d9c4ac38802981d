//! What the policy crate's integration tests share.
#![allow(clippy::panic, reason = "tests fail by panicking")]
use std::path::PathBuf;

/// The fixture made by `python -m umpnet_train.fixture DIR` (make test sets
/// UMPNET_FIXTURE), or None: the test is skipped, with the reason printed. In
/// CI (CI=true) a missing fixture fails: a silent pass would hide a broken
/// contract.
pub fn fixture() -> Option<PathBuf> {
    let Some(dir) = std::env::var_os("UMPNET_FIXTURE") else {
        assert!(
            std::env::var("CI").as_deref() != Ok("true"),
            "UMPNET_FIXTURE not set under CI=true (make test sets it)"
        );
        eprintln!("skipped: UMPNET_FIXTURE not set (make test sets it)");
        return None;
    };
    let dir = PathBuf::from(dir);
    assert!(
        dir.join("model.json").is_file(),
        "UMPNET_FIXTURE={} has no model.json",
        dir.display()
    );
    Some(dir)
}
