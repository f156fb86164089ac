//! Progress bars on stderr, drawn from the library's progress events: one
//! helper for every command (model loading, synth, track, demo).

use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};
use splattrack::progress::{ProgressEvent, ProgressFn};
use std::io::IsTerminal;
use std::sync::{Arc, Mutex};

/// A [`ProgressFn`] that draws one bar per stage on stderr, each labelled
/// `prefix` and the stage, cleared when its stage is done. Draws nothing
/// when stderr is not a terminal, nor for stages of fewer than `min_total`
/// units (jobs too quick for a bar to help).
pub fn bars(prefix: impl Into<String>, min_total: u64) -> ProgressFn {
    if !std::io::stderr().is_terminal() {
        return Arc::new(|_| {});
    }
    let prefix = prefix.into();
    let bars: Mutex<Vec<(&'static str, ProgressBar)>> = Mutex::new(Vec::new());
    Arc::new(move |e: ProgressEvent| {
        if e.total < min_total.max(1) {
            return;
        }
        let mut bars = bars.lock().unwrap_or_else(|p| p.into_inner());
        let k = match bars.iter().position(|(s, _)| *s == e.stage) {
            Some(k) => k,
            None => {
                bars.push((e.stage, new_bar(&prefix, e.stage, e.total)));
                bars.len() - 1
            }
        };
        let bar = &bars[k].1;
        bar.set_length(e.total);
        bar.set_position(e.done);
        if e.done >= e.total {
            bar.finish_and_clear();
        }
    })
}

fn new_bar(prefix: &str, stage: &'static str, total: u64) -> ProgressBar {
    let bar = ProgressBar::with_draw_target(Some(total), ProgressDrawTarget::stderr());
    let style = ProgressStyle::with_template(
        "{prefix}{msg:>10} [{bar:40}] {pos}/{len} [{elapsed} < {eta}]",
    )
    .map(|s| s.progress_chars("=> "))
    .unwrap_or_else(|_| ProgressStyle::default_bar());
    bar.set_style(style);
    bar.set_prefix(prefix.to_owned());
    bar.set_message(stage);
    bar
}
