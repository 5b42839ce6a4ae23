//! Progress bars (to stderr, hidden when stderr is not a terminal): vt-app's [`vt_app::Progress`]
//! as bars, its notes as lines on stderr.

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

    /// On stderr, so that `vt fv eval --json` prints exactly one JSON object on stdout.
    fn note(&mut self, line: &str) {
        match &self.current {
            Some(pb) => pb.suspend(|| eprintln!("{line}")),
            None => eprintln!("{line}"),
        }
    }
}
