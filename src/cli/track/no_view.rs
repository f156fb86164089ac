//! Stands in for the live view in a build without it (the `view` feature
//! off): `--view` is refused before anything runs.

use splattrack::GpuContext;
use splattrack::view::{Flow, FrameSink, ViewError, ViewFrame};

/// What the live view did; never anything here.
pub struct Stats {
    pub shown: usize,
    pub skipped: usize,
    pub busy: std::time::Duration,
}

/// Never made: [`DisplaySink::open`] always fails.
pub enum DisplaySink {}

impl DisplaySink {
    pub fn open(_: &GpuContext, _: &str) -> anyhow::Result<Self> {
        anyhow::bail!(
            "--view: this splattrack was built without the live view (cargo feature `view`)"
        )
    }
    pub fn stats(&self) -> Stats {
        match *self {}
    }
}

impl FrameSink for DisplaySink {
    fn frame(&mut self, _: &ViewFrame<'_>) -> Result<Flow, ViewError> {
        match *self {}
    }
}
