//! This run's temporaries and encoder processes: registered while they exist, removed or
//! killed on SIGINT/SIGTERM; temporaries of dead processes removed by the next run beside them.

use super::*;

/// Temporaries and encoder processes of this run, removed or killed on SIGINT/SIGTERM.
#[derive(Default)]
pub(super) struct Live {
    pub(super) temps: Vec<PathBuf>,
    pub(super) children: Vec<Arc<Mutex<Child>>>,
    /// Set once a signal arrived: nothing new may be registered.
    pub(super) stopping: bool,
}

pub(super) static LIVE: Mutex<Live> = Mutex::new(Live {
    temps: Vec::new(),
    children: Vec::new(),
    stopping: false,
});

pub(super) fn live() -> std::sync::MutexGuard<'static, Live> {
    // A poisoned lock still holds a valid list: cleanup must work after any panic.
    LIVE.lock().unwrap_or_else(|e| e.into_inner())
}

pub(super) fn register_temp(path: &Path) -> Result<()> {
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

pub(super) fn unregister_temp(path: &Path) {
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

pub(super) fn remove_path(p: &Path) {
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
pub(super) fn discard_name(p: &Path) -> Option<PathBuf> {
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

pub(super) static STOP_IS_DONE: std::sync::atomic::AtomicBool =
    std::sync::atomic::AtomicBool::new(false);

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

/// Whether a process id is running (Linux: `/proc/PID`). Elsewhere every process counts as
/// running, so nothing is removed.
pub(super) fn process_alive(pid: u32) -> bool {
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
pub(super) fn stale_pid(name: &str) -> Option<u32> {
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
