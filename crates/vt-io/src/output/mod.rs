//! Outputs that cannot destroy: every file or folder vt writes goes through [`Output`].
//!
//! Rules, enforced here for every command:
//! - An output is built under a hidden temporary sibling (`.NAME.vt-tmp-PID`) and renamed into place
//!   only when complete, so a failed or interrupted run leaves the previous output untouched.
//! - An existing path is replaced only when it is a previous vt output *of the same kind*,
//!   recognised by a marker vt writes: a `.vt-output` file inside a folder (its first line
//!   `vt-output KIND`, then every entry vt wrote, so a folder holding anything else is refused),
//!   and for single files a marker embedded in the file itself (an mp4 `comment` tag, a GIF comment
//!   extension, a PNG `tEXt` chunk, a JPEG `COM` segment; see [`embed_marker`]).
//! - An output is never one of the run's own inputs, nor a folder holding one.
//! - Temporaries are registered while they exist: SIGINT/SIGTERM (see [`install_interrupt_cleanup`])
//!   kill the run's encoders and remove its temporaries; temporaries left by a process that no
//!   longer exists (killed, out of memory) are removed by the next run that writes beside them.
//!
//! Anything else at the output path gets a one-line error saying what is there and how to proceed.

use std::io::{Read, Seek, SeekFrom, Write};
use std::path::{Component, Path, PathBuf};
use std::process::Child;
use std::sync::{Arc, Mutex};

use crate::{Error, Result};

/// Name of the marker file inside a vt output folder.
pub const MARKER_FILE: &str = ".vt-output";

/// Text that marks a vt output (followed by a space and the kind).
const MARKER_PREFIX: &str = "vt-output";

/// What a command writes. The kind is recorded in the marker; an output replaces only one of the
/// same kind.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum OutputKind {
    /// A scene folder (`vt analyze`).
    Scene,
    /// A folder of PNG frames (`vt render --out NAME`).
    Frames,
    /// An mp4 or GIF video (`vt render`, `vt fv orbit`).
    Video,
    /// A single PNG or JPEG image (`vt fv render`).
    Image,
    /// A points file (`vt mark`): text, the marker its first line as a `#` comment.
    Points,
    /// A synthetic texture scene folder (`vt synth textures`).
    SynthTextures,
    /// A synthetic object folder (`vt synth object`).
    SynthObject,
    /// A hull folder (`vt fv hull`).
    Hull,
    /// The demo's folder (`vt demo`).
    Demo,
    /// A web page that plays a scene (`vt export`).
    WebExport,
    /// Any other folder (written through [`crate::atomic::AtomicDir`]).
    Folder,
}

impl OutputKind {
    /// The word written in the marker.
    pub fn name(self) -> &'static str {
        match self {
            OutputKind::Scene => "scene",
            OutputKind::Frames => "frames",
            OutputKind::Video => "video",
            OutputKind::Image => "image",
            OutputKind::Points => "points",
            OutputKind::SynthTextures => "synth-textures",
            OutputKind::SynthObject => "synth-object",
            OutputKind::Hull => "hull",
            OutputKind::Demo => "demo",
            OutputKind::WebExport => "web-export",
            OutputKind::Folder => "folder",
        }
    }

    /// True for kinds that are folders.
    pub fn is_dir(self) -> bool {
        !matches!(
            self,
            OutputKind::Video | OutputKind::Image | OutputKind::Points
        )
    }

    /// The marker of an output of this kind with identity `id` ([`identity`]).
    fn marker(self, id: &str) -> String {
        format!("{MARKER_PREFIX} {} {id}", self.name())
    }
}

/// An output being written. Dropped without [`Output::commit`], its temporary is removed and the
/// target is untouched.
pub struct Output {
    target: PathBuf,
    tmp: PathBuf,
    kind: OutputKind,
    committed: bool,
}

impl Output {
    /// Starts a folder output of `kind` at `target`. Checks `target` (see the module rules)
    /// against `inputs`, removes stale temporaries beside it, and creates the temporary folder.
    pub fn dir(target: &Path, kind: OutputKind, inputs: &[&Path]) -> Result<Self> {
        debug_assert!(kind.is_dir());
        let tmp = prepare(target, kind, inputs)?;
        register_temp(&tmp)?;
        let out = Self {
            target: target.to_path_buf(),
            tmp,
            kind,
            committed: false,
        };
        std::fs::create_dir(&out.tmp).map_err(|e| Error::io(&out.tmp, e))?;
        Ok(out)
    }

    /// Starts a single-file output of `kind` at `target` (checked as for [`Output::dir`]). The
    /// temporary file is not created: write it at [`Output::path`].
    pub fn file(target: &Path, kind: OutputKind, inputs: &[&Path]) -> Result<Self> {
        debug_assert!(!kind.is_dir());
        let tmp = prepare(target, kind, inputs)?;
        register_temp(&tmp)?;
        Ok(Self {
            target: target.to_path_buf(),
            tmp,
            kind,
            committed: false,
        })
    }

    /// ffmpeg arguments that put vt's marker in an mp4's metadata, for an encoder writing to
    /// [`Output::path`]: creates that file (empty) so the marker can record its identity (the
    /// encoder then writes into the same file).
    pub fn mp4_marker_args(&self) -> Result<[String; 2]> {
        std::fs::File::create(&self.tmp).map_err(|e| Error::io(&self.tmp, e))?;
        let id = identity(&self.tmp, &self.target)?;
        Ok([
            "-metadata".into(),
            format!("comment={}", OutputKind::Video.marker(&id)),
        ])
    }

    /// Where to write now (the temporary).
    pub fn path(&self) -> &Path {
        &self.tmp
    }

    /// Where it will be.
    pub fn target(&self) -> &Path {
        &self.target
    }

    /// Marks the output (a marker file listing the folder's entries, or a marker embedded in the
    /// file) and moves it into place, replacing a previous vt output of the same kind.
    pub fn commit(mut self) -> Result<PathBuf> {
        if self.kind.is_dir() {
            let mut entries = Vec::new();
            list_entries(&self.tmp, Path::new(""), &mut entries)
                .map_err(|e| Error::io(&self.tmp, e))?;
            let mut text = self.kind.marker(&identity(&self.tmp, &self.target)?);
            text.push('\n');
            for e in entries {
                text.push_str(&e);
                text.push('\n');
            }
            let marker = self.tmp.join(MARKER_FILE);
            std::fs::write(&marker, text).map_err(|e| Error::io(&marker, e))?;
        } else {
            embed_marker(&self.tmp, self.kind, &self.target)?;
        }
        // Re-check the target: something may have appeared there while we worked.
        check_existing(&self.target, self.kind)?;
        // Hold the registry while renaming, so an interruption cannot fall between the renames.
        let mut l = live();
        if l.stopping {
            return Err(Error::Output {
                path: self.target.clone(),
                message: "interrupted".into(),
            });
        }
        let result = if self.kind.is_dir() && self.target.exists() {
            let old = sibling(&self.target, "old")?;
            std::fs::rename(&self.target, &old).map_err(|e| Error::io(&self.target, e))?;
            l.temps.push(old.clone());
            match std::fs::rename(&self.tmp, &self.target) {
                Ok(()) => {
                    remove_path(&old);
                    l.temps.retain(|p| p != &old);
                    Ok(())
                }
                Err(e) => {
                    let _ = std::fs::rename(&old, &self.target);
                    l.temps.retain(|p| p != &old);
                    Err(Error::io(&self.target, e))
                }
            }
        } else {
            std::fs::rename(&self.tmp, &self.target).map_err(|e| Error::io(&self.target, e))
        };
        l.temps.retain(|p| p != &self.tmp);
        drop(l);
        result?;
        self.committed = true;
        Ok(self.target.clone())
    }
}

impl Drop for Output {
    fn drop(&mut self) {
        if !self.committed {
            remove_path(&self.tmp);
            unregister_temp(&self.tmp);
        }
    }
}

/// `.NAME.vt-WHAT-PID` beside `target`: the `vt-` keeps other programs' look-alike temporaries
/// (`.NAME.tmp-PID` is a common pattern) out of [`remove_stale_temps`]'s reach.
fn sibling(target: &Path, what: &str) -> Result<PathBuf> {
    let name = target
        .file_name()
        .ok_or_else(|| out_err(target, "has no file name"))?
        .to_string_lossy();
    Ok(parent_of(target).join(format!(".{name}.vt-{what}-{}", std::process::id())))
}

fn parent_of(target: &Path) -> PathBuf {
    match target.parent() {
        Some(p) if !p.as_os_str().is_empty() => p.to_path_buf(),
        _ => PathBuf::from("."),
    }
}

fn out_err(path: &Path, message: impl Into<String>) -> Error {
    Error::Output {
        path: path.to_path_buf(),
        message: message.into(),
    }
}

/// All checks before writing; returns the temporary path.
fn prepare(target: &Path, kind: OutputKind, inputs: &[&Path]) -> Result<PathBuf> {
    check_place(target)?;
    let parent = parent_of(target);
    check_not_input(target, inputs)?;
    check_existing(target, kind)?;
    remove_stale_temps(&parent);
    let tmp = sibling(target, "tmp")?;
    if std::fs::symlink_metadata(&tmp).is_ok() {
        // Left by an earlier run of this very process id (pid reuse): ours to remove.
        remove_path(&tmp);
    }
    Ok(tmp)
}

/// Checks that an output of `kind` may be written at `target` (the checks [`Output::file`] and
/// [`Output::dir`] make first), without creating anything: for a tool that asks before its
/// work starts.
pub fn check_target(target: &Path, kind: OutputKind, inputs: &[&Path]) -> Result<()> {
    check_place(target)?;
    check_not_input(target, inputs)?;
    check_existing(target, kind)
}

/// Refuses a target that is no name to write, or whose folder does not exist.
fn check_place(target: &Path) -> Result<()> {
    match target.components().next_back() {
        Some(Component::Normal(_)) => {}
        _ => return Err(out_err(target, "is not a file or folder name to write")),
    }
    let parent = parent_of(target);
    match std::fs::metadata(&parent) {
        Ok(m) if m.is_dir() => Ok(()),
        Ok(_) => Err(out_err(
            target,
            format!(
                "cannot be written: {} is a file, not a folder",
                parent.display()
            ),
        )),
        Err(_) => Err(out_err(
            target,
            format!(
                "cannot be written: folder {} does not exist",
                parent.display()
            ),
        )),
    }
}

/// Refuses an output that is one of the inputs or holds one.
fn check_not_input(target: &Path, inputs: &[&Path]) -> Result<()> {
    let Some(t) = canonical_target(target) else {
        return Ok(());
    };
    for input in inputs {
        let Ok(i) = std::fs::canonicalize(input) else {
            continue;
        };
        if i == t {
            return Err(out_err(
                target,
                "is one of this run's inputs; choose another --out",
            ));
        }
        if i.starts_with(&t) {
            return Err(out_err(
                target,
                format!(
                    "holds {}, one of this run's inputs; choose another --out",
                    input.display()
                ),
            ));
        }
    }
    Ok(())
}

/// The target's absolute path with its parent resolved (the target itself may not exist).
fn canonical_target(target: &Path) -> Option<PathBuf> {
    let parent = std::fs::canonicalize(parent_of(target)).ok()?;
    let name = target.file_name()?;
    let t = parent.join(name);
    // A symbolic link at the target resolves to what it points at.
    Some(std::fs::canonicalize(&t).unwrap_or(t))
}

/// Refuses anything at `target` but a previous vt output of the same kind.
fn check_existing(target: &Path, kind: OutputKind) -> Result<()> {
    let meta = match std::fs::symlink_metadata(target) {
        Ok(m) => m,
        Err(_) => return Ok(()),
    };
    let how = "choose another --out, or move it away first";
    if meta.file_type().is_symlink() {
        return Err(out_err(
            target,
            format!("exists and is a symbolic link, not a vt output; {how}"),
        ));
    }
    if meta.is_dir() {
        let marker = target.join(MARKER_FILE);
        let text = read_small(&marker, 16 << 20);
        let Some(text) = text else {
            let n = std::fs::read_dir(target).map(|d| d.count()).unwrap_or(0);
            return Err(out_err(
                target,
                format!(
                    "exists and is not a vt output (a folder with {n} {} and no {MARKER_FILE} marker); {how}",
                    if n == 1 { "entry" } else { "entries" }
                ),
            ));
        };
        let mut lines = text.lines();
        let first = lines.next().unwrap_or("");
        let mut words = first.strip_prefix(MARKER_PREFIX).map(str::split_whitespace);
        let found = words.as_mut().and_then(|w| w.next());
        let id = words.as_mut().and_then(|w| w.next());
        if found != Some(kind.name()) {
            return Err(out_err(
                target,
                format!(
                    "is {}, not a vt {} output; {how}",
                    match found {
                        Some(k) if !k.is_empty() => format!("a vt {} output", shorten(k)),
                        _ => "a folder with an unreadable vt marker".to_string(),
                    },
                    kind.name()
                ),
            ));
        }
        if id != Some(identity(target, target)?.as_str()) {
            return Err(out_err(
                target,
                format!(
                    "holds a vt {} marker but is not the folder vt wrote here (a copy, moved \
                     from elsewhere, or written by a vt from before 2026-11-24); {how}",
                    kind.name()
                ),
            ));
        }
        let written: std::collections::HashSet<&str> = lines.collect();
        let mut present = Vec::new();
        list_entries(target, Path::new(""), &mut present).map_err(|e| Error::io(target, e))?;
        if let Some(extra) = present
            .iter()
            .find(|e| e.as_str() != MARKER_FILE && !written.contains(e.as_str()))
        {
            return Err(out_err(
                target,
                format!(
                    "is a vt {} output but also holds {}, which vt did not write; {how}",
                    kind.name(),
                    shorten(extra)
                ),
            ));
        }
        return Ok(());
    }
    if kind.is_dir() {
        return Err(out_err(
            target,
            format!(
                "exists and is a file, not a vt {} folder; {how}",
                kind.name()
            ),
        ));
    }
    match has_marker(target, kind) {
        Ok(true) => Ok(()),
        _ => Err(out_err(
            target,
            format!(
                "exists and is not a vt {} output written here (no vt marker of this very file: \
                 another tool's file, a copy of a vt output, or one from a vt before \
                 2026-11-24); {how}",
                kind.name()
            ),
        )),
    }
}

fn read_small(path: &Path, limit: u64) -> Option<String> {
    let f = std::fs::File::open(path).ok()?;
    if f.metadata().ok()?.len() > limit {
        return None;
    }
    let mut s = String::new();
    f.take(limit).read_to_string(&mut s).ok()?;
    Some(s)
}

/// Every entry under `dir`, relative, `/`-separated, folders too; symbolic links not followed.
fn list_entries(dir: &Path, rel: &Path, out: &mut Vec<String>) -> std::io::Result<()> {
    for e in std::fs::read_dir(dir.join(rel))? {
        let e = e?;
        let r = rel.join(e.file_name());
        out.push(r.to_string_lossy().replace('\\', "/"));
        if e.file_type()?.is_dir() {
            list_entries(dir, &r, out)?;
        }
    }
    Ok(())
}

mod cleanup;
mod marker;
mod message;
#[cfg(test)]
mod tests;

use cleanup::*;
pub use cleanup::{
    cleanup_now, install_interrupt_cleanup, interrupt_means_stop, interrupted, register_child,
    remove_stale_temps, unregister_child,
};
use marker::*;
pub use marker::{embed_marker, has_marker};
pub use message::{num, shorten};
