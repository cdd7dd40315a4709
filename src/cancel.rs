//! Cancellation of long work: a shared flag that the owner raises (opening another scene
//! raises the running job's) and that every long phase checks between pieces of work.

use std::sync::atomic::{AtomicBool, Ordering};

/// The work was stopped because its cancel flag was raised; nothing it produced is valid.
#[derive(Clone, Copy, Debug, PartialEq, Eq, thiserror::Error)]
#[error("cancelled")]
pub struct Cancelled;

/// `Err(Cancelled)` once `flag` is raised.
pub fn check(flag: &AtomicBool) -> Result<(), Cancelled> {
    if flag.load(Ordering::Relaxed) {
        Err(Cancelled)
    } else {
        Ok(())
    }
}

/// A flag that is never raised, for callers that do not cancel (tests, one-shot tools).
pub fn never() -> &'static AtomicBool {
    static NEVER: AtomicBool = AtomicBool::new(false);
    &NEVER
}
