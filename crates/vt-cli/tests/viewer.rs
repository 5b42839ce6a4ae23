//! End-to-end test of `vt view`'s fallback in a real browser: Debian's Chromium, headless with
//! WebGL off (`--disable-3d-apis`), driven over the Chrome DevTools Protocol. The WebGL page `vt view`
//! serves (export.rs tests it with WebGL) sends such a browser to the CPU-rendered MJPEG page;
//! the test checks it went there, moves the slider and the arrow keys and checks that the
//! status line reports the new viewpoint and that the picture changes (with playback paused, so
//! only the viewpoint can change it).

mod common;

use std::time::{Duration, Instant};

use common::cdp::{chromium_without_webgl, vt_server, Page};
use common::*;

fn status(page: &mut Page) -> String {
    page.eval("document.getElementById('status').textContent")
        .as_str()
        .unwrap_or("")
        .to_string()
}

/// Waits until `expr` is true, showing the status line on failure.
fn wait_for(page: &mut Page, expr: &str, what: &str) {
    page.wait_until(expr, what, "document.getElementById('status').textContent");
}

/// A hash of the picture as the page shows it (the MJPEG <img> drawn into a canvas).
fn picture(page: &mut Page) -> String {
    page.eval(
        "(() => { const img = document.getElementById('video');
           const c = document.createElement('canvas'); c.width = img.naturalWidth; c.height = img.naturalHeight;
           const g = c.getContext('2d'); g.drawImage(img, 0, 0);
           const d = g.getImageData(0, 0, c.width, c.height).data; let h = 0;
           for (let i = 0; i < d.length; i += 3) h = (Math.imul(h, 31) + d[i]) >>> 0;
           return c.width + 'x' + c.height + ':' + h; })()",
    )
    .as_str()
    .unwrap()
    .to_string()
}

#[test]
fn a_browser_without_webgl_gets_the_stream_and_the_picture_follows() {
    let tmp = tempfile::tempdir().unwrap();
    let syn = synth(
        tmp.path(),
        "scene",
        &[
            "--views", "3", "--frames", "60", "--size", "160x96", "--period", "12",
        ],
    );
    let scene = tmp.path().join("analysed");
    analyze(&syn, &scene, &["--min-length", "20"]);

    let (_server, url) = vt_server(&["view", s(&scene), "--port", "0"]);
    let browser = chromium_without_webgl(&tmp.path().join("chromium-profile"))
        .expect("chromium is installed by scripts/test-all (apt-get install chromium)");

    let mut page = Page::open(&browser.ws, &url);
    wait_for(
        &mut page,
        "location.pathname === '/mjpeg'",
        "the page to send a browser without WebGL2 to the stream",
    );
    let webgl = page.eval("!!document.createElement('canvas').getContext('webgl2')");
    assert_eq!(webgl.as_bool(), Some(false), "this browser has WebGL2");
    wait_for(
        &mut page,
        "document.getElementById('status').textContent.startsWith('q 0.00')",
        "the first status",
    );
    wait_for(
        &mut page,
        "document.getElementById('video').naturalWidth === 160",
        "the first frame",
    );
    // Pause, so only the viewpoint changes the picture.
    page.eval("(() => { const s = document.getElementById('speed'); s.value = '0'; s.dispatchEvent(new Event('input')); })()");
    wait_for(
        &mut page,
        "document.getElementById('status').textContent.includes('speed 0.00x')",
        "pause",
    );
    std::thread::sleep(Duration::from_millis(400));
    let paused = picture(&mut page);
    std::thread::sleep(Duration::from_millis(400));
    assert_eq!(
        picture(&mut page),
        paused,
        "a paused picture at a fixed viewpoint stays still"
    );

    page.eval("(() => { const q = document.getElementById('q'); q.value = '1.5'; q.dispatchEvent(new Event('input')); })()");
    wait_for(
        &mut page,
        "document.getElementById('status').textContent.startsWith('q 1.50')",
        "q 1.50 in the status",
    );
    let start = Instant::now();
    while picture(&mut page) == paused {
        assert!(
            start.elapsed() < Duration::from_secs(10),
            "the picture did not change after moving the slider"
        );
        std::thread::sleep(Duration::from_millis(100));
    }
    let status = status(&mut page);
    assert!(
        status.contains("view 2"),
        "q 1.5 shows the object from view 2 (the 0.5 tie goes right): {status}"
    );

    // Arrow keys step the viewpoint.
    page.eval("document.dispatchEvent(new KeyboardEvent('keydown', {key: 'ArrowLeft'}))");
    wait_for(
        &mut page,
        "document.getElementById('status').textContent.startsWith('q 1.45')",
        "q 1.45 after ArrowLeft",
    );
}
