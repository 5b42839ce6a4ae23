//! Progress bars (to stderr, hidden when stderr is not a terminal) and the analysis observer
//! that also streams each view's moving-object store to disk.

use std::path::PathBuf;

use image::RgbImage;
use indicatif::{ProgressBar, ProgressStyle};
use vt_core::analysis::{Observer, Stage};
use vt_core::Mask;
use vt_io::objects::StoreWriter;

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

/// Progress bars per stage, and object stores written as masks arrive (vt-io's [`StoreWriter`]).
pub struct AnalysisObserver {
    current: Option<ProgressBar>,
    stores: StoreWriter,
}

impl AnalysisObserver {
    /// Writes object stores at `quality` into `dir` (the scene's temporary directory).
    pub fn new(dir: PathBuf, quality: vt_io::objects::StoreQuality) -> Self {
        Self {
            current: None,
            stores: StoreWriter::with_quality(dir, quality),
        }
    }

    /// Closes the last object store.
    pub fn finish_objects(&mut self) -> vt_core::Result<()> {
        self.stores.finish()
    }
}

impl Observer for AnalysisObserver {
    fn start(&mut self, stage: Stage, view: Option<usize>, total: Option<u64>) {
        let msg = match view {
            Some(p) => format!("view {p}: {stage}"),
            None => stage.to_string(),
        };
        self.current = Some(match total {
            Some(t) => bar(t, &msg),
            None => spinner(&msg),
        });
    }

    fn tick(&mut self) {
        if let Some(pb) = &self.current {
            pb.inc(1);
        }
    }

    fn finish(&mut self) {
        if let Some(pb) = self.current.take() {
            pb.finish_and_clear();
        }
    }

    fn object_frame(
        &mut self,
        view: usize,
        frame: usize,
        mask: &Mask,
        raw: &RgbImage,
    ) -> vt_core::Result<()> {
        self.stores.object_frame(view, frame, mask, raw)
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
