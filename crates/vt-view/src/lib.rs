//! vt-view: System A in the browser, on 127.0.0.1. `vt view` and `vt mark` are thin front ends
//! over it.
//!
//! - The live viewer ([`Viewer`]) serves the WebGL2 page `vt export` writes (vt-web's player,
//!   its files held in memory: `/` and `/data/*`), which renders in the browser. A browser
//!   without WebGL2 is sent by that page to `/mjpeg`, the fallback: there the Rust side renders
//!   (eq. 3-6, as `vt render`) and streams JPEG frames as MJPEG (`multipart/x-mixed-replace`,
//!   `/stream.mjpg`, or one frame at `/frame.jpg`), shown in a plain `<img>`; that page sends the
//!   viewpoint and speed to `/control` and polls `/state`. The CPU renders only while a stream
//!   or frame is asked for. Exactly these routes: `/`, `/data/NAME` (the page's files),
//!   `/mjpeg`, `/stream.mjpg`, `/frame.jpg`, `/state`, `/control`; everything else is 404.
//! - The marking page ([`mark`]): the points that register the views, shown on the views'
//!   backgrounds, moved, added and removed in the browser, with the fit of every neighbour pair
//!   recomputed after each change, and saved as a points file.
//!
//! Both bind 127.0.0.1 only and serve no files from disk. The HTTP layer is std's `TcpListener` with
//! `httparse` for the request line and headers, so nothing is ever allocated on a client's word:
//! a request head is at most [`MAX_HEAD`] bytes, the viewer refuses request bodies unread (413;
//! the marking page takes bodies up to [`mark::MAX_BODY`]), each connection has its own thread
//! (at most [`MAX_CONNECTIONS`]; beyond that new ones get 503), and idle or slow clients are
//! dropped after [`IDLE_TIMEOUT`] (reads) or [`WRITE_TIMEOUT`] (a stream nobody reads).
#![deny(missing_docs)]

mod error;
mod http;
pub mod mark;

pub use error::{Error, Result};
pub use http::{IDLE_TIMEOUT, MAX_CONNECTIONS, MAX_HEAD, WRITE_TIMEOUT};

use std::collections::BTreeMap;
use std::io::Write;
use std::net::{TcpListener, TcpStream};
use std::sync::{Arc, Condvar, Mutex, MutexGuard};
use std::time::{Duration, Instant};

use http::{Body, Reply};
use image::codecs::jpeg::JpegEncoder;
use image::RgbImage;
use serde::Serialize;
use vt_core::render::{split_q, FrameChoice, Player, RenderParams, Renderer};
use vt_io::scene::LoadedScene;

const PAGE: &str = include_str!("view.html");

/// Slowest playback speed other than 0 (paused), and the fastest.
pub const SPEED_RANGE: (f64, f64) = (0.01, 8.0);

/// Locks, treating a poisoned lock as usable: the data behind these locks (a control value, the
/// latest frame) is valid whatever a panicking thread was doing.
fn lock<T>(m: &Mutex<T>) -> MutexGuard<'_, T> {
    m.lock().unwrap_or_else(|e| e.into_inner())
}

#[derive(Clone, Copy)]
struct Control {
    q: f64,
    speed: f64,
}

#[derive(Clone, Copy, Default, Serialize)]
struct Status {
    q: f64,
    view: usize,
    frame: usize,
    wraps: u64,
    switches: u64,
    fps: f64,
    speed: f64,
    frames: u64,
}

#[derive(Default)]
struct Latest {
    seq: u64,
    jpeg: Arc<Vec<u8>>,
    status: Status,
}

struct Shared {
    control: Mutex<Control>,
    latest: Mutex<Latest>,
    fresh: Condvar,
    /// When a client last asked for a rendered frame (a stream's part, `/frame.jpg`): the render
    /// thread idles [`IDLE_AFTER`] after it.
    asked: Mutex<Option<Instant>>,
}

/// The CPU renderer stops this long after the last client asked for a frame.
const IDLE_AFTER: Duration = Duration::from_secs(1);

impl Shared {
    fn ask(&self) {
        *lock(&self.asked) = Some(Instant::now());
    }

    fn wanted(&self) -> bool {
        lock(&self.asked).is_some_and(|t| t.elapsed() < IDLE_AFTER)
    }
}

/// Fastest frame rate the viewer streams at speed 1.
pub const MAX_FPS: f64 = 240.0;

/// What the viewer shows and how: the scene's renderer settings, the starting viewpoint, the
/// frame rate at speed 1 (at most [`MAX_FPS`]) and the JPEG quality. Checked by
/// [`Viewer::bind`].
#[derive(Debug, Clone)]
pub struct ViewerParams {
    /// Port on 127.0.0.1 (0 = any free port; [`Viewer::port`] says which).
    pub port: u16,
    /// Frames per second at speed 1, in (0, 240].
    pub fps: f64,
    /// Starting viewpoint, in `[0, M - 1]`.
    pub q: f64,
    /// JPEG quality, 1-100.
    pub quality: u8,
    /// Renderer settings (interpolation, crossfade, gain compensation, ...).
    pub render: RenderParams,
}

/// A viewer bound to its port, not yet serving.
pub struct Viewer {
    listener: TcpListener,
    port: u16,
    shared: Arc<Shared>,
    page: Arc<String>,
    q_max: f64,
    files: Arc<BTreeMap<String, Arc<Vec<u8>>>>,
}

impl Viewer {
    /// Checks the parameters, starts the render thread (idle until a client asks for a frame)
    /// and binds 127.0.0.1:`port`. `name` is the scene's name as the fallback page shows it.
    /// The WebGL page is served once [`Viewer::with_page`] hands it over.
    pub fn bind(scene: Arc<LoadedScene>, name: &str, params: &ViewerParams) -> Result<Self> {
        let num = vt_io::output::num;
        let bad = |name, value, why: String| Err(Error::Param { name, value, why });
        if !(params.fps.is_finite() && params.fps > 0.0 && params.fps <= MAX_FPS) {
            return bad("fps", num(params.fps), format!("must be in (0, {MAX_FPS}]"));
        }
        if !(1..=100).contains(&params.quality) {
            return bad(
                "quality",
                params.quality.to_string(),
                "must be in 1..=100".into(),
            );
        }
        if scene.render.check_q(params.q).is_err() {
            let (q_max, n) = (scene.render.q_max(), scene.render.views.len());
            let why = format!("is outside [0, {q_max}] (the scene has {n} views)");
            return bad("q", num(params.q), why);
        }
        let q_max = scene.render.q_max();
        let renderer = Renderer::new(scene.render.clone(), params.render)?;
        let (listener, port) = http::bind(params.port)?;
        let shared = Arc::new(Shared {
            control: Mutex::new(Control {
                q: params.q,
                speed: 1.0,
            }),
            latest: Mutex::new(Latest::default()),
            fresh: Condvar::new(),
            asked: Mutex::new(None),
        });
        {
            let shared = shared.clone();
            let (fps, quality) = (params.fps, params.quality);
            std::thread::spawn(move || {
                let mut renderer = renderer;
                // A panic in the renderer must not freeze the video: say so and start again.
                for _ in 0..100 {
                    // On this thread, not on a rayon worker: the loop lives as long as the server
                    // and waits between frames, and a worker parked in it is one the rest of
                    // the process cannot use. On 2 cores that deadlocked the page's own
                    // rendering (vt view's start hung in rayon's join, one worker asleep in
                    // this loop and the other waiting on a latch), so the renderer's passes
                    // queue through the global pool like any other caller's.
                    let run = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
                        render_loop(&scene, &mut renderer, &shared, fps, quality)
                    }));
                    if run.is_ok() {
                        return;
                    }
                    eprintln!("vt view: the renderer failed; restarting it");
                    std::thread::sleep(Duration::from_millis(100));
                }
            });
        }
        let name = serde_json::to_string(name)
            .unwrap_or_else(|_| "\"scene\"".into())
            .replace('<', "\\u003c");
        let page = Arc::new(
            PAGE.replace("__QMAX__", &q_max.to_string())
                .replace("__Q0__", &format!("{:.2}", params.q))
                .replace("\"__SCENE__\"", &name),
        );
        Ok(Self {
            listener,
            port,
            shared,
            page,
            q_max,
            files: Arc::default(),
        })
    }

    /// The page served at `/`: its files by path (`index.html`, `data/player.js`, ...), as
    /// `vt_web::page` builds them. Without one, `/` is the fallback page.
    pub fn with_page(mut self, files: BTreeMap<String, Vec<u8>>) -> Self {
        self.files = Arc::new(files.into_iter().map(|(k, v)| (k, Arc::new(v))).collect());
        self
    }

    /// The port it listens on.
    pub fn port(&self) -> u16 {
        self.port
    }

    /// Serves connections until the process ends.
    pub fn serve(self) {
        let Viewer {
            listener,
            shared,
            page,
            q_max,
            files,
            ..
        } = self;
        let limits = http::Limits {
            max_body: 0,
            stack: 256 << 10,
        };
        http::serve(
            listener,
            limits,
            Arc::new(ViewHandler {
                shared,
                page,
                q_max,
                files,
            }),
        );
    }
}

/// The viewer's routes.
struct ViewHandler {
    shared: Arc<Shared>,
    /// The fallback page.
    page: Arc<String>,
    q_max: f64,
    /// The WebGL page's files.
    files: Arc<BTreeMap<String, Arc<Vec<u8>>>>,
}

impl ViewHandler {
    /// One of the WebGL page's files.
    fn file(&self, name: &str) -> Option<Reply> {
        page_file(&self.files, name)
    }
}

/// A page's file by its exact path, with its content type.
fn page_file(files: &BTreeMap<String, Arc<Vec<u8>>>, name: &str) -> Option<Reply> {
    let bytes = files.get(name)?.clone();
    let kind = match name.rsplit_once('.').map(|(_, e)| e) {
        Some("html") => "text/html; charset=utf-8",
        Some("js") => "text/javascript; charset=utf-8",
        _ => "application/octet-stream",
    };
    Some(Reply::new(200, kind, Body::Shared(bytes)))
}

/// A static page served on 127.0.0.1 (`vt fv view`): `GET /` is its `index.html`, `GET
/// /data/NAME` its files by exact name, everything else 404. Every request must name this
/// server in `Host` (`127.0.0.1:PORT` or `localhost:PORT`; else 403), against DNS rebinding.
pub struct PageServer {
    listener: TcpListener,
    port: u16,
    files: Arc<BTreeMap<String, Arc<Vec<u8>>>>,
}

impl PageServer {
    /// Binds 127.0.0.1:`port` (0 = any free port) for the page's `files` (by path).
    pub fn bind(port: u16, files: BTreeMap<String, Vec<u8>>) -> Result<Self> {
        let (listener, port) = http::bind(port)?;
        let files = Arc::new(files.into_iter().map(|(k, v)| (k, Arc::new(v))).collect());
        Ok(Self {
            listener,
            port,
            files,
        })
    }

    /// The port it listens on.
    pub fn port(&self) -> u16 {
        self.port
    }

    /// Serves connections until the process ends.
    pub fn serve(self) {
        let limits = http::Limits {
            max_body: 0,
            stack: 256 << 10,
        };
        let hosts = [
            format!("127.0.0.1:{}", self.port),
            format!("localhost:{}", self.port),
        ];
        let handler = PageHandler {
            files: self.files,
            hosts,
        };
        http::serve(self.listener, limits, Arc::new(handler));
    }
}

struct PageHandler {
    files: Arc<BTreeMap<String, Arc<Vec<u8>>>>,
    hosts: [String; 2],
}

impl http::Handler for PageHandler {
    fn handle(&self, req: &http::Request, _conn: &mut TcpStream) -> Reply {
        if !req.host.as_ref().is_some_and(|h| self.hosts.contains(h)) {
            let want = &self.hosts[0];
            return Reply::text(403, format!("only pages from {want} may use this server"));
        }
        match req.path.as_str() {
            "/" => page_file(&self.files, "index.html").unwrap_or_else(Reply::not_found),
            p if p.starts_with("/data/") => {
                page_file(&self.files, &p[1..]).unwrap_or_else(Reply::not_found)
            }
            _ => Reply::not_found(),
        }
    }
}

impl http::Handler for ViewHandler {
    fn handle(&self, req: &http::Request, conn: &mut TcpStream) -> Reply {
        let shared = &self.shared;
        let fallback = || {
            Reply::new(
                200,
                "text/html; charset=utf-8",
                Body::Text(self.page.clone()),
            )
        };
        match req.path.as_str() {
            "/" => self.file("index.html").unwrap_or_else(fallback),
            "/mjpeg" => fallback(),
            p if p.starts_with("/data/") => self.file(&p[1..]).unwrap_or_else(Reply::not_found),
            "/state" => Reply::json(200, &lock(&shared.latest).status),
            "/control" => match parse_control(&req.query, self.q_max) {
                Ok((q, speed)) => {
                    let mut c = lock(&shared.control);
                    if let Some(q) = q {
                        c.q = q;
                    }
                    if let Some(sp) = speed {
                        c.speed = sp;
                    }
                    drop(c);
                    Reply::json(200, &lock(&shared.latest).status)
                }
                Err(e) => Reply::text(400, e),
            },
            "/frame.jpg" => Reply::new(200, "image/jpeg", Body::Shared(fresh_frame(shared))),
            "/stream.mjpg" => {
                // Written straight to the socket and flushed per frame: a buffered body would
                // hold back the last frame while playback is paused.
                stream_mjpeg(shared, conn);
                Reply::Taken
            }
            _ => Reply::not_found(),
        }
    }
}

/// `q=1.5&speed=0.5`; each optional; values checked.
fn parse_control(query: &str, q_max: f64) -> Result<(Option<f64>, Option<f64>), String> {
    let (mut q, mut speed) = (None, None);
    for pair in query.split('&').filter(|p| !p.is_empty()) {
        let (k, v) = pair.split_once('=').unwrap_or((pair, ""));
        let (ks, vs) = (vt_io::output::shorten(k), vt_io::output::shorten(v));
        let x: f64 = v
            .parse()
            .map_err(|_| format!("{ks}: '{vs}' is not a number"))?;
        let (slow, fast) = SPEED_RANGE;
        match k {
            "q" if x.is_finite() && (0.0..=q_max).contains(&x) => q = Some(x),
            "q" => {
                return Err(format!(
                    "q {} is outside [0, {q_max}]",
                    vt_io::output::num(x)
                ))
            }
            "speed" if x == 0.0 || (slow..=fast).contains(&x) => speed = Some(x),
            "speed" => {
                return Err(format!(
                    "speed {} must be 0 (paused) or in [{slow}, {fast}]",
                    vt_io::output::num(x)
                ))
            }
            _ => return Err(format!("unknown parameter '{ks}'")),
        }
    }
    Ok((q, speed))
}

/// Renders at `fps * speed`, encodes JPEG, publishes. Paused (speed 0), it re-renders only when
/// the viewpoint moves, keeping the shown frame unless the object's source view changes.
fn render_loop(
    scene: &LoadedScene,
    renderer: &mut Renderer,
    shared: &Shared,
    fps: f64,
    quality: u8,
) {
    let (w, h) = renderer.size();
    let mut frame = RgbImage::new(w, h);
    let mut player = Player::new();
    // The last published control and choice: any control change republishes at once.
    let mut last: Option<(f64, f64, FrameChoice)> = None;
    let mut next_tick = Instant::now();
    let mut times: std::collections::VecDeque<Instant> = std::collections::VecDeque::new();
    let mut count = 0u64;
    loop {
        if !shared.wanted() {
            // Nobody watches the stream: the WebGL page renders in the browser. The next client
            // gets a frame at once.
            last = None;
            std::thread::sleep(Duration::from_millis(20));
            continue;
        }
        let Control { q, speed } = *lock(&shared.control);
        let now = Instant::now();
        let playing = speed > 0.0;
        let due = playing && now >= next_tick;
        let moved = last.is_none_or(|(lq, ls, _)| lq != q || ls != speed);
        if !due && !moved {
            let wait = if playing {
                next_tick.saturating_duration_since(now)
            } else {
                Duration::from_millis(10)
            };
            std::thread::sleep(wait.min(Duration::from_millis(10)));
            continue;
        }
        let choice = match last {
            Some((_, _, c)) if !due && c.view == split_q(q).nearest => c,
            _ => match player.advance(&scene.render, q) {
                Ok(c) => c,
                Err(_) => continue,
            },
        };
        if renderer
            .render_into(&scene.objects, q, &choice, &mut frame)
            .is_err()
        {
            std::thread::sleep(Duration::from_millis(50));
            continue;
        }
        let mut jpeg = Vec::with_capacity(64 << 10);
        if JpegEncoder::new_with_quality(&mut jpeg, quality)
            .encode_image(&frame)
            .is_err()
        {
            continue;
        }
        count += 1;
        times.push_back(Instant::now());
        while times.len() > 30 {
            times.pop_front();
        }
        let measured = match (times.front(), times.back()) {
            (Some(a), Some(b)) if times.len() > 1 && b > a => {
                (times.len() - 1) as f64 / (*b - *a).as_secs_f64()
            }
            _ => 0.0,
        };
        {
            let mut l = lock(&shared.latest);
            l.seq += 1;
            l.jpeg = Arc::new(jpeg);
            l.status = Status {
                q,
                view: choice.view,
                frame: choice.frame,
                wraps: player.wraps,
                switches: player.switches,
                fps: if playing { measured } else { 0.0 },
                speed,
                frames: count,
            };
        }
        shared.fresh.notify_all();
        last = Some((q, speed, choice));
        if due {
            // Speed is at least SPEED_RANGE.0 and fps positive, so the step is finite; still,
            // never panic on it.
            next_tick += Duration::try_from_secs_f64(1.0 / (fps * speed))
                .unwrap_or(Duration::from_secs(1))
                .min(Duration::from_secs(3600));
            if next_tick < Instant::now() {
                next_tick = Instant::now();
            }
        }
    }
}

/// A frame rendered after this request (the renderer may have been idle), or after a second
/// the latest there is.
fn fresh_frame(shared: &Shared) -> Arc<Vec<u8>> {
    shared.ask();
    let mut l = lock(&shared.latest);
    let seen = l.seq;
    let deadline = Instant::now() + Duration::from_secs(1);
    while (l.seq == seen || l.jpeg.is_empty()) && Instant::now() < deadline {
        let left = deadline.saturating_duration_since(Instant::now());
        l = shared
            .fresh
            .wait_timeout(l, left.max(Duration::from_millis(1)))
            .unwrap_or_else(|e| e.into_inner())
            .0;
    }
    l.jpeg.clone()
}

/// Serves one MJPEG client until it disconnects: every new frame becomes one part, each part ends
/// with the next boundary, and while nothing new is rendered (paused) the current frame is
/// repeated every 200 ms, because browsers display a part only when the following one arrives.
fn stream_mjpeg(shared: &Shared, out: &mut TcpStream) {
    let head = "HTTP/1.1 200 OK\r\nContent-Type: multipart/x-mixed-replace; boundary=vtframe\r\n\
                Cache-Control: no-cache, no-store\r\nConnection: close\r\n\r\n--vtframe\r\n";
    if out
        .write_all(head.as_bytes())
        .and_then(|_| out.flush())
        .is_err()
    {
        return;
    }
    let mut seen = 0u64;
    loop {
        shared.ask();
        // A new frame, or after 200 ms the current one again: browsers show a multipart part
        // only once the next one starts, so a paused picture must still be followed.
        let jpeg = {
            let mut l = lock(&shared.latest);
            let deadline = Instant::now() + Duration::from_millis(200);
            while (l.seq == seen && Instant::now() < deadline) || l.jpeg.is_empty() {
                let left = deadline
                    .saturating_duration_since(Instant::now())
                    .max(Duration::from_millis(1));
                l = shared
                    .fresh
                    .wait_timeout(l, left)
                    .unwrap_or_else(|e| e.into_inner())
                    .0;
            }
            seen = l.seq;
            l.jpeg.clone()
        };
        let part = format!(
            "Content-Type: image/jpeg\r\nContent-Length: {}\r\n\r\n",
            jpeg.len()
        );
        let sent = out
            .write_all(part.as_bytes())
            .and_then(|_| out.write_all(&jpeg))
            .and_then(|_| out.write_all(b"\r\n--vtframe\r\n"))
            .and_then(|_| out.flush());
        if sent.is_err() {
            return;
        }
    }
}
