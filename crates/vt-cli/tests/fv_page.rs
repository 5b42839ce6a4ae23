//! `vt fv export`'s page in headless Chromium (software WebGL) against `vt fv render`: the
//! real templeSparseRing and kettle photos and the NeRF lego's 8 benchmark views, a model built
//! once per scene (`vt fv hull`), the page's 8 preset views around the object read back from
//! the page and scored against `vt fv render --camera angle:DEG` (inside the render's coverage
//! where it has an alpha channel; the whole image over white for the lego, as its benchmark
//! scores); a real mouse drag turns the view. `vt fv view` serves the same page.

mod common;

use std::path::{Path, PathBuf};

use common::cdp::{chromium_webgl, decode_b64, vt_server, Page};
use common::*;

/// PSNR (dB) of `got` (RGB) against `want` (RGBA, its coverage as a soft alpha; opaque for a
/// render over a background) over the pixels inside the coverage (alpha 255: the pixel and its
/// 8 neighbours covered), and their share.
fn psnr_inside(got: &[u8], want: &image::RgbaImage) -> (f64, f64) {
    let (mut sq, mut n) = (0.0f64, 0usize);
    for (i, px) in want.pixels().enumerate() {
        if px.0[3] < 255 {
            continue;
        }
        for c in 0..3 {
            let d = got[3 * i + c] as f64 - px.0[c] as f64;
            sq += d * d;
        }
        n += 1;
    }
    let mse = sq / (3 * n.max(1)) as f64;
    (
        10.0 * (255.0f64 * 255.0 / mse.max(1e-12)).log10(),
        n as f64 / (want.width() * want.height()) as f64,
    )
}

fn open(ws: &str, url: &str) -> Page {
    let mut page = Page::open_sized(ws, url, Some((900, 900)));
    page.wait_until(
        "window.vt !== undefined && (window.vt.ready || window.vt.error !== null)",
        "the page to load",
        "document.getElementById('status').textContent",
    );
    let error = page.eval("window.vt.error");
    assert!(error.is_null(), "the page failed: {error}");
    page
}

/// The page's view `i` (0-based) read back as RGB, rows top first.
fn look(page: &mut Page, what: &str) -> (Vec<u8>, serde_json::Value) {
    let got = page.eval(&format!("window.vt.look({what})"));
    let rgb = decode_b64(got["rgb"].as_str().expect("look returns rgb"));
    (rgb, got["references"].clone())
}

/// Exports `data`'s page, scores its preset views against `vt fv render`'s, and drags; with
/// `serve`, `vt fv view`'s page must show the same picture.
fn page_matches_render(name: &str, data: &Path, extra: &[&str], root: &Path, serve: bool) {
    let data_s = data.to_str().unwrap();
    let with = |args: &[&str]| -> String { vt_ok(&[args, extra].concat()) };
    // The model as `vt fv hull DATA EXTRA` builds it, shared with the other System B tests.
    let (model_dir, _) = shared_model(data, extra);
    let model = model_dir.join("model.vtfv");
    let model_s = model.to_str().unwrap();
    let web = root.join(format!("{name}-web"));
    let out = with(&[
        "fv",
        "export",
        data_s,
        "--model",
        model_s,
        "--out",
        web.to_str().unwrap(),
    ]);
    let specs: Vec<String> = out
        .lines()
        .find_map(|l| l.split_once("`vt fv render --camera` "))
        .map(|(_, s)| s.split(", ").map(str::to_string).collect())
        .unwrap_or_else(|| panic!("no views in {out:?}"));
    assert_eq!(specs.len(), 8, "{out}");
    let Some(browser) = chromium_webgl(&root.join(format!("{name}-profile"))) else {
        eprintln!("skipped: chromium is not installed");
        return;
    };
    let mut page = open(
        &browser.ws,
        &format!("file://{}", web.join("index.html").display()),
    );
    let mut scores = Vec::new();
    for (i, spec) in specs.iter().enumerate() {
        let png = root.join(format!("{name}-{i}.png"));
        with(&[
            "fv",
            "render",
            data_s,
            "--model",
            model_s,
            "--camera",
            spec,
            "--out",
            png.to_str().unwrap(),
        ]);
        let want = image::open(&png).unwrap().to_rgba8();
        let (rgb, refs) = look(&mut page, &i.to_string());
        assert_eq!(rgb.len(), (3 * want.width() * want.height()) as usize);
        let (db, covered) = psnr_inside(&rgb, &want);
        assert!(covered > 0.01, "{name} {spec}: the render covers {covered}");
        scores.push(db);
        if std::env::var_os("VT_TEST_VERBOSE").is_some() {
            eprintln!("{name} {spec}: {db:.2} dB inside the render's coverage; photos {refs}");
        }
    }
    let ms = page.eval("window.vt.lookMs").as_f64().unwrap_or(f64::NAN);
    eprintln!(
        "{name}: page against vt fv render at 8 views: {:?} dB; a view rendered and read back in {ms:.0} ms (software WebGL)",
        scores
            .iter()
            .map(|s| (s * 10.0).round() / 10.0)
            .collect::<Vec<_>>()
    );
    for (spec, db) in specs.iter().zip(&scores) {
        assert!(
            *db >= 30.0,
            "{name} {spec}: {db:.2} dB against vt fv render"
        );
    }

    // A real drag across the picture turns the camera about the object and changes the view.
    let (first, _) = look(&mut page, "0");
    let before = page.eval("window.vt.camera()");
    page.eval("window.before = JSON.stringify(window.vt.camera()), true");
    page.drag((300.0, 300.0), (500.0, 330.0), 8);
    page.wait_until(
        "JSON.stringify(window.vt.camera()) !== window.before",
        "the drag to move the camera",
        "window.vt.camera()",
    );
    let after = page.eval("window.vt.camera()");
    let (moved, _) = look(&mut page, "window.vt.camera()");
    let changed = first.iter().zip(&moved).filter(|(a, b)| a != b).count();
    assert!(
        changed > first.len() / 20,
        "{name}: the drag changed {changed} of {} values",
        first.len()
    );
    // An orbit: the camera keeps its distance from the object's centre.
    let centre = page.eval("window.vt.centre");
    let (d0, d1) = (distance(&before, &centre), distance(&after, &centre));
    assert!(
        (d0 - d1).abs() <= 1e-6 * d0,
        "{name}: the drag moved the camera from {d0} to {d1} from the centre"
    );

    // Stepping back (the - key) brings the photos' cameras into the picture; C draws them over
    // the view on screen.
    let d_near = distance(&page.eval("window.vt.camera()"), &centre);
    for _ in 0..12 {
        page.key("-", "Minus", 189);
    }
    let d_far = distance(&page.eval("window.vt.camera()"), &centre);
    assert!(
        d_far > 2.5 * d_near,
        "{name}: - moved the camera from {d_near} to {d_far}"
    );
    let canvas = "document.getElementById('view').toDataURL()";
    let settled = "!window.vt.pending()";
    page.wait_until(settled, "the page to draw the view", "window.vt.drawn");
    let plain = page.eval(canvas);
    let drawn = page.eval("window.vt.drawn").as_u64().unwrap();
    page.key("c", "KeyC", 67);
    page.wait_until(
        &format!("window.vt.drawn > {drawn} && {settled}"),
        "the page to redraw after C",
        "window.vt.drawn",
    );
    assert!(page.eval(canvas) != plain, "{name}: C showed no cameras");

    if serve {
        // `vt fv view` serves the same page: the same picture, byte for byte.
        let args = [
            &["fv", "view", data_s, "--model", model_s, "--port", "0"],
            extra,
        ]
        .concat();
        let (_server, url) = vt_server(&args);
        // Only requests naming the server are answered (against DNS rebinding), and only the
        // page's own files by their exact names.
        let hostport = url
            .trim_start_matches("http://")
            .trim_end_matches('/')
            .to_string();
        let get = |path: &str, host: &str| -> String {
            use std::io::{Read, Write};
            let mut c = std::net::TcpStream::connect(&hostport).unwrap();
            write!(
                c,
                "GET {path} HTTP/1.1\r\nHost: {host}\r\nConnection: close\r\n\r\n"
            )
            .unwrap();
            let mut reply = String::new();
            c.read_to_string(&mut reply).ok();
            reply.lines().next().unwrap_or_default().to_string()
        };
        assert!(
            get("/", &hostport).contains(" 200 "),
            "{}",
            get("/", &hostport)
        );
        assert!(get("/", "evil.example:80").contains(" 403 "));
        assert!(get("/data/../index.html", &hostport).contains(" 404 "));
        assert!(get("/data/fv.js", &hostport).contains(" 200 "));
        let mut served = open(&browser.ws, &url);
        let (same, _) = look(&mut served, "0");
        assert!(
            same == first,
            "{name}: vt fv view's page differs from vt fv export's"
        );
    }
}

fn floats(v: &serde_json::Value) -> Vec<f64> {
    v.as_array()
        .unwrap_or_else(|| panic!("not an array: {v}"))
        .iter()
        .map(|x| x.as_f64().unwrap())
        .collect()
}

/// Distance of camera `c` ({k, r, t}) from `centre`: |C - centre| with C = -R^T t.
fn distance(c: &serde_json::Value, centre: &serde_json::Value) -> f64 {
    let (r, t, m) = (floats(&c["r"]), floats(&c["t"]), floats(centre));
    (0..3)
        .map(|i| (-(0..3).map(|k| r[3 * k + i] * t[k]).sum::<f64>() - m[i]).powi(2))
        .sum::<f64>()
        .sqrt()
}

fn testdata(name: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("../../testdata")
        .join(name)
}

#[test]
fn temple_page_matches_vt_fv_render() {
    let root = tempfile::tempdir().unwrap();
    page_matches_render(
        "temple",
        &testdata("templeSparseRing"),
        &[],
        root.path(),
        true,
    );
}

#[test]
fn kettle_page_matches_vt_fv_render() {
    let root = tempfile::tempdir().unwrap();
    page_matches_render("kettle", &testdata("kettle"), &[], root.path(), false);
}

/// The field's sparse-view setting: NeRF cameras, RGBA photos over white, 8 views.
#[test]
fn lego_page_matches_vt_fv_render() {
    let root = tempfile::tempdir().unwrap();
    let views = ["--views", LEGO_VIEWS];
    page_matches_render("lego", &testdata("nerf-lego"), &views, root.path(), false);
}
