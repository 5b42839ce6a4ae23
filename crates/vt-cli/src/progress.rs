//! Progress bars (to stderr, hidden when stderr is not a terminal): vt-app's [`vt_app::Progress`]
//! as bars, and bars for vt-fv's `progress(stage, done, total)` callbacks.

use indicatif::{ProgressBar, ProgressStyle};

/// A bar with a message, or a spinner when the total is unknown.
pub fn bar(total: u64, msg: &str) -> ProgressBar {
    let pb = ProgressBar::new(total);
    pb.set_style(
        ProgressStyle::with_template(
            "{msg:>24} [{bar:30}] {pos}/{len} {elapsed_precise} eta {eta}",
        )
        .expect("static template")
        .progress_chars("=> "),
    );
    pb.set_message(msg.to_string());
    pb
}

fn spinner(msg: &str) -> ProgressBar {
    let pb = ProgressBar::new_spinner();
    pb.set_style(
        ProgressStyle::with_template("{msg:>24} {spinner} {pos} {elapsed_precise}")
            .expect("static template"),
    );
    pb.set_message(msg.to_string());
    pb
}

/// Progress bars for vt-app's use cases: one bar per stage (a spinner while the total is
/// unknown), cleared when the stage ends.
#[derive(Default)]
pub struct Bars {
    current: Option<ProgressBar>,
}

impl vt_app::Progress for Bars {
    fn start(&mut self, stage: &str, total: Option<u64>) {
        self.finish();
        self.current = Some(match total {
            Some(t) => bar(t, stage),
            None => spinner(stage),
        });
    }

    fn at(&mut self, done: u64, total: Option<u64>) {
        if let Some(pb) = &self.current {
            if let Some(t) = total {
                pb.set_length(t);
            }
            pb.set_position(done);
        }
    }

    fn finish(&mut self) {
        if let Some(pb) = self.current.take() {
            pb.finish_and_clear();
        }
    }
}

/// One bar per stage for library calls that report `progress(stage, done, total)`: a new bar
/// when the stage changes, cleared by [`StageBars::finish`].
#[derive(Default)]
pub struct StageBars {
    current: Option<(String, ProgressBar)>,
}

impl StageBars {
    /// The progress callback.
    pub fn update(&mut self, stage: &str, done: u64, total: u64) {
        if self.current.as_ref().is_none_or(|(s, _)| s != stage) {
            self.finish();
            self.current = Some((stage.to_string(), bar(total, stage)));
        }
        if let Some((_, pb)) = &self.current {
            pb.set_position(done);
        }
    }

    /// Clears the last bar.
    pub fn finish(&mut self) {
        if let Some((_, pb)) = self.current.take() {
            pb.finish_and_clear();
        }
    }
}
