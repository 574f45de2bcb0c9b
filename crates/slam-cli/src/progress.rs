//! The progress bar of `slam run`: on stderr, only when stderr is a terminal, not with
//! `--quiet`, and only once a run has lasted more than a second (short runs stay silent).

use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};
use std::io::IsTerminal;
use std::time::{Duration, Instant};

/// How long a run must last before the bar appears.
const DELAY: Duration = Duration::from_secs(1);

/// A progress bar that appears late, or never.
pub(crate) struct Progress {
    enabled: bool,
    total: u64,
    start: Instant,
    bar: Option<ProgressBar>,
}

impl Progress {
    /// A bar over `total` steps; shown only if `!quiet`, stderr is a terminal and the run
    /// passes one second.
    pub(crate) fn new(total: usize, quiet: bool) -> Self {
        Self {
            enabled: !quiet && std::io::stderr().is_terminal(),
            total: total as u64,
            start: Instant::now(),
            bar: None,
        }
    }

    /// Reports that `done` steps are finished.
    pub(crate) fn set(&mut self, done: usize) {
        if !self.enabled {
            return;
        }
        if self.bar.is_none() {
            // Checking the clock every step costs nothing next to a filter step.
            if self.start.elapsed() < DELAY {
                return;
            }
            let bar = ProgressBar::with_draw_target(
                Some(self.total),
                ProgressDrawTarget::stderr_with_hz(10),
            )
            .with_elapsed(self.start.elapsed());
            if let Ok(style) = ProgressStyle::with_template(
                "{elapsed_precise} [{bar:30}] {pos}/{len} steps, {msg}",
            ) {
                bar.set_style(style.progress_chars("=> "));
            }
            self.bar = Some(bar);
        }
        if let Some(bar) = &self.bar {
            // Rate and time left from the whole run so far (indicatif's own estimator would
            // see the bar start at a large position and report a spike).
            let elapsed = self.start.elapsed().as_secs_f64();
            let rate = done as f64 / elapsed.max(1e-9);
            let left = (self.total as f64 - done as f64).max(0.0) / rate.max(1e-9);
            bar.set_message(format!("{rate:.0}/s, {left:.0} s left"));
            bar.set_position(done as u64);
        }
    }

    /// Removes the bar (if it was shown).
    pub(crate) fn finish(&mut self) {
        if let Some(bar) = self.bar.take() {
            bar.finish_and_clear();
        }
    }
}

impl Drop for Progress {
    fn drop(&mut self) {
        self.finish();
    }
}
