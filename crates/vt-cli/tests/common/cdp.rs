//! Headless Chromium (Debian's `chromium`) driven over the Chrome DevTools Protocol, and `vt`
//! servers that print their URL: what the browser tests (`viewer.rs`, `mark.rs`) share.

use std::io::{BufRead, BufReader};
use std::net::TcpStream;
use std::path::Path;
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

use serde_json::{json, Value};
use tungstenite::{stream::MaybeTlsStream, Message, WebSocket};

/// A child process killed (and reaped) when dropped.
pub struct Kill(pub Child);
impl Drop for Kill {
    fn drop(&mut self) {
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

/// Starts `vt ARGS` as a server and returns it with the `http://127.0.0.1:PORT/` URL from the
/// first line it prints.
pub fn vt_server(args: &[&str]) -> (Kill, String) {
    let mut server = Kill(
        Command::new(env!("CARGO_BIN_EXE_vt"))
            .args(args)
            .stdout(Stdio::piped())
            .spawn()
            .unwrap(),
    );
    // The line is read on a thread of its own so that a server that never prints it fails the
    // test within CALL_DEADLINE instead of hanging the run.
    let stdout = server.0.stdout.take().unwrap();
    let (send, recv) = std::sync::mpsc::channel();
    std::thread::spawn(move || {
        let mut line = String::new();
        let _ = BufReader::new(stdout).read_line(&mut line);
        let _ = send.send(line);
    });
    let line = recv.recv_timeout(CALL_DEADLINE).unwrap_or_else(|_| {
        panic!(
            "vt {}: no line printed within {} s",
            args.join(" "),
            CALL_DEADLINE.as_secs()
        )
    });
    let url = line
        .split_whitespace()
        .find(|w| w.starts_with("http://127.0.0.1:"))
        .unwrap_or_else(|| panic!("vt {}: no URL in {line:?}", args.join(" ")))
        .to_string();
    (server, url)
}

/// A running headless Chromium and its DevTools WebSocket URL.
pub struct Chromium {
    // Dropped in this order: the browser is gone before the next test's may start.
    _child: Kill,
    _turn: std::sync::MutexGuard<'static, ()>,
    pub ws: String,
}

/// One browser at a time in a test process: two software-WebGL browsers side by side on a
/// small machine only contend for its cores and memory.
static TURN: std::sync::Mutex<()> = std::sync::Mutex::new(());

/// Starts headless Chromium with its profile in `profile`; None when `chromium` is not
/// installed.
pub fn chromium(profile: &Path) -> Option<Chromium> {
    chromium_with(profile, &["--headless", "--disable-gpu", "--disable-quic"])
}

/// Headless Chromium without WebGL (`--disable-3d-apis`): a browser the WebGL page cannot
/// serve.
pub fn chromium_without_webgl(profile: &Path) -> Option<Chromium> {
    chromium_with(
        profile,
        &[
            "--headless",
            "--disable-gpu",
            "--disable-3d-apis",
            "--disable-quic",
        ],
    )
}

/// Headless Chromium with software WebGL2 (SwiftShader), for pages that draw with WebGL.
pub fn chromium_webgl(profile: &Path) -> Option<Chromium> {
    chromium_with(
        profile,
        &[
            "--headless=new",
            "--use-angle=swiftshader",
            "--enable-unsafe-swiftshader",
        ],
    )
}

/// Starts Chromium with `flags` beside the ones every test uses (no sandbox, first run,
/// background networking, updates or sync; DevTools on a free port).
fn chromium_with(profile: &Path, flags: &[&str]) -> Option<Chromium> {
    // A test that failed holding the turn poisons it; the next one may still go.
    let turn = TURN.lock().unwrap_or_else(|e| e.into_inner());
    let spawned = Command::new("chromium")
        .args(flags)
        .args([
            "--no-sandbox",
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
        .spawn();
    let mut child = match spawned {
        Ok(c) => Kill(c),
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => return None,
        Err(e) => panic!("cannot start chromium: {e}"),
    };
    let stderr = BufReader::new(child.0.stderr.take().unwrap());
    let (tx, rx) = std::sync::mpsc::channel();
    std::thread::spawn(move || {
        for l in stderr.lines().map_while(Result::ok) {
            if let Some(i) = l.find("ws://") {
                let _ = tx.send(l[i..].trim().to_string());
            }
        }
    });
    let ws = rx
        .recv_timeout(Duration::from_secs(30))
        .expect("chromium printed its DevTools URL");
    Some(Chromium {
        _child: child,
        _turn: turn,
        ws,
    })
}

/// A CDP connection to one page (flat session mode).
pub struct Page {
    ws: WebSocket<MaybeTlsStream<TcpStream>>,
    session: String,
    id: u64,
}

/// How long one DevTools call may take before the test fails (a page whose promise never
/// settles, or a browser that stopped answering, must fail the test, not hang it).
const CALL_DEADLINE: Duration = Duration::from_secs(300);

fn call(
    ws: &mut WebSocket<MaybeTlsStream<TcpStream>>,
    id: u64,
    session: Option<&str>,
    method: &str,
    params: Value,
) -> Value {
    try_call(ws, id, session, method, params).unwrap_or_else(|v| panic!("{method}: {v}"))
}

/// `call`, with the error Chromium answered (its whole reply) as `Err`.
fn try_call(
    ws: &mut WebSocket<MaybeTlsStream<TcpStream>>,
    id: u64,
    session: Option<&str>,
    method: &str,
    params: Value,
) -> Result<Value, Value> {
    let mut msg = json!({"id": id, "method": method, "params": params});
    if let Some(s) = session {
        msg["sessionId"] = json!(s);
    }
    ws.send(Message::text(msg.to_string()))
        .expect("send to chromium");
    let start = Instant::now();
    loop {
        let m = match ws.read() {
            Ok(m) => m,
            Err(tungstenite::Error::Io(e))
                if matches!(
                    e.kind(),
                    std::io::ErrorKind::WouldBlock | std::io::ErrorKind::TimedOut
                ) =>
            {
                assert!(
                    start.elapsed() < CALL_DEADLINE,
                    "chromium did not answer {method} within {} s",
                    CALL_DEADLINE.as_secs()
                );
                continue;
            }
            Err(e) => panic!("read from chromium during {method}: {e}"),
        };
        if let Message::Text(t) = m {
            let v: Value = serde_json::from_str(&t).unwrap();
            if v["id"] == json!(id) {
                if v.get("error").is_some() {
                    return Err(v);
                }
                return Ok(v["result"].clone());
            }
            // A page that crashed or went away never answers: say so instead of waiting.
            let event = v["method"].as_str().unwrap_or("");
            let ours = session.is_some() && v["sessionId"].as_str() == session;
            let detached = event == "Target.detachedFromTarget"
                && session.is_some()
                && v["params"]["sessionId"].as_str() == session;
            assert!(
                !(detached || ours && event == "Inspector.targetCrashed"),
                "the page crashed or closed during {method}: {v}"
            );
        }
    }
}

impl Page {
    /// Opens `url` in a new page.
    pub fn open(browser_ws: &str, url: &str) -> Page {
        Self::open_sized(browser_ws, url, None)
    }

    /// Opens `url` in a new page whose viewport is `size` CSS pixels (device scale 1).
    pub fn open_sized(browser_ws: &str, url: &str, size: Option<(u32, u32)>) -> Page {
        let (mut ws, _) = tungstenite::connect(browser_ws).expect("connect to chromium");
        // Reads wake every 5 s, so a call can check its deadline.
        if let MaybeTlsStream::Plain(tcp) = ws.get_mut() {
            tcp.set_read_timeout(Some(Duration::from_secs(5)))
                .expect("a read timeout on the DevTools socket");
        }
        let first = if size.is_some() { "about:blank" } else { url };
        let target = call(
            &mut ws,
            1,
            None,
            "Target.createTarget",
            json!({"url": first}),
        );
        let attached = call(
            &mut ws,
            2,
            None,
            "Target.attachToTarget",
            json!({"targetId": target["targetId"], "flatten": true}),
        );
        let mut page = Page {
            ws,
            session: attached["sessionId"].as_str().unwrap().to_string(),
            id: 10,
        };
        if let Some((w, h)) = size {
            page.call(
                "Emulation.setDeviceMetricsOverride",
                json!({"width": w, "height": h, "deviceScaleFactor": 1, "mobile": false}),
            );
            page.call("Page.navigate", json!({"url": url}));
        }
        page
    }

    /// Calls a CDP method on this page.
    pub fn call(&mut self, method: &str, params: Value) -> Value {
        self.id += 1;
        let session = self.session.clone();
        call(&mut self.ws, self.id, Some(&session), method, params)
    }

    /// Evaluates a JavaScript expression (promises awaited) and returns its value (null when it
    /// throws, e.g. while the page is still loading).
    pub fn eval(&mut self, expr: &str) -> Value {
        self.evaluate(expr)
            .unwrap_or_else(|v| panic!("Runtime.evaluate: {v}"))
    }

    /// `eval`, except that an evaluation the page's own navigation cut short (Chromium answers
    /// "Inspected target navigated or closed", or that the execution context was destroyed)
    /// gives None instead of failing: a page that redirects itself does so at a moment of its
    /// own choosing.
    fn eval_across_navigation(&mut self, expr: &str) -> Option<Value> {
        match self.evaluate(expr) {
            Ok(v) => Some(v),
            Err(v) => {
                let message = v["error"]["message"].as_str().unwrap_or("");
                let navigated = message.contains("navigated or closed")
                    || message.contains("Execution context was destroyed")
                    || message.contains("Cannot find context");
                assert!(navigated, "Runtime.evaluate: {v}");
                None
            }
        }
    }

    /// `Runtime.evaluate` of `expr`: its value, or Chromium's whole error reply.
    fn evaluate(&mut self, expr: &str) -> Result<Value, Value> {
        let params = json!({"expression": expr, "returnByValue": true, "awaitPromise": true});
        self.id += 1;
        let session = self.session.clone();
        try_call(
            &mut self.ws,
            self.id,
            Some(&session),
            "Runtime.evaluate",
            params,
        )
        .map(|r| r["result"]["value"].clone())
    }

    /// Waits until `expr` is true; fails naming `what` (and `detail`'s value) after 30 s. The
    /// page may navigate meanwhile.
    pub fn wait_until(&mut self, expr: &str, what: &str, detail: &str) {
        let start = Instant::now();
        loop {
            if self.eval_across_navigation(expr).and_then(|v| v.as_bool()) == Some(true) {
                return;
            }
            if start.elapsed() > Duration::from_secs(30) {
                let d = self.eval_across_navigation(detail).unwrap_or(Value::Null);
                panic!("timed out waiting for {what}; {detail}: {d}");
            }
            std::thread::sleep(Duration::from_millis(50));
        }
    }

    /// A real mouse event at CSS pixel (x, y) of the viewport: `kind` is mousePressed,
    /// mouseMoved or mouseReleased; `held`: the left button is down during (or after) it.
    pub fn mouse(&mut self, kind: &str, x: f64, y: f64, held: bool) {
        let button = if kind == "mouseMoved" && !held {
            "none"
        } else {
            "left"
        };
        self.call(
            "Input.dispatchMouseEvent",
            json!({
                "type": kind, "x": x, "y": y, "button": button,
                "buttons": if held { 1 } else { 0 }, "clickCount": 1,
            }),
        );
    }

    /// A click (press and release) at (x, y).
    pub fn click(&mut self, x: f64, y: f64) {
        self.mouse("mouseMoved", x, y, false);
        self.mouse("mousePressed", x, y, true);
        self.mouse("mouseReleased", x, y, false);
    }

    /// A drag from `from` to `to` in `steps` moves with the button held.
    pub fn drag(&mut self, from: (f64, f64), to: (f64, f64), steps: usize) {
        self.mouse("mouseMoved", from.0, from.1, false);
        self.mouse("mousePressed", from.0, from.1, true);
        for i in 1..=steps {
            let t = i as f64 / steps as f64;
            let x = from.0 + (to.0 - from.0) * t;
            let y = from.1 + (to.1 - from.1) * t;
            self.mouse("mouseMoved", x, y, true);
        }
        self.mouse("mouseReleased", to.0, to.1, false);
    }

    /// A key press (down and up): `key` as in `KeyboardEvent.key`, with its Windows key code.
    pub fn key(&mut self, key: &str, code: &str, key_code: u32) {
        for kind in ["rawKeyDown", "keyUp"] {
            self.call(
                "Input.dispatchKeyEvent",
                json!({"type": kind, "key": key, "code": code, "windowsVirtualKeyCode": key_code}),
            );
        }
    }
}

/// Decodes standard base64 (what the pages' `btoa` returns).
pub fn decode_b64(s: &str) -> Vec<u8> {
    let val = |c: u8| -> u32 {
        match c {
            b'A'..=b'Z' => (c - b'A') as u32,
            b'a'..=b'z' => (c - b'a' + 26) as u32,
            b'0'..=b'9' => (c - b'0' + 52) as u32,
            b'+' => 62,
            b'/' => 63,
            _ => panic!("not base64: {c}"),
        }
    };
    let bytes = s.as_bytes();
    let mut out = Vec::with_capacity(bytes.len() / 4 * 3);
    for chunk in bytes.chunks(4) {
        let pad = chunk.iter().filter(|&&c| c == b'=').count();
        let mut n = 0u32;
        for (k, &c) in chunk.iter().enumerate() {
            n |= if c == b'=' { 0 } else { val(c) } << (18 - 6 * k);
        }
        let b = [(n >> 16) as u8, (n >> 8) as u8, n as u8];
        out.extend_from_slice(&b[..3 - pad]);
    }
    out
}
