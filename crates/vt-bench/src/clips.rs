//! What the `vt-bench` binaries that run `vt analyze` as a process share: the clips they make
//! from tree.avi (cached under `target/vt-bench-data/`) and a process's peak memory.

use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use anyhow::{bail, Context, Result};

/// `dir/name`, made once: tree.avi's hand-free frames (0-53) looped at 25 fps to `frames`
/// frames, scaled to `size` (`W:H`, bicubic), then `extra` filters (may be empty), encoded with
/// the ffmpeg output options `codec`.
pub fn tree_clip(
    dir: &Path,
    tree: &Path,
    name: &str,
    frames: usize,
    size: &str,
    extra: &str,
    codec: &[&str],
) -> Result<PathBuf> {
    let path = dir.join(name);
    if path.exists() {
        return Ok(path);
    }
    let mut vf = format!(
        "select=lt(n\\,54),setpts=N/25/TB,loop=loop=-1:size=54:start=0,scale={size}:flags=bicubic"
    );
    if !extra.is_empty() {
        vf.push(',');
        vf.push_str(extra);
    }
    let tmp = dir.join(format!("part-{name}"));
    let ok = Command::new("ffmpeg")
        .args(["-v", "error", "-y", "-i"])
        .arg(tree)
        .args(["-vf", &vf, "-frames:v", &frames.to_string(), "-r", "25"])
        .args(codec)
        .args(["-pix_fmt", "yuv420p"])
        .arg(&tmp)
        .status()
        .context("ffmpeg (apt-get install ffmpeg)")?
        .success();
    if !ok {
        bail!("ffmpeg failed making {name}");
    }
    std::fs::rename(&tmp, &path)?;
    Ok(path)
}

/// Peak resident memory (VmHWM) of process `pid` in KiB, while it runs.
pub fn hwm_kib(pid: u32) -> Option<u64> {
    let s = std::fs::read_to_string(format!("/proc/{pid}/status")).ok()?;
    s.lines()
        .find(|l| l.starts_with("VmHWM:"))?
        .split_whitespace()
        .nth(1)?
        .parse()
        .ok()
}

/// Runs `cmd` to the end: wall seconds, peak memory (MiB) and stdout.
pub fn timed(mut cmd: Command) -> Result<(f64, f64, String)> {
    let t = Instant::now();
    let mut child = cmd.stdout(Stdio::piped()).stderr(Stdio::null()).spawn()?;
    let pid = child.id();
    let mut out = String::new();
    let mut stdout = child.stdout.take().expect("piped");
    let reader = std::thread::spawn(move || {
        let mut s = String::new();
        std::io::Read::read_to_string(&mut stdout, &mut s).map(|_| s)
    });
    let mut peak = 0;
    let status = loop {
        peak = peak.max(hwm_kib(pid).unwrap_or(0));
        if let Some(s) = child.try_wait()? {
            break s;
        }
        std::thread::sleep(Duration::from_millis(10));
    };
    let secs = t.elapsed().as_secs_f64();
    if let Ok(Ok(s)) = reader.join() {
        out = s;
    }
    if !status.success() {
        bail!("{cmd:?} failed");
    }
    Ok((secs, peak as f64 / 1024.0, out))
}
