//! End-to-end test of `vt view` in a real browser: Debian's Chromium, headless, driven over the
//! Chrome DevTools Protocol. It moves the slider and the arrow keys and checks that the status
//! line reports the new viewpoint and that the picture changes (with playback paused, so only
//! the viewpoint can change it).

mod common;

use std::io::{BufRead, BufReader};
use std::net::TcpStream;
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

use common::*;
use serde_json::{json, Value};
use tungstenite::{stream::MaybeTlsStream, Message, WebSocket};

struct Kill(Child);
impl Drop for Kill {
    fn drop(&mut self) {
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

/// A CDP connection to one page (flat session mode).
struct Page {
    ws: WebSocket<MaybeTlsStream<TcpStream>>,
    session: String,
    id: u64,
}

fn call(
    ws: &mut WebSocket<MaybeTlsStream<TcpStream>>,
    id: u64,
    session: Option<&str>,
    method: &str,
    params: Value,
) -> Value {
    let mut msg = json!({"id": id, "method": method, "params": params});
    if let Some(s) = session {
        msg["sessionId"] = json!(s);
    }
    ws.send(Message::text(msg.to_string()))
        .expect("send to chromium");
    loop {
        let m = ws.read().expect("read from chromium");
        if let Message::Text(t) = m {
            let v: Value = serde_json::from_str(&t).unwrap();
            if v["id"] == json!(id) {
                assert!(v.get("error").is_none(), "{method}: {v}");
                return v["result"].clone();
            }
        }
    }
}

impl Page {
    fn open(browser_ws: &str, url: &str) -> Page {
        let (mut ws, _) = tungstenite::connect(browser_ws).expect("connect to chromium");
        let target = call(&mut ws, 1, None, "Target.createTarget", json!({"url": url}));
        let attached = call(
            &mut ws,
            2,
            None,
            "Target.attachToTarget",
            json!({"targetId": target["targetId"], "flatten": true}),
        );
        Page {
            ws,
            session: attached["sessionId"].as_str().unwrap().to_string(),
            id: 10,
        }
    }

    fn eval(&mut self, expr: &str) -> Value {
        self.id += 1;
        let params = json!({"expression": expr, "returnByValue": true, "awaitPromise": true});
        let r = call(
            &mut self.ws,
            self.id,
            Some(&self.session.clone()),
            "Runtime.evaluate",
            params,
        );
        r["result"]["value"].clone()
    }

    fn wait_for(&mut self, expr: &str, what: &str) -> Value {
        let start = Instant::now();
        loop {
            let v = self.eval(expr);
            if v.as_bool() == Some(true) {
                return v;
            }
            assert!(
                start.elapsed() < Duration::from_secs(20),
                "timed out waiting for {what}; status: {}",
                self.status()
            );
            std::thread::sleep(Duration::from_millis(100));
        }
    }

    fn status(&mut self) -> String {
        self.eval("document.getElementById('status').textContent")
            .as_str()
            .unwrap_or("")
            .to_string()
    }

    /// A hash of the picture as the page shows it (the MJPEG <img> drawn into a canvas).
    fn picture(&mut self) -> String {
        self.eval(
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
}

#[test]
fn browser_moves_the_viewpoint_and_the_picture_follows() {
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

    let mut server = Kill(
        Command::new(env!("CARGO_BIN_EXE_vt"))
            .args(["view", s(&scene), "--port", "0"])
            .stdout(Stdio::piped())
            .spawn()
            .unwrap(),
    );
    let mut line = String::new();
    BufReader::new(server.0.stdout.take().unwrap())
        .read_line(&mut line)
        .unwrap();
    let url = line
        .split_whitespace()
        .find(|w| w.starts_with("http://127.0.0.1:"))
        .unwrap_or_else(|| panic!("no URL in {line:?}"));
    let url = url.to_string();

    let profile = tmp.path().join("chromium-profile");
    let chromium = Command::new("chromium")
        .args([
            "--headless",
            "--no-sandbox",
            "--disable-gpu",
            "--disable-quic",
            "--no-first-run",
            "--disable-background-networking",
            "--disable-component-update",
            "--disable-sync",
            "--remote-debugging-port=0",
        ])
        .arg(format!("--user-data-dir={}", profile.display()))
        .arg("about:blank")
        .stderr(Stdio::piped())
        .stdout(Stdio::null())
        .spawn()
        .expect("chromium is installed by scripts/test-all (apt-get install chromium)");
    let mut chromium = Kill(chromium);
    let stderr = BufReader::new(chromium.0.stderr.take().unwrap());
    let (tx, rx) = std::sync::mpsc::channel();
    std::thread::spawn(move || {
        for l in stderr.lines().map_while(Result::ok) {
            if let Some(i) = l.find("ws://") {
                let _ = tx.send(l[i..].trim().to_string());
            }
        }
    });
    let browser_ws = rx
        .recv_timeout(Duration::from_secs(30))
        .expect("chromium printed its DevTools URL");

    let mut page = Page::open(&browser_ws, &url);
    page.wait_for(
        "document.getElementById('status').textContent.startsWith('q 0.00')",
        "the first status",
    );
    page.wait_for(
        "document.getElementById('video').naturalWidth === 160",
        "the first frame",
    );
    // Pause, so only the viewpoint changes the picture.
    page.eval("(() => { const s = document.getElementById('speed'); s.value = '0'; s.dispatchEvent(new Event('input')); })()");
    page.wait_for(
        "document.getElementById('status').textContent.includes('speed 0.00x')",
        "pause",
    );
    std::thread::sleep(Duration::from_millis(400));
    let paused = page.picture();
    std::thread::sleep(Duration::from_millis(400));
    assert_eq!(
        page.picture(),
        paused,
        "a paused picture at a fixed viewpoint stays still"
    );

    page.eval("(() => { const q = document.getElementById('q'); q.value = '1.5'; q.dispatchEvent(new Event('input')); })()");
    page.wait_for(
        "document.getElementById('status').textContent.startsWith('q 1.50')",
        "q 1.50 in the status",
    );
    let start = Instant::now();
    while page.picture() == paused {
        assert!(
            start.elapsed() < Duration::from_secs(10),
            "the picture did not change after moving the slider"
        );
        std::thread::sleep(Duration::from_millis(100));
    }
    let status = page.status();
    assert!(
        status.contains("view 2"),
        "q 1.5 shows the object from view 2 (the 0.5 tie goes right): {status}"
    );

    // Arrow keys step the viewpoint.
    page.eval("document.dispatchEvent(new KeyboardEvent('keydown', {key: 'ArrowLeft'}))");
    page.wait_for(
        "document.getElementById('status').textContent.startsWith('q 1.45')",
        "q 1.45 after ArrowLeft",
    );
}
