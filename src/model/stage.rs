//! Progress of a stage of loading or estimation, reported to an optional
//! [`ProgressFn`].

use crate::progress::{ProgressEvent, ProgressFn};
use std::cell::Cell;

/// One stage of a job, reported to an optional [`ProgressFn`].
pub(crate) struct Stage<'a> {
    report: Option<&'a ProgressFn>,
    stage: &'static str,
    total: u64,
    done: Cell<u64>,
}

impl<'a> Stage<'a> {
    pub(crate) fn new(report: Option<&'a ProgressFn>, stage: &'static str, total: usize) -> Self {
        Self {
            report,
            stage,
            total: total as u64,
            done: Cell::new(0),
        }
    }

    /// A stage that reports nothing.
    pub(crate) fn silent() -> Self {
        Self::new(None, "", 0)
    }

    fn emit(&self) {
        if let Some(report) = self.report {
            report(ProgressEvent {
                stage: self.stage,
                done: self.done.get(),
                total: self.total,
            });
        }
    }

    /// `units` more are done.
    pub(crate) fn advance(&self, units: u64) {
        self.done.set(self.done.get() + units);
        self.emit();
    }

    /// The stage is complete.
    pub(crate) fn finish(&self) {
        self.done.set(self.total);
        self.emit();
    }
}
