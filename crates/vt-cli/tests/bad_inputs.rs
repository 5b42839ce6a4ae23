//! The bad-input catalogue (`tests/bad_inputs.txt`): every hostile or careless command in it runs
//! the real `vt` binary and must fail with the stated exit code and a one-line message naming the
//! file or flag with the numbers, without a panic, leaving nothing behind and damaging nothing
//! that existed. Also here: interruption (SIGTERM) and stale-temporary cleanup, and the viewer
//! under hostile HTTP (loopback only).

mod common;

use std::collections::BTreeMap;
use std::hash::{Hash, Hasher};
use std::io::{Read, Write};
use std::net::TcpStream;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use common::*;

fn scratch(name: &str) -> PathBuf {
    let d = PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join(format!("bad-inputs-{name}"));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

fn write(p: &Path, bytes: impl AsRef<[u8]>) {
    std::fs::write(p, bytes).unwrap_or_else(|e| panic!("{}: {e}", p.display()));
}

/// Edits a text file in place.
fn edit(p: &Path, f: impl FnOnce(String) -> String) {
    let t = std::fs::read_to_string(p).unwrap();
    write(p, f(t));
}

/// A PNG of `w x h` whose header is then patched to claim `cw x ch` (an image bomb's header).
fn png_claiming(w: u32, h: u32, cw: u32, ch: u32) -> Vec<u8> {
    let img = image::RgbImage::from_pixel(w, h, image::Rgb([9, 9, 9]));
    let mut bytes = Vec::new();
    img.write_to(
        &mut std::io::Cursor::new(&mut bytes),
        image::ImageFormat::Png,
    )
    .unwrap();
    bytes[16..20].copy_from_slice(&cw.to_be_bytes());
    bytes[20..24].copy_from_slice(&ch.to_be_bytes());
    // The IHDR CRC covers type and data (bytes 12..29).
    let crc = crc32(&bytes[12..29]);
    bytes[29..33].copy_from_slice(&crc.to_be_bytes());
    bytes
}

fn crc32(data: &[u8]) -> u32 {
    let mut crc = 0xFFFF_FFFFu32;
    for &b in data {
        crc ^= b as u32;
        for _ in 0..8 {
            crc = if crc & 1 == 1 {
                (crc >> 1) ^ 0xEDB8_8320
            } else {
                crc >> 1
            };
        }
    }
    !crc
}

fn save_png(p: &Path, w: u32, h: u32) {
    image::RgbImage::from_fn(w, h, |x, y| image::Rgb([x as u8, y as u8, 7]))
        .save(p)
        .unwrap();
}

/// The fixture folder of the catalogue (see the `$F` names in bad_inputs.txt).
fn build_fixtures(f: &Path) {
    let scene = small_scene(f);
    let tex = f.join("tex");
    let obj = f.join("obj");
    vt_ok(&[
        "synth",
        "object",
        "--out",
        s(&obj),
        "--views",
        "4",
        "--size",
        "48",
    ]);

    // A user's things.
    std::fs::create_dir(f.join("photos")).unwrap();
    write(&f.join("photos/p.jpg"), b"\xFF\xD8\xFF\xE0 a user's photo");
    write(&f.join("note.txt"), "a user's note\n");
    write(
        &f.join("user.mp4"),
        b"\0\0\0\x18ftypisom\0\0\x02\0isomiso2 a user's video",
    );
    write(&f.join("user.gif"), b"GIF89a\x01\x00\x01\x00\x80\x00\x00\xff\xff\xff\x00\x00\x00,\x00\x00\x00\x00\x01\x00\x01\x00\x00\x02\x02D\x01\x00;");
    save_png(&f.join("photo.png"), 8, 8);
    std::os::unix::fs::symlink(&scene, f.join("link")).unwrap();
    std::os::unix::fs::symlink(f.join("photos"), f.join("link_photos")).unwrap();
    let suf = f.join("scene_user_file");
    copy_dir(&scene, &suf);
    write(&suf.join("photo.jpg"), b"\xFF\xD8 mine");

    // Points files.
    let pts = std::fs::read_to_string(tex.join("points.txt")).unwrap();
    let lines: Vec<&str> = pts.lines().filter(|l| !l.starts_with('#')).collect();
    let far: Vec<String> = lines
        .iter()
        .enumerate()
        .map(|(i, l)| {
            if i != 1 {
                return l.to_string();
            }
            let mut v: Vec<&str> = l.split_whitespace().collect();
            v[4] = "5000";
            v[5] = "20";
            v.join(" ")
        })
        .collect();
    write(&f.join("points_far.txt"), far.join("\n"));
    let mut huge = "7".repeat(2_000_000);
    huge.push_str("x 1 2 3 4 5 6 7\n");
    write(&f.join("points_huge_token.txt"), huge);
    write(&f.join("points_nan.txt"), "1 2 3 4 5 6 7 nan\n");
    write(&f.join("points_3pts.txt"), "1 2 3 4 5 6\n");
    write(&f.join("points_odd.txt"), "1 2 3 4 5 6 7\n");
    write(&f.join("points_empty.txt"), "# nothing here\n");
    write(&f.join("points_binary.txt"), b"\xFF\xFE\x00\x01 1 2");
    write(
        &f.join("points_2lines.txt"),
        format!("{}\n{}\n", lines[0], lines[1]),
    );
    write(
        &f.join("points_mismatch.txt"),
        "1 2 3 4 5 6 7 8\n1 2 3 4 5 6 7 8 9 10\n1 2 3 4 5 6 7 8\n",
    );
    write(
        &f.join("points_degenerate.txt"),
        "5 5 5 5 5 5 5 5\n5 5 5 5 5 5 5 5\n5 5 5 5 5 5 5 5\n",
    );
    write(
        &f.join("points_2views.txt"),
        "1 1 20 1 20 20 1 20\n1 1 20 1 20 20 1 20\n",
    );
    write(&f.join("qs_bad.txt"), "0.5\nabc\n");
    write(&f.join("qs_out.txt"), "99\n");
    write(&f.join("qs_many.txt"), "0\n".repeat(18_001));

    // Frame folders.
    std::fs::create_dir(f.join("frames_empty")).unwrap();
    let mixed = f.join("frames_mixed");
    std::fs::create_dir(&mixed).unwrap();
    save_png(&mixed.join("frame_00000.png"), 64, 48);
    save_png(&mixed.join("frame_00001.png"), 64, 48);
    save_png(&mixed.join("frame_00002.png"), 32, 24);
    let small = f.join("frames_small");
    std::fs::create_dir(&small).unwrap();
    for i in 0..3 {
        save_png(&small.join(format!("frame_{i:05}.png")), 32, 24);
    }
    let trunc = f.join("frames_trunc");
    std::fs::create_dir(&trunc).unwrap();
    write(&trunc.join("frame_00000.png"), b"\x89PNG\r\n\x1a\n\0\0");
    let later = f.join("frames_trunc_later");
    std::fs::create_dir(&later).unwrap();
    save_png(&later.join("frame_00000.png"), 64, 48);
    let good = std::fs::read(later.join("frame_00000.png")).unwrap();
    write(&later.join("frame_00001.png"), &good[..good.len() / 2]);
    let bomb = f.join("frames_bomb");
    std::fs::create_dir(&bomb).unwrap();
    write(&bomb.join("bomb.png"), png_claiming(8, 8, 100_000, 100_000));
    write(&f.join("garbage.mp4"), [0x5Au8; 4096]);

    // Broken scenes.
    let variant = |name: &str, json: &dyn Fn(String) -> String| {
        let d = f.join(name);
        copy_dir(&scene, &d);
        edit(&d.join("scene.json"), json);
        d
    };
    variant("scene_v0", &|t| {
        t.replace("\"version\": 1", "\"version\": 0")
    });
    variant("scene_badjson", &|t| t[..t.len() / 2].to_string());
    variant("scene_notvt", &|t| {
        t.replace("\"format\": \"vt-scene\"", "\"format\": \"other\"")
    });
    variant("scene_abs", &|t| {
        t.replacen("\"background_000.png\"", "\"/etc/passwd\"", 1)
    });
    variant("scene_dotdot", &|t| {
        t.replacen("\"objects_000.bin\"", "\"../../objects_000.bin\"", 1)
    });
    variant("scene_bigdims", &|t| {
        t.replacen("\"width\": 64", "\"width\": 100000", 1)
            .replacen("\"height\": 48", "\"height\": 100000", 1)
    });
    variant("scene_bigframes", &|t| {
        t.replacen("\"frames\": 40", "\"frames\": 100000000", 1)
    });
    variant("scene_noviews", &|t| {
        let mut v: serde_json::Value = serde_json::from_str(&t).unwrap();
        v["views"] = serde_json::json!([]);
        v.to_string()
    });
    let d = variant("scene_trunc_obj", &|t| t);
    let obj1 = std::fs::read(d.join("objects_001.bin")).unwrap();
    write(&d.join("objects_001.bin"), &obj1[..obj1.len() - 7]);
    let d = variant("scene_badobj_dims", &|t| t);
    let mut obj0 = std::fs::read(d.join("objects_000.bin")).unwrap();
    obj0[8..16].copy_from_slice(&[0xFF; 8]);
    write(&d.join("objects_000.bin"), obj0);
    let d = variant("scene_bad_bg", &|t| t);
    write(&d.join("background_000.png"), b"\x89PNG\r\n\x1a\n garbage");

    // Broken System B data folders (copies of obj/ with the par file renamed after the folder).
    let par_of = |d: &Path| {
        d.join(format!(
            "{}_par.txt",
            d.file_name().unwrap().to_string_lossy()
        ))
    };
    let fv_variant = |name: &str, par: &dyn Fn(Vec<String>) -> Vec<String>| {
        let d = f.join(name);
        copy_dir(&obj, &d);
        let text = std::fs::read_to_string(d.join("object_par.txt")).unwrap();
        std::fs::remove_file(d.join("object_par.txt")).unwrap();
        let lines: Vec<String> = text.lines().map(String::from).collect();
        write(&par_of(&d), par(lines).join("\n") + "\n");
        d
    };
    fv_variant("obj_count", &|mut l| {
        l[0] = "1000000000000".into();
        l
    });
    fv_variant("obj_count_e", &|mut l| {
        l[0] = "1e12".into();
        l
    });
    fv_variant("obj_few", &|mut l| {
        l[0] = "9".into();
        l
    });
    fv_variant("obj_rot", &|mut l| {
        // Scale R of the first camera by 1.05: det 1.05^3 = 1.157625.
        let mut f: Vec<String> = l[1].split_whitespace().map(String::from).collect();
        for v in &mut f[10..19] {
            *v = (v.parse::<f64>().unwrap() * 1.05).to_string();
        }
        l[1] = f.join(" ");
        l
    });
    fv_variant("obj_dotdot", &|mut l| {
        l[1] = l[1].replacen("view_00.png", "../../view_00.png", 1);
        l
    });
    fv_variant("obj_abs", &|mut l| {
        l[1] = l[1].replacen("view_00.png", "/etc/passwd", 1);
        l
    });
    fv_variant("obj_bad_field", &|mut l| {
        let mut f: Vec<String> = l[2].split_whitespace().map(String::from).collect();
        f[5] = "abc".into();
        l[2] = f.join(" ");
        l
    });
    fv_variant("obj_short_line", &|mut l| {
        l[1] = l[1]
            .split_whitespace()
            .take(10)
            .collect::<Vec<_>>()
            .join(" ");
        l
    });
    let d = fv_variant("obj_two_par", &|l| l);
    std::fs::copy(par_of(&d), d.join("other_par.txt")).unwrap();
    let d = fv_variant("obj_no_par", &|l| l);
    std::fs::remove_file(par_of(&d)).unwrap();
    let d = fv_variant("obj_missing_img", &|l| l);
    std::fs::remove_file(d.join("view_02.png")).unwrap();
    let d = fv_variant("obj_trunc_img", &|l| l);
    let img = std::fs::read(d.join("view_01.png")).unwrap();
    write(&d.join("view_01.png"), &img[..img.len() / 3]);
    let d = fv_variant("obj_mixed", &|l| l);
    std::fs::remove_dir_all(d.join("masks")).unwrap();
    save_png(&d.join("view_01.png"), 24, 24);
}

/// Every path under `root` with its kind, size and a hash of its bytes (links not followed).
fn snapshot(root: &Path) -> BTreeMap<PathBuf, (char, u64, u64)> {
    fn walk(root: &Path, dir: &Path, out: &mut BTreeMap<PathBuf, (char, u64, u64)>) {
        for e in std::fs::read_dir(dir).unwrap() {
            let e = e.unwrap();
            let p = e.path();
            let meta = std::fs::symlink_metadata(&p).unwrap();
            let rel = p.strip_prefix(root).unwrap().to_path_buf();
            if meta.file_type().is_symlink() {
                out.insert(rel, ('l', 0, 0));
            } else if meta.is_dir() {
                out.insert(rel, ('d', 0, 0));
                walk(root, &p, out);
            } else {
                let mut h = std::collections::hash_map::DefaultHasher::new();
                std::fs::read(&p).unwrap().hash(&mut h);
                out.insert(rel, ('f', meta.len(), h.finish()));
            }
        }
    }
    let mut out = BTreeMap::new();
    walk(root, root, &mut out);
    out
}

/// Runs vt with a time limit (a case that wrongly succeeds must not hang the suite).
fn run_limited(args: &[String], limit: Duration) -> (Option<i32>, String, String) {
    let mut child = Command::new(env!("CARGO_BIN_EXE_vt"))
        .args(args)
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("run vt");
    let mut out = child.stdout.take().unwrap();
    let mut err = child.stderr.take().unwrap();
    let t_out = std::thread::spawn(move || {
        let mut s = String::new();
        let _ = out.read_to_string(&mut s);
        s
    });
    let t_err = std::thread::spawn(move || {
        let mut s = Vec::new();
        let _ = err.read_to_end(&mut s);
        String::from_utf8_lossy(&s).to_string()
    });
    let start = Instant::now();
    let code = loop {
        if let Some(st) = child.try_wait().unwrap() {
            break st.code();
        }
        if start.elapsed() > limit {
            let _ = child.kill();
            let _ = child.wait();
            break None;
        }
        std::thread::sleep(Duration::from_millis(5));
    };
    (code, t_out.join().unwrap(), t_err.join().unwrap())
}

#[test]
fn bad_input_catalogue() {
    let root = scratch("catalogue");
    let f = root.join("F");
    std::fs::create_dir(&f).unwrap();
    build_fixtures(&f);
    let work = f.join("work");
    std::fs::create_dir(&work).unwrap();
    let text = include_str!("bad_inputs.txt");
    let mut failures = Vec::new();
    let mut n = 0;
    for (i, line) in text.lines().enumerate() {
        let line = line.trim();
        if line.is_empty() || line.starts_with('#') {
            continue;
        }
        n += 1;
        let parts: Vec<&str> = line.splitn(3, " | ").collect();
        assert_eq!(
            parts.len(),
            3,
            "bad_inputs.txt:{}: not EXIT | ARGS | WANTED",
            i + 1
        );
        let want_code: i32 = parts[0].trim().parse().unwrap();
        let w = work.join(format!("case_{:03}", i + 1));
        std::fs::create_dir(&w).unwrap();
        let fill = |t: &str| t.replace("$F", s(&f)).replace("$W", s(&w));
        let args: Vec<String> = parts[1].split_whitespace().map(fill).collect();
        let wants: Vec<String> = parts[2]
            .split(';')
            .map(|x| fill(x.trim()))
            .filter(|x| !x.is_empty())
            .collect();
        let before = snapshot(&f);
        let (code, stdout, stderr) = run_limited(&args, Duration::from_secs(120));
        let after = snapshot(&f);
        let mut problems = Vec::new();
        if code != Some(want_code) {
            problems.push(format!("exit {code:?}, want {want_code}"));
        }
        if stderr.contains("panicked") || stderr.contains("RUST_BACKTRACE") {
            problems.push("panicked".into());
        }
        let lines: Vec<&str> = stderr.lines().filter(|l| !l.trim().is_empty()).collect();
        if lines.len() != 1 {
            problems.push(format!("{} lines on stderr", lines.len()));
        }
        let msg = lines.first().copied().unwrap_or("");
        if !msg.starts_with("error: ") {
            problems.push("message does not start with 'error: '".into());
        }
        if msg.len() > 400 {
            problems.push(format!("message is {} characters long", msg.len()));
        }
        let segs: Vec<&str> = msg.split(": ").collect();
        if segs.windows(2).any(|p| p[0] == p[1]) {
            problems.push("a cause is repeated".into());
        }
        for want in &wants {
            match want.strip_prefix('!') {
                Some(not) if msg.contains(not) => problems.push(format!("contains {not:?}")),
                Some(_) => {}
                None if !msg.contains(want.as_str()) => {
                    problems.push(format!("does not mention {want:?}"))
                }
                None => {}
            }
        }
        if before != after {
            let changed: Vec<String> = before
                .iter()
                .filter(|(k, v)| after.get(*k) != Some(v))
                .map(|(k, _)| format!("changed or removed {}", k.display()))
                .chain(
                    after
                        .keys()
                        .filter(|k| !before.contains_key(*k))
                        .map(|k| format!("left {}", k.display())),
                )
                .take(5)
                .collect();
            problems.push(changed.join(", "));
        }
        if !problems.is_empty() {
            failures.push(format!(
                "bad_inputs.txt:{}: vt {}\n  {}\n  stderr: {}\n  stdout: {}",
                i + 1,
                parts[1],
                problems.join("; "),
                stderr.trim().chars().take(600).collect::<String>(),
                stdout.trim().chars().take(200).collect::<String>()
            ));
        }
    }
    assert!(n >= 100, "the catalogue has {n} cases, fewer than 100");
    assert!(
        failures.is_empty(),
        "{} of {n} catalogue cases failed:\n{}",
        failures.len(),
        failures.join("\n")
    );
}

/// A small analysed scene of its own, for the tests below.
fn small_scene(root: &Path) -> PathBuf {
    let tex = root.join("tex");
    vt_ok(&[
        "synth",
        "textures",
        "--out",
        s(&tex),
        "--frames",
        "40",
        "--size",
        "64x48",
        "--period",
        "8",
    ]);
    let scene = root.join("scene");
    vt_ok(&[
        "analyze",
        s(&tex.join("view_00")),
        s(&tex.join("view_01")),
        s(&tex.join("view_02")),
        "--points",
        s(&tex.join("points.txt")),
        "--out",
        s(&scene),
        "--min-length",
        "8",
    ]);
    scene
}

fn names(dir: &Path) -> Vec<String> {
    let mut v: Vec<String> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().to_string())
        .collect();
    v.sort();
    v
}

/// Waits until `dir` holds an entry whose name contains `part`.
fn wait_for_entry(dir: &Path, part: &str, child: &mut std::process::Child) {
    let start = Instant::now();
    while !names(dir).iter().any(|n| n.contains(part)) {
        assert!(
            child.try_wait().unwrap().is_none(),
            "vt exited before writing its temporary"
        );
        assert!(
            start.elapsed() < Duration::from_secs(60),
            "no temporary appeared"
        );
        std::thread::sleep(Duration::from_millis(20));
    }
}

#[test]
fn sigterm_removes_temporaries_and_stale_ones_are_cleaned() {
    let root = scratch("signals");
    let scene = small_scene(&root);
    for out in ["long.mp4", "long_frames"] {
        let w = root.join(format!("w_{out}"));
        std::fs::create_dir(&w).unwrap();
        let mut child = Command::new(env!("CARGO_BIN_EXE_vt"))
            .args([
                "render",
                s(&scene),
                "--path",
                "sweep",
                "--duration",
                "600",
                "--out",
                s(&w.join(out)),
            ])
            .stdout(Stdio::null())
            .stderr(Stdio::piped())
            .spawn()
            .unwrap();
        wait_for_entry(&w, ".vt-tmp-", &mut child);
        std::thread::sleep(Duration::from_millis(300));
        let killed = Command::new("kill")
            .args(["-TERM", &child.id().to_string()])
            .status()
            .unwrap();
        assert!(killed.success());
        let out_put = child.wait_with_output().unwrap();
        let stderr = String::from_utf8_lossy(&out_put.stderr);
        assert_eq!(out_put.status.code(), Some(130), "{out}: {stderr}");
        assert!(stderr.contains("interrupted"), "{out}: {stderr}");
        // Nothing left, also after a moment (a killed encoder must not write on).
        std::thread::sleep(Duration::from_millis(500));
        assert!(names(&w).is_empty(), "{out}: left {:?}", names(&w));
    }

    // Temporaries of processes that no longer exist are removed by the next run beside them;
    // a live process's and a user's look-alike are not.
    let w = root.join("stale");
    std::fs::create_dir(&w).unwrap();
    std::fs::create_dir(w.join(".scene.vt-tmp-4194305")).unwrap();
    write(&w.join(".scene.vt-tmp-4194305/half.png"), b"x");
    write(&w.join(".a.mp4.vt-tmp-4194304"), b"x");
    write(&w.join(".scene.vt-old-4194303"), b"x");
    std::fs::create_dir(w.join(".scene.vt-tmp-1")).unwrap();
    write(&w.join("tmp-notes.txt"), b"mine");
    // Another program's look-alike temporary of a dead process: not vt's, so it stays.
    write(&w.join(".notes.tmp-4194302"), b"theirs");
    let out = w.join("a.mp4");
    for _ in 0..2 {
        // Twice: the second run replaces vt's own earlier output.
        vt_ok(&["render", s(&scene), "--path", "sweep", "--out", s(&out)]);
    }
    assert_eq!(
        names(&w),
        vec![
            ".notes.tmp-4194302",
            ".scene.vt-tmp-1",
            "a.mp4",
            "tmp-notes.txt"
        ],
        "stale temporaries of dead processes removed, the rest kept"
    );
    // The scene, analysed again into the same place, is replaced (it is vt's).
    let tex = root.join("tex");
    vt_ok(&[
        "analyze",
        s(&tex.join("view_00")),
        "--out",
        s(&scene),
        "--min-length",
        "8",
    ]);
    assert_eq!(
        read_json(&scene.join("scene.json"))["views"]
            .as_array()
            .unwrap()
            .len(),
        1
    );
}

/// Sends a raw request and reads the whole answer (requests say `Connection: close`).
fn http(port: u16, raw: &[u8]) -> String {
    let mut c = TcpStream::connect(("127.0.0.1", port)).unwrap();
    c.set_read_timeout(Some(Duration::from_secs(20))).unwrap();
    let _ = c.write_all(raw);
    let mut buf = Vec::new();
    let _ = c.read_to_end(&mut buf);
    String::from_utf8_lossy(&buf).to_string()
}

fn get(port: u16, target: &str) -> String {
    http(
        port,
        format!("GET {target} HTTP/1.1\r\nHost: x\r\nConnection: close\r\n\r\n").as_bytes(),
    )
}

/// Reads from an MJPEG stream until `parts` JPEG parts arrived; false on timeout.
fn stream_parts(port: u16, parts: usize, limit: Duration) -> bool {
    let mut c = TcpStream::connect(("127.0.0.1", port)).unwrap();
    c.set_read_timeout(Some(Duration::from_millis(500)))
        .unwrap();
    c.write_all(b"GET /stream.mjpg HTTP/1.1\r\nHost: x\r\n\r\n")
        .unwrap();
    let start = Instant::now();
    let mut seen = Vec::new();
    let mut buf = [0u8; 65536];
    while start.elapsed() < limit {
        if let Ok(n) = c.read(&mut buf) {
            if n == 0 {
                return false;
            }
            seen.extend_from_slice(&buf[..n]);
            let count = seen
                .windows(b"Content-Type: image/jpeg".len())
                .filter(|w| *w == b"Content-Type: image/jpeg")
                .count();
            if count >= parts {
                return true;
            }
        }
    }
    false
}

#[test]
fn viewer_survives_hostile_http() {
    let root = scratch("viewer");
    let scene = small_scene(&root);
    let mut server = Command::new(env!("CARGO_BIN_EXE_vt"))
        .args(["view", s(&scene), "--port", "0"])
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    struct Kill(std::process::Child);
    impl Drop for Kill {
        fn drop(&mut self) {
            let _ = self.0.kill();
            let _ = self.0.wait();
        }
    }
    let mut line = String::new();
    std::io::BufRead::read_line(
        &mut std::io::BufReader::new(server.stdout.take().unwrap()),
        &mut line,
    )
    .unwrap();
    let mut server = Kill(server);
    let port: u16 = line
        .split("http://127.0.0.1:")
        .nth(1)
        .and_then(|r| r.split('/').next())
        .and_then(|p| p.parse().ok())
        .unwrap_or_else(|| panic!("no URL in {line:?}"));

    // 200 idle connections held open for the whole test.
    let idle: Vec<TcpStream> = (0..200)
        .map(|_| TcpStream::connect(("127.0.0.1", port)).unwrap())
        .collect();
    // A huge declared body is refused unread; so are other methods, huge heads, many headers.
    let r = http(
        port,
        b"POST /control HTTP/1.1\r\nContent-Length: 99999999999999\r\n\r\nabc",
    );
    assert!(r.starts_with("HTTP/1.1 413"), "{r}");
    let r = http(
        port,
        b"GET / HTTP/1.1\r\nContent-Length: 99999999999999\r\n\r\n",
    );
    assert!(r.starts_with("HTTP/1.1 413"), "{r}");
    let r = http(port, b"DELETE / HTTP/1.1\r\nConnection: close\r\n\r\n");
    assert!(r.starts_with("HTTP/1.1 405"), "{r}");
    let long = format!("GET /state?{} HTTP/1.1\r\n\r\n", "a".repeat(100_000));
    assert!(http(port, long.as_bytes()).starts_with("HTTP/1.1 431"));
    let many: String = (0..100).map(|i| format!("X-{i}: y\r\n")).collect();
    let r = http(port, format!("GET / HTTP/1.1\r\n{many}\r\n").as_bytes());
    assert!(r.starts_with("HTTP/1.1 431"), "{r}");
    assert!(http(port, b"\x00\x01garbage\r\n\r\n").starts_with("HTTP/1.1 400"));
    // Absurd parameter values get 400 with the value shortened; the render thread lives on.
    for (q, want) in [
        (
            "speed=1e-300",
            "speed 1e-300 must be 0 (paused) or in [0.01, 8]",
        ),
        ("speed=NaN", "speed NaN"),
        ("speed=1e308", "speed 1e308"),
        ("q=1e400", "q inf is outside [0, 2]"),
        ("q=-1", "q -1 is outside"),
        ("zoom=2", "unknown parameter 'zoom'"),
    ] {
        let r = get(port, &format!("/control?{q}"));
        assert!(
            r.starts_with("HTTP/1.1 400") && r.contains(want),
            "{q}: {r}"
        );
    }
    let r = get(port, &format!("/control?speed={}", "x".repeat(5000)));
    assert!(
        r.starts_with("HTTP/1.1 400") && r.contains("(5000 characters)"),
        "{r}"
    );
    assert!(get(port, "/etc/passwd").starts_with("HTTP/1.1 404"));
    // The page's files come from memory, by exact name only.
    assert!(get(port, "/data/player.js").starts_with("HTTP/1.1 200"));
    for path in [
        "/data/",
        "/data/../index.html",
        "/data/%2e%2e/Cargo.toml",
        "/data/scene.js/",
    ] {
        assert!(get(port, path).starts_with("HTTP/1.1 404"), "{path}");
    }
    assert!(get(port, "/control?speed=8").starts_with("HTTP/1.1 200"));
    // The renderer still works: it renders when a frame is asked for (it idles otherwise).
    let frames = |r: String| -> u64 {
        let body = r.split("\r\n\r\n").nth(1).unwrap_or("").to_string();
        serde_json::from_str::<serde_json::Value>(&body).unwrap()["frames"]
            .as_u64()
            .unwrap()
    };
    let f0 = frames(get(port, "/state"));
    let frame = get(port, "/frame.jpg");
    assert!(
        frame.starts_with("HTTP/1.1 200") && frame.contains("image/jpeg"),
        "{}",
        &frame[..frame.len().min(200)]
    );
    let f1 = frames(get(port, "/state"));
    assert!(f1 > f0, "the renderer stopped: frames {f0} -> {f1}");
    // New streams are answered while the idle connections are held, also 30 at once.
    let streams: Vec<_> = (0..30)
        .map(|_| std::thread::spawn(move || stream_parts(port, 3, Duration::from_secs(20))))
        .collect();
    let ok = streams
        .into_iter()
        .map(|t| t.join())
        .filter(|r| matches!(r, Ok(true)))
        .count();
    assert_eq!(ok, 30, "only {ok} of 30 concurrent streams got frames");
    assert!(server.0.try_wait().unwrap().is_none(), "vt view exited");
    drop(idle);
    // Ctrl-C is how the viewer ends: "stopped", status 0, not an error.
    let sent = Command::new("kill")
        .args(["-INT", &server.0.id().to_string()])
        .status()
        .unwrap();
    assert!(sent.success());
    let mut stderr = String::new();
    std::io::Read::read_to_string(&mut server.0.stderr.take().unwrap(), &mut stderr).unwrap();
    let status = server.0.wait().unwrap();
    assert_eq!(status.code(), Some(0), "{stderr}");
    assert_eq!(stderr.trim(), "stopped", "{stderr}");
}
