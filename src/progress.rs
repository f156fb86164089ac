//! Progress of long jobs, reported by the library and drawn by the caller
//! (the CLI draws bars; an embedding program may log or ignore it).

use std::sync::Arc;

/// One step of a long job: `done` of `total` units of the stage `stage`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ProgressEvent {
    /// What is being done, e.g. "reading", "neighbours", "orienting".
    pub stage: &'static str,
    /// Units finished so far.
    pub done: u64,
    /// Units in all (0 when unknown).
    pub total: u64,
}

/// Receives progress events; called often, so it must be cheap.
pub type ProgressFn = Arc<dyn Fn(ProgressEvent) + Send + Sync>;
