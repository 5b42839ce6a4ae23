//! How a use case reports progress: stages with a step count, each followed to its end.

/// Progress of a long use case. Every method has an empty default. `Send`: the render driver
/// reports from the thread that renders.
pub trait Progress: Send {
    /// A stage begins: its name (`"view 0: median"`, `"render"`) and its steps when known.
    fn start(&mut self, _stage: &str, _total: Option<u64>) {}
    /// `done` steps of the current stage are done (`total` when it became known only now).
    fn at(&mut self, _done: u64, _total: Option<u64>) {}
    /// The current stage ended.
    fn finish(&mut self) {}
    /// A line the user should read now (e.g. "photos rescaled to the cameras' size").
    fn note(&mut self, _line: &str) {}
}

/// Reports nothing.
#[derive(Debug, Default, Clone, Copy)]
pub struct Silent;

impl Progress for Silent {}

/// Runs `f` with a `Fn() + Sync` tick (what vt-synth's parallel writers call once per frame)
/// that advances `progress` through a stage named `stage` of `total` steps.
pub(crate) fn with_ticks<R>(
    progress: &mut dyn Progress,
    stage: &str,
    total: u64,
    f: impl FnOnce(&(dyn Fn() + Sync)) -> R,
) -> R {
    progress.start(stage, Some(total));
    let counter = std::sync::Mutex::new((&mut *progress, 0u64));
    let tick = || {
        let mut g = counter.lock().unwrap_or_else(|e| e.into_inner());
        g.1 += 1;
        let n = g.1;
        g.0.at(n, None);
    };
    let out = f(&tick);
    progress.finish();
    out
}
