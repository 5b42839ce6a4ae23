//! Atomic output folders, the older name: an [`AtomicDir`] is an [`Output`] folder of the
//! generic kind [`OutputKind::Folder`], with no inputs to protect. New code uses
//! [`crate::output::Output`] directly, with its own kind and the run's inputs.

use std::path::{Path, PathBuf};

use crate::output::{Output, OutputKind};
use crate::Result;

/// A folder being written; it becomes `target` on [`AtomicDir::commit`]; dropped without a
/// commit, it is removed and `target` is untouched. Follows every rule of [`crate::output`].
pub struct AtomicDir(Output);

impl AtomicDir {
    /// Starts a new folder that will replace `target` (only a previous generic vt folder).
    pub fn create(target: &Path) -> Result<Self> {
        Output::dir(target, OutputKind::Folder, &[]).map(AtomicDir)
    }

    /// Where to write the contents now.
    pub fn path(&self) -> &Path {
        self.0.path()
    }

    /// Marks the folder and moves it into place.
    pub fn commit(self) -> Result<PathBuf> {
        self.0.commit()
    }
}
