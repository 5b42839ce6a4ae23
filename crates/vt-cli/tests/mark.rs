//! End-to-end test of `vt mark` in a real browser: Debian's Chromium, headless, driven over the
//! Chrome DevTools Protocol with real mouse and key events at the on-screen positions of the
//! points. It marks a synthetic scene's points, deletes one, drags the others onto their true
//! positions, saves, and checks that `vt analyze` makes the same scene from the saved file as
//! from the same coordinates written by hand. Without chromium it prints "skipped: chromium not
//! found" and passes.

mod common;

use std::path::Path;

use common::cdp::{chromium, vt_server, Page};
use common::*;
use serde_json::Value;

/// Where a canvas lies on the screen: its left and top edges and its magnification (CSS pixels
/// per image pixel, from its laid-out width).
#[derive(Clone, Copy)]
struct Canvas {
    left: f64,
    top: f64,
    scale: f64,
}

impl Canvas {
    fn of(page: &mut Page, id: &str, image_width: f64) -> Canvas {
        let r = page.eval(&format!(
            "(() => {{ const r = document.getElementById('{id}').getBoundingClientRect();
               return [r.left, r.top, r.width]; }})()"
        ));
        let f = |i: usize| r[i].as_f64().unwrap();
        Canvas {
            left: f(0),
            top: f(1),
            scale: f(2) / image_width,
        }
    }

    /// The screen position of image point `p` (pixel centres at integers).
    fn screen(&self, p: (f64, f64)) -> (f64, f64) {
        (
            self.left + (p.0 + 0.5) * self.scale,
            self.top + (p.1 + 0.5) * self.scale,
        )
    }

    /// The image point shown at screen position `s`.
    fn image(&self, s: (f64, f64)) -> (f64, f64) {
        (
            (s.0 - self.left) / self.scale - 0.5,
            (s.1 - self.top) / self.scale - 0.5,
        )
    }

    /// The nearest image coordinate that falls on a whole screen pixel.
    fn snap(&self, v: f64) -> f64 {
        ((v + 0.5) * self.scale).round() / self.scale - 0.5
    }
}

fn points(page: &mut Page) -> Vec<Vec<(f64, f64)>> {
    let v = page.eval("JSON.stringify(vtMark.points)");
    let v: Vec<Vec<[f64; 2]>> = serde_json::from_str(v.as_str().unwrap()).unwrap();
    v.into_iter()
        .map(|view| view.into_iter().map(|p| (p[0], p[1])).collect())
        .collect()
}

fn wait_idle(page: &mut Page) {
    page.wait_until(
        "!!window.vtMark && vtMark.idle()",
        "the fit after the last change",
        "document.getElementById('msg').textContent + ' | ' + document.getElementById('fit').textContent",
    );
}

/// The RMS error of pair `p` in the page's latest fit.
fn pair_rms(page: &mut Page, p: usize) -> f64 {
    page.eval(&format!("vtMark.fit.pairs[{p}].rms"))
        .as_f64()
        .unwrap_or_else(|| panic!("no fit for pair {p}"))
}

fn close(a: (f64, f64), b: (f64, f64), tol: f64) -> bool {
    (a.0 - b.0).abs() <= tol && (a.1 - b.1).abs() <= tol
}

/// scene.json without what names the inputs (the views' names).
fn scene_without_names(dir: &Path) -> Value {
    let mut v = read_json(&dir.join("scene.json"));
    for view in v["views"].as_array_mut().unwrap() {
        view.as_object_mut().unwrap().remove("name");
    }
    v
}

#[test]
fn browser_marks_drags_deletes_and_saves_points_that_analyze_reads() {
    let tmp = tempfile::tempdir().unwrap();
    let Some(browser) = chromium(&tmp.path().join("chromium-profile")) else {
        println!("skipped: chromium not found");
        return;
    };
    let syn = synth(
        tmp.path(),
        "tex",
        &["--views", "3", "--frames", "40", "--size", "160x96"],
    );
    let truth = vt_io::points::read_points(&syn.dir.join("points.txt")).unwrap();
    let (m, k) = (truth.len(), truth[0].len());
    let out = tmp.path().join("marked.txt");
    let mut args = vec!["mark"];
    args.extend(syn.views.iter().map(String::as_str));
    args.extend(["--out", s(&out), "--port", "0"]);
    let (_server, url) = vt_server(&args);

    let mut page = Page::open_sized(&browser.ws, &url, Some((1400, 900)));
    wait_idle(&mut page);
    assert_eq!(points(&mut page), vec![Vec::new(); m], "no points to start");
    let left = Canvas::of(&mut page, "left", 160.0);
    let right = Canvas::of(&mut page, "right", 160.0);
    assert!(left.scale >= 1.0, "the 160x96 views are magnified");
    // The true points, on the screen's pixel grid.
    let want: Vec<Vec<(f64, f64)>> = truth
        .iter()
        .map(|v| v.iter().map(|p| (left.snap(p.x), left.snap(p.y))).collect())
        .collect();

    // Clicks on empty spots of the left view (view 0) add a point to every view.
    for (i, &p) in want[0].iter().enumerate() {
        let (x, y) = left.screen(p);
        page.click(x, y);
        wait_idle(&mut page);
        let now = points(&mut page);
        assert!(now.iter().all(|v| v.len() == i + 1), "{now:?}");
        assert!(
            close(now[0][i], p, 1e-9),
            "added at {:?}, want {p:?}",
            now[0][i]
        );
    }
    // Every view holds the same points: pair 0 fits exactly.
    assert!(pair_rms(&mut page, 0) < 1e-6);

    // Another point, selected as it is added, then removed from every view by the Delete key.
    let (x, y) = left.screen((20.0, 85.0));
    page.click(x, y);
    wait_idle(&mut page);
    assert!(points(&mut page).iter().all(|v| v.len() == k + 1));
    page.key("Delete", "Delete", 46);
    wait_idle(&mut page);
    let now = points(&mut page);
    assert!(
        now.iter().all(|v| v.len() == k),
        "Delete removed the point: {now:?}"
    );
    assert!(now[0]
        .iter()
        .zip(&want[0])
        .all(|(a, b)| close(*a, *b, 1e-9)));

    // Drag view 1's points (the right view of pair 0) onto their true positions. The first drag
    // alone leaves a misfit the page reports; the point lands where it was dropped.
    let mut dropped = (0.0, 0.0);
    for i in 0..k {
        let from = right.screen(points(&mut page)[1][i]);
        let to = right.screen(want[1][i]);
        page.drag(from, to, 5);
        wait_idle(&mut page);
        if i == 0 {
            dropped = right.image(to);
            let at = points(&mut page)[1][0];
            assert!(
                close(at, dropped, 1.0),
                "dragged to {at:?}, dropped at {dropped:?}"
            );
            let rms = pair_rms(&mut page, 0);
            assert!(rms > 0.1, "one point moved: the fit shows it (rms {rms})");
        }
    }
    // The next pair, by a real click on its button; then view 2's points.
    let next = page.eval(
        "(() => { const r = document.getElementById('next').getBoundingClientRect();
           return [r.left + r.width / 2, r.top + r.height / 2]; })()",
    );
    page.click(next[0].as_f64().unwrap(), next[1].as_f64().unwrap());
    page.wait_until("vtMark.pair === 1", "pair 1", "vtMark.pair");
    for i in 0..k {
        let from = right.screen(points(&mut page)[2][i]);
        page.drag(from, right.screen(want[2][i]), 5);
        wait_idle(&mut page);
    }
    for p in 0..m - 1 {
        let rms = pair_rms(&mut page, p);
        assert!(rms < 0.5, "pair {p}: true points fit (rms {rms})");
    }

    // Save, by a real click on the button.
    let save = page.eval(
        "(() => { const r = document.getElementById('save').getBoundingClientRect();
           return [r.left + r.width / 2, r.top + r.height / 2]; })()",
    );
    page.click(save[0].as_f64().unwrap(), save[1].as_f64().unwrap());
    page.wait_until(
        "document.getElementById('saved').textContent.startsWith('saved')",
        "the save",
        "document.getElementById('saved').textContent",
    );
    let text = std::fs::read_to_string(&out).unwrap();
    assert!(text.starts_with(vt_io::points::OUTPUT_MARKER), "{text}");
    let saved = vt_io::points::read_for_views(&out, m, (160, 96)).unwrap();
    assert!(saved.iter().all(|v| v.len() == k), "{saved:?}");
    for (p, (got, want)) in saved.iter().zip(&want).enumerate() {
        for (i, (g, w)) in got.iter().zip(want).enumerate() {
            assert!(
                close((g.x, g.y), *w, 1e-3),
                "view {p} point {i}: {g:?}, want {w:?}"
            );
        }
    }
    let moved = (saved[1][0].x, saved[1][0].y);
    assert!(
        close(moved, dropped, 1.0),
        "the dragged point was saved at {moved:?}, dropped at {dropped:?}"
    );

    // The same coordinates written by hand make the same scene.
    let hand = tmp.path().join("hand.txt");
    let mut lines = String::from("# written by hand\n");
    for v in &want {
        let pairs: Vec<String> = v.iter().map(|p| format!("{:.3},{:.3}", p.0, p.1)).collect();
        lines.push_str(&pairs.join("   "));
        lines.push('\n');
    }
    std::fs::write(&hand, lines).unwrap();
    let (a, b) = (
        tmp.path().join("scene_marked"),
        tmp.path().join("scene_hand"),
    );
    for (points, scene) in [(&out, &a), (&hand, &b)] {
        let mut args = vec!["analyze"];
        args.extend(syn.views.iter().map(String::as_str));
        args.extend([
            "--points",
            s(points),
            "--out",
            s(scene),
            "--min-length",
            "10",
        ]);
        vt_ok(&args);
    }
    let (sa, sb) = (scene_without_names(&a), scene_without_names(&b));
    for (p, (va, vb)) in sa["views"]
        .as_array()
        .unwrap()
        .iter()
        .zip(sb["views"].as_array().unwrap())
        .enumerate()
    {
        for field in ["points", "loop"] {
            assert_eq!(va[field], vb[field], "view {p} {field}");
        }
        assert_eq!(
            va["to_next"]["homography"], vb["to_next"]["homography"],
            "view {p} H"
        );
    }
    assert_eq!(sa, sb, "the two scenes differ beyond the views' names");
}

/// One request on its own connection; returns the status line's code and the body.
fn http(port: u16, method: &str, target: &str, body: &str) -> (u16, String) {
    use std::io::{Read, Write};
    let mut c = std::net::TcpStream::connect(("127.0.0.1", port)).unwrap();
    c.set_read_timeout(Some(std::time::Duration::from_secs(30)))
        .unwrap();
    let head = format!(
        "{method} {target} HTTP/1.1\r\nHost: 127.0.0.1:{port}\r\nConnection: close\r\n\
         Content-Type: application/json\r\nContent-Length: {}\r\n\r\n",
        body.len()
    );
    let _ = c.write_all(head.as_bytes());
    let _ = c.write_all(body.as_bytes());
    let mut buf = Vec::new();
    let _ = c.read_to_end(&mut buf);
    let text = String::from_utf8_lossy(&buf).to_string();
    let code = text
        .split_whitespace()
        .nth(1)
        .and_then(|c| c.parse().ok())
        .unwrap_or(0);
    let body = text.split_once("\r\n\r\n").map_or("", |(_, b)| b);
    (code, body.to_string())
}

fn port_of(url: &str) -> u16 {
    url.trim_start_matches("http://127.0.0.1:")
        .trim_end_matches('/')
        .parse()
        .unwrap()
}

#[test]
fn scene_points_start_file_routes_and_saving_rules() {
    let tmp = tempfile::tempdir().unwrap();
    let syn = synth(
        tmp.path(),
        "tex",
        &[
            "--views", "3", "--frames", "40", "--size", "64x48", "--period", "8",
        ],
    );
    let scene = tmp.path().join("scene");
    let sj = analyze(&syn, &scene, &["--min-length", "8"]);
    let out = tmp.path().join("fixed.txt");

    // A scene directory: its backgrounds and points.
    let (server, url) = vt_server(&["mark", s(&scene), "--out", s(&out), "--port", "0"]);
    let port = port_of(&url);
    let (code, state) = http(port, "GET", "/state", "");
    assert_eq!(code, 200, "{state}");
    let state: Value = serde_json::from_str(&state).unwrap();
    assert_eq!(
        (state["width"].as_u64(), state["height"].as_u64()),
        (Some(64), Some(48))
    );
    let scene_points: Vec<Value> = sj["views"]
        .as_array()
        .unwrap()
        .iter()
        .map(|v| v["points"].clone())
        .collect();
    assert_eq!(state["points"], Value::Array(scene_points.clone()));
    let (code, png) = http(port, "GET", "/background/2", "");
    assert_eq!(code, 404, "{png}");
    for (method, target, want) in [
        ("GET", "/background/0.png", 200),
        ("GET", "/background/3.png", 404),
        ("GET", "/background/../scene.json", 404),
        ("GET", "/scene.json", 404),
        ("GET", "/save", 405),
        ("POST", "/state", 405),
        ("DELETE", "/", 405),
    ] {
        assert_eq!(http(port, method, target, "").0, want, "{method} {target}");
    }
    // Fits of the scene's own points; bodies that do not fit the scene are refused.
    let body = serde_json::json!({ "points": scene_points }).to_string();
    let (code, fit) = http(port, "POST", "/fit", &body);
    assert_eq!(code, 200, "{fit}");
    let fit: Value = serde_json::from_str(&fit).unwrap();
    assert_eq!(fit["pairs"].as_array().unwrap().len(), 2);
    assert!(fit["pairs"][0]["rms"].as_f64().unwrap() < 1.0, "{fit}");
    assert!(fit["model"]["model"].is_string(), "{fit}");
    for (bad, want) in [
        ("{\"points\": [[], []]}", "2 lists of points for 3 views"),
        ("{\"points\": [[[1, 2]], [], []]}", "view 1 has 0 points"),
        ("not json", "expected"),
    ] {
        let (code, msg) = http(port, "POST", "/fit", bad);
        assert!(code == 400 && msg.contains(want), "{bad}: {code} {msg}");
    }
    // Huge bodies are refused unread; other sites' pages (a foreign Host, as after DNS
    // rebinding, or a POST without the JSON type, as a cross-site form sends) are refused.
    let raw = |request: String| {
        let mut c = std::net::TcpStream::connect(("127.0.0.1", port)).unwrap();
        std::io::Write::write_all(&mut c, request.as_bytes()).unwrap();
        let mut answer = String::new();
        let _ = std::io::Read::read_to_string(&mut c, &mut answer);
        answer
    };
    let host = format!("Host: 127.0.0.1:{port}\r\nConnection: close");
    for (request, want) in [
        (
            format!("POST /fit HTTP/1.1\r\n{host}\r\nContent-Length: 99999999999\r\n\r\n"),
            "HTTP/1.1 413",
        ),
        (
            "GET /state HTTP/1.1\r\nHost: evil.example:80\r\nConnection: close\r\n\r\n".into(),
            "HTTP/1.1 403",
        ),
        (
            format!(
                "POST /save HTTP/1.1\r\n{host}\r\nContent-Type: text/plain\r\n\
                 Content-Length: {}\r\n\r\n{body}",
                body.len()
            ),
            "HTTP/1.1 415",
        ),
    ] {
        let answer = raw(request);
        assert!(answer.starts_with(want), "{want}: {answer}");
    }
    assert!(!out.exists(), "nothing saved by refused requests");
    // Saving writes the file, and again replaces vt's own file.
    for _ in 0..2 {
        let (code, msg) = http(port, "POST", "/save", &body);
        assert_eq!(code, 200, "{msg}");
    }
    let saved = vt_io::points::read_points(&out).unwrap();
    assert_eq!(saved.len(), 3);
    // A user's file at the path is never replaced.
    std::fs::write(&out, "my notes\n").unwrap();
    let (code, msg) = http(port, "POST", "/save", &body);
    assert!(
        code == 409 && msg.contains("not a vt points output"),
        "{code} {msg}"
    );
    assert_eq!(std::fs::read_to_string(&out).unwrap(), "my notes\n");
    // Fewer than 4 points cannot be saved.
    let three = serde_json::json!({ "points": vec![[[1, 1], [5, 1], [5, 5]]; 3] }).to_string();
    let (code, msg) = http(port, "POST", "/save", &three);
    assert!(code == 409 && msg.contains("at least 4"), "{code} {msg}");
    drop(server);

    // A points file given with --points replaces the scene's.
    std::fs::remove_file(&out).unwrap();
    let start = syn.dir.join("points.txt");
    let (_server, url) = vt_server(&[
        "mark",
        s(&scene),
        "--points",
        s(&start),
        "--out",
        s(&out),
        "--port",
        "0",
    ]);
    let (_, state) = http(port_of(&url), "GET", "/state", "");
    let state: Value = serde_json::from_str(&state).unwrap();
    let want = vt_io::points::read_points(&start).unwrap();
    let got = state["points"].as_array().unwrap();
    for (g, w) in got.iter().zip(&want) {
        let g: Vec<[f64; 2]> = serde_json::from_value(g.clone()).unwrap();
        let w: Vec<[f64; 2]> = w.iter().map(|p| [p.x, p.y]).collect();
        assert_eq!(g, w);
    }
}
