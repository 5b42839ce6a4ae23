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

/// What a marker records about the output it is in, so that only the very file or folder vt
/// wrote there matches it: the device and inode of the written file (kept by the rename into
/// place; new for any copy, and for another tool's rewrite to a new file) and a hash of the
/// final path (another for a copy or a move to another name). `file`: the file or folder to
/// take the inode of (the temporary while writing, the target when checking); `target`: where
/// it is (to be).
fn identity(file: &Path, target: &Path) -> Result<String> {
    let meta = std::fs::metadata(file).map_err(|e| Error::io(file, e))?;
    #[cfg(unix)]
    let (dev, ino) = {
        use std::os::unix::fs::MetadataExt;
        (meta.dev(), meta.ino())
    };
    #[cfg(not(unix))]
    let (dev, ino) = {
        let _ = meta;
        (0u64, 0u64)
    };
    let place = canonical_target(target).unwrap_or_else(|| target.to_path_buf());
    // FNV-1a over the path's bytes.
    let hash = place
        .to_string_lossy()
        .bytes()
        .fold(0xcbf2_9ce4_8422_2325u64, |h, b| {
            (h ^ u64::from(b)).wrapping_mul(0x0100_0000_01b3)
        });
    Ok(format!("{dev:x}-{ino:x}-{hash:016x}"))
}

/// Temporaries and encoder processes of this run, removed or killed on SIGINT/SIGTERM.
#[derive(Default)]
struct Live {
    temps: Vec<PathBuf>,
    children: Vec<Arc<Mutex<Child>>>,
    /// Set once a signal arrived: nothing new may be registered.
    stopping: bool,
}

static LIVE: Mutex<Live> = Mutex::new(Live {
    temps: Vec::new(),
    children: Vec::new(),
    stopping: false,
});

fn live() -> std::sync::MutexGuard<'static, Live> {
    // A poisoned lock still holds a valid list: cleanup must work after any panic.
    LIVE.lock().unwrap_or_else(|e| e.into_inner())
}

fn register_temp(path: &Path) -> Result<()> {
    let mut l = live();
    if l.stopping {
        return Err(Error::Output {
            path: path.to_path_buf(),
            message: "interrupted".into(),
        });
    }
    l.temps.push(path.to_path_buf());
    Ok(())
}

fn unregister_temp(path: &Path) {
    live().temps.retain(|p| p != path);
}

/// Registers an encoder process so an interruption kills it before removing its output.
pub fn register_child(child: &Arc<Mutex<Child>>) {
    live().children.push(child.clone());
}

/// Forgets an encoder process (it has exited).
pub fn unregister_child(child: &Arc<Mutex<Child>>) {
    live().children.retain(|c| !Arc::ptr_eq(c, child));
}

fn remove_path(p: &Path) {
    match std::fs::symlink_metadata(p) {
        Ok(m) if m.is_dir() => {
            // Rename first: worker threads still writing frames into the old path then fail
            // instead of refilling the folder while it is being removed. The new name is one
            // stale cleanup also recognises, should the removal itself be cut short.
            let p = &discard_name(p)
                .filter(|d| std::fs::rename(p, d).is_ok())
                .unwrap_or_else(|| p.to_path_buf());
            // Another thread may still be writing into it: retry a few times.
            for _ in 0..5 {
                if std::fs::remove_dir_all(p).is_ok() || !p.exists() {
                    break;
                }
                std::thread::sleep(std::time::Duration::from_millis(20));
            }
        }
        Ok(_) => {
            let _ = std::fs::remove_file(p);
        }
        Err(_) => {}
    }
}

/// `.NAME.vt-del-PID` for a vt temporary `.NAME.vt-tmp-PID` (or `.NAME.vt-old-PID`).
fn discard_name(p: &Path) -> Option<PathBuf> {
    let name = p.file_name()?.to_str()?;
    let pid = stale_pid(name)?;
    let stem = name.strip_suffix(&format!("-{pid}"))?;
    let base = stem
        .strip_suffix(".vt-tmp")
        .or_else(|| stem.strip_suffix(".vt-old"))?;
    Some(p.with_file_name(format!("{base}.vt-del-{pid}")))
}

/// Kills this run's encoders and removes its temporaries; later registrations fail. Called by
/// the signal handler; also usable before an abnormal exit. Returns how many temporaries it
/// removed.
pub fn cleanup_now() -> usize {
    let mut l = live();
    l.stopping = true;
    for c in l.children.drain(..) {
        let mut c = c.lock().unwrap_or_else(|e| e.into_inner());
        let _ = c.kill();
        let _ = c.wait();
    }
    let n = l.temps.len();
    for t in l.temps.drain(..) {
        remove_path(&t);
    }
    n
}

static STOP_IS_DONE: std::sync::atomic::AtomicBool = std::sync::atomic::AtomicBool::new(false);

/// Tells the interrupt handler that this command runs until it is stopped (`vt view`): Ctrl-C
/// then ends it with "stopped" and status 0, unless it had output in progress.
pub fn interrupt_means_stop() {
    STOP_IS_DONE.store(true, std::sync::atomic::Ordering::SeqCst);
}

/// True once an interruption started cleaning up; waits until the cleanup is done. A run whose
/// work failed because its temporaries vanished under it asks this before reporting the failure.
pub fn interrupted() -> bool {
    live().stopping
}

/// Installs the SIGINT/SIGTERM (and SIGHUP) handler of a command-line run: it removes the run's
/// temporaries, kills its encoders, says so on stderr and exits with status 130.
pub fn install_interrupt_cleanup() -> Result<()> {
    ctrlc::set_handler(|| {
        let removed = cleanup_now();
        if removed == 0 && STOP_IS_DONE.load(std::sync::atomic::Ordering::SeqCst) {
            // A command that runs until stopped (a server): Ctrl-C is how it ends.
            eprintln!("stopped");
            std::process::exit(0);
        }
        if removed > 0 {
            eprintln!("error: interrupted; temporary output removed");
        } else {
            eprintln!("error: interrupted");
        }
        std::process::exit(130);
    })
    .map_err(|e| Error::Output {
        path: PathBuf::from("."),
        message: format!("cannot install the interrupt handler: {e}"),
    })
}

/// Shortens a user-supplied value for a message: at most 40 characters, the rest counted.
pub fn shorten(s: &str) -> String {
    const MAX: usize = 40;
    let n = s.chars().count();
    if n <= MAX {
        return s.to_string();
    }
    let head: String = s.chars().take(MAX - 8).collect();
    format!("{head}... ({n} characters)")
}

/// Formats a user-supplied number for a message: as Rust prints it when that is short, else in
/// scientific notation (`1e-300`, not 300 digits).
pub fn num(x: f64) -> String {
    let plain = x.to_string();
    if plain.len() <= 24 {
        plain
    } else {
        format!("{x:e}")
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

/// Whether a process id is running (Linux: `/proc/PID`). Elsewhere every process counts as
/// running, so nothing is removed.
fn process_alive(pid: u32) -> bool {
    if !Path::new("/proc/self").exists() {
        return true;
    }
    Path::new("/proc").join(pid.to_string()).exists()
}

/// Removes vt's `.NAME.vt-tmp-PID` / `.NAME.vt-old-PID` entries in `dir` whose process no longer
/// exists. Nothing else matches: a look-alike without `vt-` is another program's, and kept.
pub fn remove_stale_temps(dir: &Path) {
    let Ok(rd) = std::fs::read_dir(dir) else {
        return;
    };
    let me = std::process::id();
    for e in rd.flatten() {
        let name = e.file_name();
        let Some(pid) = stale_pid(&name.to_string_lossy()) else {
            continue;
        };
        if pid == me || process_alive(pid) {
            continue;
        }
        remove_path(&e.path());
    }
}

/// The process id in a vt temporary's name `.NAME.vt-tmp-PID` or `.NAME.vt-old-PID`.
fn stale_pid(name: &str) -> Option<u32> {
    let rest = name.strip_prefix('.')?;
    let (stem, pid) = rest.rsplit_once('-')?;
    let vt_temp = [".vt-tmp", ".vt-old", ".vt-del"]
        .iter()
        .any(|suffix| stem.ends_with(suffix));
    if !vt_temp || stem.len() < 8 {
        return None;
    }
    if pid.is_empty() || !pid.bytes().all(|b| b.is_ascii_digit()) {
        return None;
    }
    pid.parse().ok()
}

// ---- Markers embedded in single files ----

/// Adds vt's marker to a finished file, in a way its format allows: a first line `# MARKER` in
/// a points file (text), a PNG `tEXt` chunk after
/// `IHDR`, a JPEG `COM` segment after `SOI`, a GIF comment extension before the trailer. MP4 files
/// get theirs from the encoder (`-metadata comment=...`, see [`mp4_marker_args`]) and are only
/// checked here. The marker records the identity of `path` as the file that will be at `target`
/// ([`identity`]); the marking rewrites `path` in place (same inode).
pub fn embed_marker(path: &Path, kind: OutputKind, target: &Path) -> Result<()> {
    let mut head = [0u8; 8];
    let mut f = std::fs::OpenOptions::new()
        .read(true)
        .write(true)
        .open(path)
        .map_err(|e| Error::io(path, e))?;
    let n = f.read(&mut head).map_err(|e| Error::io(path, e))?;
    let marker = kind.marker(&identity(path, target)?);
    let io = |e| Error::io(path, e);
    if kind == OutputKind::Points {
        let mut data = format!("# {marker}\n").into_bytes();
        f.seek(SeekFrom::Start(0)).map_err(io)?;
        f.read_to_end(&mut data).map_err(io)?;
        std::fs::write(path, data).map_err(io)
    } else if n == 8 && head == *b"\x89PNG\r\n\x1a\n" {
        let mut data = Vec::new();
        f.seek(SeekFrom::Start(0)).map_err(io)?;
        f.read_to_end(&mut data).map_err(io)?;
        let ihdr_end = 8 + 25;
        if data.len() < ihdr_end || &data[12..16] != b"IHDR" {
            return Err(out_err(path, "not a PNG vt can mark"));
        }
        let mut body = b"tEXt".to_vec();
        body.extend_from_slice(b"Comment\0");
        body.extend_from_slice(marker.as_bytes());
        let mut chunk = ((body.len() - 4) as u32).to_be_bytes().to_vec();
        chunk.extend_from_slice(&body);
        chunk.extend_from_slice(&crc32fast::hash(&body).to_be_bytes());
        data.splice(ihdr_end..ihdr_end, chunk);
        std::fs::write(path, data).map_err(io)
    } else if n >= 2 && head[..2] == [0xFF, 0xD8] {
        let mut data = Vec::new();
        f.seek(SeekFrom::Start(0)).map_err(io)?;
        f.read_to_end(&mut data).map_err(io)?;
        let mut seg = vec![0xFF, 0xFE];
        seg.extend_from_slice(&((marker.len() + 2) as u16).to_be_bytes());
        seg.extend_from_slice(marker.as_bytes());
        data.splice(2..2, seg);
        std::fs::write(path, data).map_err(io)
    } else if n >= 6 && (&head[..6] == b"GIF89a" || &head[..6] == b"GIF87a") {
        let len = f.metadata().map_err(io)?.len();
        let mut last = [0u8; 1];
        f.seek(SeekFrom::Start(len.saturating_sub(1))).map_err(io)?;
        f.read_exact(&mut last).map_err(io)?;
        if last[0] != 0x3B {
            return Err(out_err(path, "GIF without its trailer"));
        }
        f.seek(SeekFrom::Start(len - 1)).map_err(io)?;
        f.write_all(&gif_comment(&marker)).map_err(io)
    } else if contains_marker(path, &marker)? {
        Ok(())
    } else {
        Err(out_err(path, "vt could not mark this file as its output"))
    }
}

fn gif_comment(marker: &str) -> Vec<u8> {
    let mut v = vec![0x21, 0xFE, marker.len() as u8];
    v.extend_from_slice(marker.as_bytes());
    v.extend_from_slice(&[0x00, 0x3B]);
    v
}

/// Whether a file carries vt's marker of `kind` for itself, where it is (see [`embed_marker`]):
/// false for a copy of a vt output, or one moved from another name.
pub fn has_marker(path: &Path, kind: OutputKind) -> Result<bool> {
    contains_marker(path, &kind.marker(&identity(path, path)?))
}

/// Whether a file carries the marker text `marker` where its format keeps vt's marker.
fn contains_marker(path: &Path, marker: &str) -> Result<bool> {
    let io = |e| Error::io(path, e);
    let mut f = std::fs::File::open(path).map_err(io)?;
    let len = f.metadata().map_err(io)?.len();
    let mut head = vec![0u8; 64 << 10];
    let n = read_up_to(&mut f, &mut head).map_err(io)?;
    head.truncate(n);
    if head.starts_with(b"# ") {
        // A text file: the marker is its first line, as a comment.
        let line = head.split(|&b| b == b'\n').next().unwrap_or_default();
        let line = line.strip_suffix(b"\r").unwrap_or(line);
        return Ok(line.strip_prefix(b"# ") == Some(marker.as_bytes()));
    }
    if head.starts_with(b"\x89PNG") {
        // tEXt chunks before IDAT; vt puts its own right after IHDR.
        let mut o = 8usize;
        while o + 8 <= head.len() {
            let l = u32::from_be_bytes(head[o..o + 4].try_into().expect("4 bytes")) as usize;
            let t = &head[o + 4..o + 8];
            if t == b"IDAT" {
                break;
            }
            let end = o.saturating_add(8).saturating_add(l);
            if t == b"tEXt" && end <= head.len() {
                let body = &head[o + 8..end];
                if body.strip_prefix(b"Comment\0") == Some(marker.as_bytes()) {
                    return Ok(true);
                }
            }
            o = end.saturating_add(4);
        }
        return Ok(false);
    }
    if head.starts_with(&[0xFF, 0xD8]) {
        let mut seg = vec![0xFF, 0xFE];
        seg.extend_from_slice(&((marker.len() + 2) as u16).to_be_bytes());
        seg.extend_from_slice(marker.as_bytes());
        return Ok(head[2..].starts_with(&seg));
    }
    if head.starts_with(b"GIF8") {
        let tail = gif_comment(marker);
        if len < tail.len() as u64 {
            return Ok(false);
        }
        let mut buf = vec![0u8; tail.len()];
        f.seek(SeekFrom::Start(len - tail.len() as u64))
            .map_err(io)?;
        f.read_exact(&mut buf).map_err(io)?;
        return Ok(buf == tail);
    }
    if head.len() >= 8 && &head[4..8] == b"ftyp" {
        // MP4: find the top-level moov box and look for the comment in it.
        let mut o = 0u64;
        while o + 8 <= len {
            let mut hdr = [0u8; 16];
            f.seek(SeekFrom::Start(o)).map_err(io)?;
            let got = read_up_to(&mut f, &mut hdr).map_err(io)?;
            if got < 8 {
                break;
            }
            let mut size = u32::from_be_bytes(hdr[..4].try_into().expect("4 bytes")) as u64;
            let mut body = 8;
            if size == 1 && got >= 16 {
                size = u64::from_be_bytes(hdr[8..16].try_into().expect("8 bytes"));
                body = 16;
            } else if size == 0 {
                size = len - o;
            }
            if size < body {
                break;
            }
            if &hdr[4..8] == b"moov" {
                let take = (size - body).min(64 << 20);
                let mut moov = Vec::new();
                f.seek(SeekFrom::Start(o + body)).map_err(io)?;
                (&mut f).take(take).read_to_end(&mut moov).map_err(io)?;
                return Ok(moov.windows(marker.len()).any(|w| w == marker.as_bytes()));
            }
            o = o.saturating_add(size);
        }
        return Ok(false);
    }
    Ok(false)
}

fn read_up_to(f: &mut std::fs::File, buf: &mut [u8]) -> std::io::Result<usize> {
    let mut n = 0;
    while n < buf.len() {
        match f.read(&mut buf[n..])? {
            0 => break,
            k => n += k,
        }
    }
    Ok(n)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn entries(dir: &Path) -> Vec<String> {
        let mut v: Vec<String> = std::fs::read_dir(dir)
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().to_string())
            .collect();
        v.sort();
        v
    }

    #[test]
    fn replaces_only_its_own_kind_and_never_foreign_folders() {
        let root = tempfile::tempdir().unwrap();
        let target = root.path().join("scene");
        // A first output, then a replacement.
        let o = Output::dir(&target, OutputKind::Scene, &[]).unwrap();
        std::fs::write(o.path().join("a.txt"), "1").unwrap();
        o.commit().unwrap();
        let o = Output::dir(&target, OutputKind::Scene, &[]).unwrap();
        std::fs::write(o.path().join("b.txt"), "2").unwrap();
        {
            // An unfinished one is dropped: the committed one stays.
            let d = Output::dir(&root.path().join("other"), OutputKind::Scene, &[]).unwrap();
            std::fs::write(d.path().join("x"), "x").unwrap();
        }
        o.commit().unwrap();
        assert_eq!(entries(&target), vec![".vt-output", "b.txt"]);
        assert_eq!(entries(root.path()), vec!["scene"], "no temporary left");
        // Another kind, a user file inside, a foreign folder, a file: refused, untouched.
        let e = Output::dir(&target, OutputKind::Frames, &[])
            .err()
            .unwrap()
            .to_string();
        assert!(
            e.contains("is a vt scene output, not a vt frames output"),
            "{e}"
        );
        std::fs::write(target.join("photo.jpg"), "mine").unwrap();
        let e = Output::dir(&target, OutputKind::Scene, &[])
            .err()
            .unwrap()
            .to_string();
        assert!(e.contains("also holds photo.jpg"), "{e}");
        let foreign = root.path().join("photos");
        std::fs::create_dir(&foreign).unwrap();
        std::fs::write(foreign.join("p.jpg"), "x").unwrap();
        let e = Output::dir(&foreign, OutputKind::Scene, &[])
            .err()
            .unwrap()
            .to_string();
        assert!(
            e.contains("not a vt output (a folder with 1 entry and"),
            "{e}"
        );
        let file = root.path().join("notes.txt");
        std::fs::write(&file, "x").unwrap();
        let e = Output::dir(&file, OutputKind::Scene, &[])
            .err()
            .unwrap()
            .to_string();
        assert!(e.contains("is a file"), "{e}");
        let e = Output::dir(&file.join("x"), OutputKind::Scene, &[])
            .err()
            .unwrap()
            .to_string();
        assert!(e.contains("notes.txt is a file, not a folder"), "{e}");
        assert_eq!(std::fs::read_to_string(&file).unwrap(), "x");
        assert_eq!(
            std::fs::read_to_string(target.join("photo.jpg")).unwrap(),
            "mine"
        );
    }

    #[test]
    fn refuses_inputs_and_folders_holding_them() {
        let root = tempfile::tempdir().unwrap();
        let frames = root.path().join("frames");
        std::fs::create_dir(&frames).unwrap();
        let f = frames.join("f0.png");
        std::fs::write(&f, "x").unwrap();
        for (target, want) in [
            (&frames, "is one of this run's inputs"),
            (&root.path().to_path_buf(), "holds"),
        ] {
            let e = Output::dir(target, OutputKind::Scene, &[&frames])
                .err()
                .unwrap()
                .to_string();
            assert!(e.contains(want), "{e}");
        }
        // Through a relative path with `..` too.
        let sneaky = frames.join("..").join("frames");
        assert!(Output::dir(&sneaky, OutputKind::Scene, &[&f]).is_err());
        assert!(f.exists());
    }

    #[test]
    fn stale_temporaries_of_dead_processes_are_removed() {
        let root = tempfile::tempdir().unwrap();
        // A pid that cannot be running (above Linux's pid_max limit of 2^22).
        let dead = root.path().join(".scene.vt-tmp-4194305");
        std::fs::create_dir(&dead).unwrap();
        std::fs::write(dead.join("half"), "x").unwrap();
        let alive = root.path().join(format!(".scene.vt-tmp-{}", 1));
        std::fs::create_dir(&alive).unwrap();
        let user = root.path().join(".tmp-notes");
        std::fs::write(&user, "x").unwrap();
        // Another program's temporary of a process that is gone: not vt's, so kept.
        let other = root.path().join(".scene.tmp-4194305");
        std::fs::write(&other, "x").unwrap();
        let o = Output::dir(&root.path().join("scene"), OutputKind::Scene, &[]).unwrap();
        o.commit().unwrap();
        let left = entries(root.path());
        if Path::new("/proc/self").exists() {
            assert!(
                !left.contains(&".scene.vt-tmp-4194305".to_string()),
                "{left:?}"
            );
        }
        assert!(
            left.contains(&".scene.vt-tmp-1".to_string()),
            "pid 1 is alive: {left:?}"
        );
        assert!(left.contains(&".tmp-notes".to_string()), "{left:?}");
        assert!(left.contains(&".scene.tmp-4194305".to_string()), "{left:?}");
        assert_eq!(stale_pid(".a.b.vt-tmp-12"), Some(12));
        assert_eq!(stale_pid(".a.vt-old-7"), Some(7));
        assert_eq!(stale_pid(".a.vt-del-7"), Some(7));
        assert_eq!(
            discard_name(Path::new("/x/.a.b.vt-tmp-12")),
            Some(PathBuf::from("/x/.a.b.vt-del-12"))
        );
        assert_eq!(discard_name(Path::new("/x/.a.tmp-12")), None);
        assert_eq!(stale_pid(".a.tmp-12"), None);
        assert_eq!(stale_pid(".vt-tmp-7"), None);
        assert_eq!(stale_pid("a.vt-tmp-7"), None);
        assert_eq!(stale_pid(".a.vt-tmp-7x"), None);
    }

    #[test]
    fn file_markers_round_trip() {
        let root = tempfile::tempdir().unwrap();
        let img = image::RgbImage::from_pixel(5, 4, image::Rgb([1, 2, 3]));
        for (name, fmt) in [
            ("a.png", image::ImageFormat::Png),
            ("a.jpg", image::ImageFormat::Jpeg),
        ] {
            let target = root.path().join(name);
            let o = Output::file(&target, OutputKind::Image, &[]).unwrap();
            img.save_with_format(o.path(), fmt).unwrap();
            o.commit().unwrap();
            assert!(has_marker(&target, OutputKind::Image).unwrap(), "{name}");
            assert!(!has_marker(&target, OutputKind::Video).unwrap(), "{name}");
            let back = image::open(&target).unwrap().to_rgb8();
            assert_eq!(back.dimensions(), (5, 4), "{name} still decodes");
            // Replaceable now; a plain image of the user's is not.
            assert!(Output::file(&target, OutputKind::Image, &[]).is_ok());
            let user = root.path().join(format!("user_{name}"));
            img.save_with_format(&user, fmt).unwrap();
            let e = Output::file(&user, OutputKind::Image, &[])
                .err()
                .unwrap()
                .to_string();
            assert!(e.contains("not a vt image output"), "{e}");
        }
        // A GIF (1x1, hand-made): the comment goes before the trailer.
        let gif = root.path().join("a.gif");
        let o = Output::file(&gif, OutputKind::Video, &[]).unwrap();
        let bytes: &[u8] = b"GIF89a\x01\x00\x01\x00\x80\x00\x00\xff\xff\xff\x00\x00\x00,\x00\x00\x00\x00\x01\x00\x01\x00\x00\x02\x02D\x01\x00;";
        std::fs::write(o.path(), bytes).unwrap();
        o.commit().unwrap();
        assert!(has_marker(&gif, OutputKind::Video).unwrap());
        let back = std::fs::read(&gif).unwrap();
        assert_eq!(&back[..bytes.len() - 1], &bytes[..bytes.len() - 1]);
        assert_eq!(back.last(), Some(&0x3B));
        assert_eq!(shorten("short"), "short");
        assert_eq!(num(1e-300), "1e-300");
        assert_eq!(num(2.5), "2.5");
        assert_eq!(
            shorten(&"9".repeat(309)),
            format!("{}... (309 characters)", "9".repeat(32))
        );
    }

    /// The mark records the very file (or folder) vt wrote there: a copy of a vt output, one
    /// copied over another vt output, or one moved from another name is refused as a target and
    /// kept; vt's own output at its place is still replaced.
    #[test]
    fn a_copied_mark_does_not_make_a_file_replaceable() {
        let root = tempfile::tempdir().unwrap();
        let img = image::RgbImage::from_pixel(5, 4, image::Rgb([1, 2, 3]));
        let target = root.path().join("a.png");
        let write = |t: &Path| {
            let o = Output::file(t, OutputKind::Image, &[]).unwrap();
            img.save_with_format(o.path(), image::ImageFormat::Png)
                .unwrap();
            o.commit().unwrap();
        };
        write(&target);
        write(&target);
        let refused = |t: &Path| {
            let e = Output::file(t, OutputKind::Image, &[])
                .err()
                .expect("refused")
                .to_string();
            assert!(e.contains("not a vt image output written here"), "{e}");
        };
        // A copy under another name.
        let copy = root.path().join("holiday.png");
        std::fs::copy(&target, &copy).unwrap();
        refused(&copy);
        // Copied over another vt output (the same inode there, other bytes).
        let other = root.path().join("b.png");
        write(&other);
        std::fs::copy(&target, &other).unwrap();
        refused(&other);
        // Moved to another name.
        let moved = root.path().join("moved.png");
        std::fs::rename(&target, &moved).unwrap();
        refused(&moved);
        assert!(moved.exists() && copy.exists() && other.exists());
        // A folder output copied elsewhere.
        let dir = root.path().join("frames");
        let o = Output::dir(&dir, OutputKind::Frames, &[]).unwrap();
        std::fs::write(o.path().join("f.png"), b"x").unwrap();
        o.commit().unwrap();
        assert!(Output::dir(&dir, OutputKind::Frames, &[]).is_ok());
        let dcopy = root.path().join("frames-copy");
        std::fs::create_dir(&dcopy).unwrap();
        for name in ["f.png", MARKER_FILE] {
            std::fs::copy(dir.join(name), dcopy.join(name)).unwrap();
        }
        let e = Output::dir(&dcopy, OutputKind::Frames, &[])
            .err()
            .expect("refused")
            .to_string();
        assert!(e.contains("not the folder vt wrote here"), "{e}");
    }
}
