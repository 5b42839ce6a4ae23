//! Helpers shared by the CLI tests: run the real `vt` binary, check its output, make scenes.
#![allow(dead_code)]

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

use serde_json::Value;

pub fn vt(args: &[&str]) -> Output {
    let out = Command::new(env!("CARGO_BIN_EXE_vt"))
        .args(args)
        .output()
        .expect("run vt");
    if std::env::var_os("VT_TEST_VERBOSE").is_some() {
        eprintln!(
            "$ vt {}\n{}{}",
            args.join(" "),
            String::from_utf8_lossy(&out.stdout),
            String::from_utf8_lossy(&out.stderr)
        );
    }
    out
}

/// Runs vt and fails with its command line and output unless it succeeds.
pub fn vt_ok(args: &[&str]) -> String {
    let out = vt(args);
    assert!(
        out.status.success(),
        "vt {} failed:\nstdout:\n{}\nstderr:\n{}",
        args.join(" "),
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
    String::from_utf8_lossy(&out.stdout).to_string()
}

/// Runs vt expecting a clean failure: non-zero exit, a one-line error containing every `want`,
/// no panic. Returns the error line.
pub fn vt_err(args: &[&str], want: &[&str]) -> String {
    let out = vt(args);
    let stderr = String::from_utf8_lossy(&out.stderr).to_string();
    assert!(
        !out.status.success(),
        "vt {} succeeded but should fail",
        args.join(" ")
    );
    assert!(
        !stderr.contains("panicked"),
        "vt {} panicked:\n{stderr}",
        args.join(" ")
    );
    let lines: Vec<&str> = stderr.lines().filter(|l| !l.trim().is_empty()).collect();
    assert_eq!(
        lines.len(),
        1,
        "vt {}: expected one error line, got:\n{stderr}",
        args.join(" ")
    );
    for w in want {
        assert!(
            lines[0].contains(w),
            "vt {}: error {:?} does not mention {w:?}",
            args.join(" "),
            lines[0]
        );
    }
    lines[0].to_string()
}

pub fn s(p: &Path) -> &str {
    p.to_str().expect("utf-8 temp path")
}

pub fn read_json(p: &Path) -> Value {
    serde_json::from_str(
        &std::fs::read_to_string(p).unwrap_or_else(|e| panic!("{}: {e}", p.display())),
    )
    .unwrap()
}

pub struct Synth {
    pub dir: PathBuf,
    pub views: Vec<String>,
}

pub fn synth(root: &Path, name: &str, extra: &[&str]) -> Synth {
    let dir = root.join(name);
    let mut args = vec!["synth", "textures", "--out", s(&dir)];
    args.extend_from_slice(extra);
    vt_ok(&args);
    let truth = read_json(&dir.join("truth.json"));
    let m = truth["phase"].as_array().unwrap().len();
    let views = (0..m)
        .map(|p| {
            dir.join(format!("view_{p:02}"))
                .to_str()
                .unwrap()
                .to_string()
        })
        .collect();
    Synth { dir, views }
}

pub fn analyze(syn: &Synth, out: &Path, extra: &[&str]) -> Value {
    let points = syn.dir.join("points.txt");
    let mut args = vec!["--points", s(&points)];
    args.extend_from_slice(extra);
    analyze_auto(syn, out, &args)
}

/// `vt analyze` of the views with `extra` flags only (no points file: automatic registration).
pub fn analyze_auto(syn: &Synth, out: &Path, extra: &[&str]) -> Value {
    let mut args = vec!["analyze"];
    args.extend(syn.views.iter().map(String::as_str));
    args.extend_from_slice(&["--out", s(out)]);
    args.extend_from_slice(extra);
    vt_ok(&args);
    read_json(&out.join("scene.json"))
}

/// The first frame a fresh player shows at `q`, rendered in-process from a loaded scene, with the
/// player's choice (view, source frame).
pub fn first_frame(
    scene: &vt_io::scene::LoadedScene,
    q: f64,
    params: vt_core::render::RenderParams,
) -> (vt_core::render::FrameChoice, image::RgbImage) {
    let mut renderer = vt_core::render::Renderer::new(scene.render.clone(), params).unwrap();
    let choice = vt_core::render::Player::new()
        .advance(&scene.render, q)
        .unwrap();
    let (w, h) = renderer.size();
    let mut out = image::RgbImage::new(w, h);
    renderer
        .render_into(&scene.objects, q, &choice, &mut out)
        .unwrap();
    (choice, out)
}

/// Copies a folder tree.
pub fn copy_dir(src: &Path, dst: &Path) {
    std::fs::create_dir_all(dst).unwrap();
    for e in std::fs::read_dir(src).unwrap() {
        let e = e.unwrap();
        let to = dst.join(e.file_name());
        if e.path().is_dir() {
            copy_dir(&e.path(), &to);
        } else {
            std::fs::copy(e.path(), &to).unwrap();
        }
    }
}

/// PNG files in `dir` (a frames folder also holds vt's `.vt-output` marker).
pub fn count_pngs(dir: &Path) -> usize {
    std::fs::read_dir(dir)
        .unwrap()
        .filter(|e| {
            e.as_ref()
                .unwrap()
                .path()
                .extension()
                .is_some_and(|x| x == "png")
        })
        .count()
}

/// Headless Chromium over the DevTools protocol (the browser tests).
pub mod cdp;

/// Runs ffmpeg quietly (overwriting, no stdin) with `args`; panics naming them when it fails.
pub fn ffmpeg(args: &[&str]) {
    let ok = std::process::Command::new("ffmpeg")
        .args(["-v", "error", "-y", "-nostdin"])
        .args(args)
        .status()
        .unwrap()
        .success();
    assert!(ok, "ffmpeg {args:?}");
}

/// The folder `vt fv hull DATA --out DIR EXTRA...` writes, built once per build of vt and per
/// argument list, then shared by every test and test binary that asks for the same model: the
/// System B tests need the same few real models (lego, temple, kettle), each tens of seconds to
/// carve. Returns the folder and the hull command's stdout. The folder lives under the target's
/// tmp dir, named by a hash of the arguments and the vt binary's size and time; it is written
/// beside and renamed into place whole, so a reader never sees half a model; folders left by
/// older builds are removed. A model from changed data is refused by vt itself (the model file
/// holds its views' fingerprints), so a stale folder fails loudly rather than passing.
pub fn shared_model(data: &Path, extra: &[&str]) -> (PathBuf, String) {
    use std::collections::HashMap;
    use std::sync::{Arc, Mutex, OnceLock};
    type Slot = Arc<OnceLock<(PathBuf, String)>>;
    static SLOTS: OnceLock<Mutex<HashMap<String, Slot>>> = OnceLock::new();
    // vt-core's word hash (the same in every test binary, unlike std's), over bytes and a
    // separator after each part.
    let hash = |parts: &[&[u8]]| -> u64 {
        let words: Vec<u64> = parts
            .iter()
            .flat_map(|p| p.iter().map(|&b| b as u64).chain([u64::MAX]))
            .collect();
        vt_core::rng::hash(&words)
    };
    let exe = std::fs::metadata(env!("CARGO_BIN_EXE_vt")).expect("the vt binary");
    let time = exe
        .modified()
        .ok()
        .and_then(|t| t.duration_since(std::time::UNIX_EPOCH).ok())
        .map_or(0, |d| d.as_nanos());
    let build = format!(
        "{:016x}",
        hash(&[&exe.len().to_le_bytes(), &time.to_le_bytes()])
    );
    let data = data.canonicalize().expect("the data folder");
    let mut parts: Vec<&[u8]> = vec![s(&data).as_bytes()];
    parts.extend(extra.iter().map(|a| a.as_bytes()));
    let key = format!("{build}-{:016x}", hash(&parts));
    let slot = SLOTS
        .get_or_init(Default::default)
        .lock()
        .unwrap()
        .entry(key.clone())
        .or_default()
        .clone();
    slot.get_or_init(|| {
        let root = PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join("fv-models");
        std::fs::create_dir_all(&root).unwrap();
        for e in std::fs::read_dir(&root).unwrap().flatten() {
            let name = e.file_name().to_string_lossy().to_string();
            // (vt's own temporary folders, `.NAME.vt-tmp-PID`, belong to builds in progress.)
            if !name.starts_with(&build) && !name.starts_with('.') {
                let _ = std::fs::remove_dir_all(e.path());
            }
        }
        let dir = root.join(&key);
        let said = dir.join("stdout.txt");
        if !said.is_file() {
            let part = root.join(format!("{key}.{}.part", std::process::id()));
            let _ = std::fs::remove_dir_all(&part);
            let mut args = vec!["fv", "hull", s(&data), "--out", s(&part)];
            args.extend_from_slice(extra);
            let out = vt_ok(&args);
            std::fs::write(part.join("stdout.txt"), out).unwrap();
            // Another test binary may have put the same model in place first: keep that one.
            if std::fs::rename(&part, &dir).is_err() {
                let _ = std::fs::remove_dir_all(&part);
            }
        }
        let out =
            std::fs::read_to_string(&said).unwrap_or_else(|e| panic!("{}: {e}", said.display()));
        (dir, out)
    })
    .clone()
}

/// The NeRF lego benchmark's 8 training views (testdata/nerf-lego holds just these), as
/// `--views` names them in the documented benchmark command.
pub const LEGO_VIEWS: &str = "r_26,r_86,r_2,r_55,r_75,r_93,r_16,r_73";
