//! The README's "Your own footage" and "Your own photos" commands, run as written on the shipped test data: tree.avi as
//! the one-camera clip, three views made from it by `vt synth real` as the cameras on a line, and
//! the kettle's COLMAP folder as the photos, testdata/nerf-lego as the NeRF folder. Where vt refuses a clip as too short and says which
//! `--min-length` to pass, the command is run again with that advice, as the README tells a user
//! to. `vt view` and `vt mark` serve pages until stopped and are left out (the viewer tests run
//! them).

mod common;

use std::path::Path;
use std::process::Command;

/// The shell lines of the README section `title`'s ```sh blocks, comments removed.
fn commands(readme: &str, title: &str) -> Vec<Vec<String>> {
    let start = readme.find(title).expect("section present");
    let rest = &readme[start + title.len()..];
    let section = &rest[..rest.find("\n## ").unwrap_or(rest.len())];
    let mut out = Vec::new();
    let mut inside = false;
    for line in section.lines() {
        if line.trim_start().starts_with("```") {
            inside = !inside && line.trim() == "```sh";
            continue;
        }
        if inside {
            let code = line.split(" #").next().unwrap_or("").trim();
            if !code.is_empty() {
                out.push(code.split_whitespace().map(str::to_string).collect());
            }
        }
    }
    out
}

/// Runs `vt ARGS` in `dir`: (success, stdout, stderr).
fn run(dir: &Path, args: &[String]) -> (bool, String, String) {
    let out = Command::new(env!("CARGO_BIN_EXE_vt"))
        .args(args)
        .current_dir(dir)
        .output()
        .expect("run vt");
    (
        out.status.success(),
        String::from_utf8_lossy(&out.stdout).into(),
        String::from_utf8_lossy(&out.stderr).into(),
    )
}

#[test]
fn your_own_footage_commands_work_as_written() {
    if !vt_io::video::ffmpeg_available() {
        eprintln!("skipped: the README's commands read and write videos through ffmpeg, which is not installed");
        return;
    }
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("../..");
    let readme = std::fs::read_to_string(root.join("README.md")).unwrap();
    let mut cmds = commands(&readme, "## Your own footage");
    cmds.extend(commands(&readme, "## Your own photos"));
    assert!(cmds.len() >= 9, "found {} commands", cmds.len());

    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path();
    let testdata = root.join("testdata");
    std::fs::copy(testdata.join("tree.avi"), dir.join("clip.mp4")).unwrap();
    let views = dir.join("views");
    common::vt_ok(&[
        "synth",
        "real",
        common::s(&testdata.join("tree.avi")),
        "--views",
        "3",
        "--frames",
        "90",
        "--usable",
        "54",
        "--out",
        common::s(&views),
    ]);
    for (i, name) in ["left", "middle", "right"].iter().enumerate() {
        std::fs::rename(
            views.join(format!("view_{i:02}.mp4")),
            dir.join(format!("{name}.mp4")),
        )
        .unwrap();
    }
    common::copy_dir(&testdata.join("kettle"), &dir.join("photos"));
    // The NeRF synthetic lego folder (testdata keeps the benchmark's 8 training views).
    common::copy_dir(&testdata.join("nerf-lego"), &dir.join("lego"));

    let mut ran = Vec::new();
    for args in &cmds {
        assert_eq!(args[0], "vt", "{args:?}");
        let args = &args[1..];
        if matches!(args[0].as_str(), "view" | "mark") {
            continue;
        }
        let (ok, stdout, stderr) = run(dir, args);
        let (ok, stdout, stderr) = match (ok, stderr.split("pass --min-length ").nth(1)) {
            // The advice vt gives for a short clip, taken.
            (false, Some(hint)) => {
                let k = hint.split_whitespace().next().unwrap().to_string();
                let mut again = args.to_vec();
                again.extend(["--min-length".to_string(), k]);
                run(dir, &again)
            }
            _ => (ok, stdout, stderr),
        };
        assert!(ok, "vt {} failed:\n{stdout}\n{stderr}", args.join(" "));
        ran.push(args[0].clone());
    }
    // What the commands promise is there.
    for f in [
        "scene/scene.json",
        "loop.mp4",
        "sweep.mp4",
        "page/index.html",
        "model/model.vtfv",
        "view.png",
        "orbit.mp4",
    ] {
        assert!(dir.join(f).exists(), "{f} missing after {ran:?}");
    }
    let view = image::open(dir.join("view.png")).unwrap();
    assert!(view.width() > 0);
}
