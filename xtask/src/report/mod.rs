//! `cargo xtask report [--quick] [--out DIR]`: the speed/accuracy trade of every knob, measured
//! against truth (synthetic scenes) and on real data (tree.avi, templeSparseRing), vt-core against
//! OpenCV, written as `index.html` + plots, `report.json` and `README.md`.
//!
//! Layout: [`model`] is what a report holds, [`plot`] draws, [`html`] writes the page and the
//! Markdown, [`data`] builds the shared inputs once (lazily), and `sections/` measures. A knob is
//! one entry in a section's list: a function returning its curve (see `sections/knobs_a.rs`).

pub mod data;
pub mod html;
pub mod model;
pub mod plot;
pub mod sections;

use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::Instant;

use anyhow::{bail, Context, Result};
use image::RgbImage;

use model::{Item, Machine, Report, Section};

/// The format tag of `report.json`; an existing `--out` is replaced only if it holds one.
pub const FORMAT: &str = "vt-report 1";

/// Shared state of one run: options, where files go, and lazily built inputs.
pub struct Ctx {
    /// `--quick`: smaller inputs, fewer settings.
    pub quick: bool,
    /// `--only TEXT`: only the sections and knobs whose title holds TEXT (any case).
    pub only: Option<String>,
    /// The report directory being written (temporary until the run completes).
    pub dir: PathBuf,
    /// Scratch space for scene directories; removed at the end.
    pub work: tempfile::TempDir,
    /// Lazily built inputs.
    pub data: data::Cache,
}

impl Ctx {
    /// Whether a section or knob titled `title` is measured in this run (`--only`).
    pub fn wants(&self, title: &str) -> bool {
        self.only
            .as_ref()
            .is_none_or(|o| title.to_lowercase().contains(&o.to_lowercase()))
    }

    /// Picks the quick or the full value.
    pub fn pick<T>(&self, quick: T, full: T) -> T {
        if self.quick {
            quick
        } else {
            full
        }
    }

    /// Saves an image under `images/` and returns its path relative to the report.
    pub fn save_image(&self, name: &str, img: &RgbImage) -> Result<String> {
        let rel = format!("images/{name}.png");
        img.save(self.dir.join(&rel))
            .with_context(|| format!("writing {rel}"))?;
        Ok(rel)
    }
}

/// Seconds `f` takes, as the median of `reps` runs (at least one), and its last result.
pub fn timed<T>(reps: usize, mut f: impl FnMut() -> T) -> (f64, T) {
    let mut times = Vec::new();
    let mut last = None;
    for _ in 0..reps.max(1) {
        let t = Instant::now();
        let v = f();
        times.push(t.elapsed().as_secs_f64());
        last = Some(v);
    }
    times.sort_by(f64::total_cmp);
    (times[times.len() / 2], last.expect("ran at least once"))
}

/// Peak resident memory of this process so far, MiB (Linux `VmHWM`; NaN elsewhere).
pub fn peak_rss_mib() -> f64 {
    std::fs::read_to_string("/proc/self/status")
        .ok()
        .and_then(|s| {
            s.lines()
                .find(|l| l.starts_with("VmHWM:"))
                .and_then(|l| l.split_whitespace().nth(1)?.parse::<f64>().ok())
        })
        .map(|kib| kib / 1024.0)
        .unwrap_or(f64::NAN)
}

fn machine() -> Machine {
    let cpuinfo = std::fs::read_to_string("/proc/cpuinfo").unwrap_or_default();
    let cpu = cpuinfo
        .lines()
        .find(|l| l.starts_with("model name"))
        .and_then(|l| l.split(':').nth(1))
        .map(|s| s.trim().to_string())
        .unwrap_or_else(|| "unknown CPU".into());
    let memory_gib = std::fs::read_to_string("/proc/meminfo")
        .ok()
        .and_then(|s| {
            s.lines()
                .find(|l| l.starts_with("MemTotal:"))
                .and_then(|l| l.split_whitespace().nth(1)?.parse::<f64>().ok())
        })
        .map(|kib| kib / (1024.0 * 1024.0))
        .unwrap_or(f64::NAN);
    let os = std::fs::read_to_string("/etc/os-release")
        .ok()
        .and_then(|s| {
            s.lines().find(|l| l.starts_with("PRETTY_NAME=")).map(|l| {
                l.trim_start_matches("PRETTY_NAME=")
                    .trim_matches('"')
                    .to_string()
            })
        })
        .unwrap_or_else(|| std::env::consts::OS.into());
    Machine {
        cpu,
        cores: std::thread::available_parallelism().map_or(1, |n| n.get()),
        memory_gib,
        os,
    }
}

fn command_line(cmd: &str, args: &[&str]) -> Option<String> {
    let out = Command::new(cmd).args(args).output().ok()?;
    out.status
        .success()
        .then(|| String::from_utf8_lossy(&out.stdout).trim().to_string())
}

fn commit() -> String {
    let root = workspace_root();
    let root = root.to_string_lossy();
    let head = command_line("git", &["-C", &root, "rev-parse", "--short=12", "HEAD"])
        .unwrap_or_else(|| "unknown".into());
    let dirty = command_line(
        "git",
        &["-C", &root, "status", "--porcelain", "--untracked-files=no"],
    )
    .is_some_and(|s| !s.is_empty());
    if dirty {
        format!("{head}-dirty")
    } else {
        head
    }
}

/// The workspace root (xtask's parent).
pub fn workspace_root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .parent()
        .expect("xtask lives in the workspace")
        .to_path_buf()
}

/// `testdata/` of the workspace.
pub fn testdata() -> PathBuf {
    workspace_root().join("testdata")
}

const USAGE: &str = "cargo xtask report [--quick] [--only TEXT] [--out DIR]   (default DIR: target/report; --only: just the sections and knobs whose title holds TEXT)";

/// Refuses to replace anything that is not an earlier report (or an empty directory).
fn check_replaceable(out: &Path) -> Result<()> {
    if !out.exists() {
        return Ok(());
    }
    if !out.is_dir() {
        bail!("--out {}: exists and is not a directory", out.display());
    }
    let empty = std::fs::read_dir(out)
        .with_context(|| out.display().to_string())?
        .next()
        .is_none();
    let ours = std::fs::read_to_string(out.join("report.json"))
        .ok()
        .and_then(|s| serde_json::from_str::<serde_json::Value>(&s).ok())
        .is_some_and(|v| v["format"] == FORMAT);
    if !(empty || ours) {
        bail!(
            "--out {}: exists and is not an earlier vt report (no report.json of format '{FORMAT}'); \
             choose another directory, vt replaces only its own reports",
            out.display()
        );
    }
    Ok(())
}

/// Runs the report.
pub fn run(args: &[String]) -> Result<()> {
    let mut quick = false;
    let mut only = None;
    let mut out = workspace_root().join("target/report");
    let mut it = args.iter();
    while let Some(a) = it.next() {
        match a.as_str() {
            "--quick" => quick = true,
            "--only" => {
                let v = it
                    .next()
                    .with_context(|| format!("--only needs a title's words\nusage: {USAGE}"))?;
                only = Some(v.clone());
            }
            "--out" => {
                let v = it
                    .next()
                    .with_context(|| format!("--out needs a directory\nusage: {USAGE}"))?;
                out = PathBuf::from(v);
            }
            other => bail!("report: unknown argument '{other}'\nusage: {USAGE}"),
        }
    }
    check_replaceable(&out)?;
    if let Some(parent) = out.parent().filter(|p| !p.as_os_str().is_empty()) {
        std::fs::create_dir_all(parent).with_context(|| parent.display().to_string())?;
    }
    let started = Instant::now();
    let atomic = vt_io::atomic::AtomicDir::create(&out)?;
    let dir = atomic.path().to_path_buf();
    for sub in ["plots", "images"] {
        std::fs::create_dir(dir.join(sub)).with_context(|| format!("{}/{sub}", dir.display()))?;
    }
    let mut ctx = Ctx {
        quick,
        only,
        dir: dir.clone(),
        work: tempfile::Builder::new().prefix("vt-report-").tempdir()?,
        data: data::Cache::default(),
    };
    let mut sections = Vec::new();
    let mut failed = Vec::new();
    for (id, title, intro, build) in sections::all() {
        // The curves section filters its knobs itself.
        if id != "curves" && !ctx.wants(title) {
            continue;
        }
        let t = Instant::now();
        eprintln!("report: {title}...");
        let items = match build(&mut ctx) {
            Ok(items) => items,
            Err(e) => {
                eprintln!("report: section '{title}' failed: {e:#}");
                failed.push(format!("{title}: {e:#}"));
                vec![Item::Missing {
                    title: "this section failed".into(),
                    why: format!("{e:#}"),
                }]
            }
        };
        let seconds = t.elapsed().as_secs_f64();
        eprintln!("report: {title}: {seconds:.1} s");
        sections.push(Section {
            id: id.into(),
            title: title.into(),
            intro: intro.into(),
            items,
            seconds,
        });
    }
    // Plots are drawn from the measured items, so the page and the JSON cannot disagree.
    for s in &sections {
        for item in &s.items {
            match item {
                Item::Curve(c) => plot::curve_svg(c, &dir.join(&c.plot))?,
                Item::Plot(p) => plot::lines_svg(p, &dir.join(&p.plot))?,
                _ => {}
            }
        }
    }
    let report = Report {
        format: FORMAT.into(),
        quick,
        commit: commit(),
        date: command_line("date", &["-u", "+%Y-%m-%d %H:%M:%S"]).unwrap_or_default(),
        machine: machine(),
        seconds: started.elapsed().as_secs_f64(),
        peak_rss_mib: peak_rss_mib(),
        sections,
    };
    std::fs::write(
        dir.join("report.json"),
        serde_json::to_string_pretty(&report)?,
    )?;
    std::fs::write(dir.join("index.html"), html::index_html(&report))?;
    std::fs::write(dir.join("README.md"), html::readme_md(&report))?;
    atomic.commit()?;
    println!(
        "report: {} ({:.0} s)",
        out.join("index.html").display(),
        report.seconds
    );
    if !failed.is_empty() {
        bail!("{} section(s) failed:\n{}", failed.len(), failed.join("\n"));
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn out_dir_is_replaced_only_when_it_holds_a_report() {
        let tmp = tempfile::tempdir().unwrap();
        let fresh = tmp.path().join("new");
        assert!(check_replaceable(&fresh).is_ok());
        let foreign = tmp.path().join("foreign");
        std::fs::create_dir(&foreign).unwrap();
        std::fs::write(foreign.join("thesis.tex"), "mine").unwrap();
        let err = check_replaceable(&foreign).unwrap_err().to_string();
        assert!(err.contains("not an earlier vt report"), "{err}");
        std::fs::write(
            foreign.join("report.json"),
            "{\"format\": \"something else\"}",
        )
        .unwrap();
        assert!(check_replaceable(&foreign).is_err());
        std::fs::write(
            foreign.join("report.json"),
            format!("{{\"format\": \"{FORMAT}\"}}"),
        )
        .unwrap();
        assert!(check_replaceable(&foreign).is_ok());
        let file = tmp.path().join("file");
        std::fs::write(&file, "x").unwrap();
        assert!(check_replaceable(&file).is_err());
    }
}
