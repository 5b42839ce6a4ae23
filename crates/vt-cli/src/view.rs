//! `vt view`: a live viewer in the browser.
//!
//! The Rust side renders (eq. 3-6, as `vt render`) and streams JPEG frames as MJPEG
//! (`multipart/x-mixed-replace`), which every browser shows in a plain `<img>` with no script;
//! the page sends the viewpoint and speed to `/control` and polls `/state` for the status line.
//! The server binds 127.0.0.1 only and answers exactly five routes: `/`, `/stream.mjpg`,
//! `/frame.jpg`, `/state`, `/control`; everything else is 404. No files are served.

use std::io::Write;
use std::path::PathBuf;
use std::sync::{Arc, Condvar, Mutex};
use std::time::{Duration, Instant};

use anyhow::{bail, Context, Result};
use clap::Args;
use image::codecs::jpeg::JpegEncoder;
use image::RgbImage;
use serde::Serialize;
use tiny_http::{Header, Response, Server};
use vt_core::render::{split_q, FrameChoice, Player, Renderer};
use vt_io::scene::LoadedScene;

use crate::render::RenderOptions;

const PAGE: &str = include_str!("view.html");

#[derive(Args)]
pub struct ViewArgs {
    /// Scene directory written by `vt analyze`.
    scene: PathBuf,
    /// Port on 127.0.0.1 (0 = any free port; the URL is printed).
    #[arg(long, default_value_t = 8080)]
    port: u16,
    /// Frame rate at speed 1.
    #[arg(long, default_value_t = 30.0)]
    fps: f64,
    /// Starting viewpoint.
    #[arg(long, default_value_t = 0.0)]
    q: f64,
    /// JPEG quality (1-100).
    #[arg(long, default_value_t = 85)]
    quality: u8,
    #[command(flatten)]
    options: RenderOptions,
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
}

pub fn run(args: ViewArgs) -> Result<()> {
    if !(args.fps.is_finite() && args.fps > 0.0 && args.fps <= 240.0) {
        bail!("--fps {} must be in (0, 240]", args.fps);
    }
    if !(1..=100).contains(&args.quality) {
        bail!("--quality {} must be in 1..=100", args.quality);
    }
    let scene = LoadedScene::open(&args.scene)?;
    scene.render.check_q(args.q)?;
    let q_max = scene.render.q_max();
    let renderer = Renderer::new(scene.render.clone(), args.options.params())?;
    let server = Server::http(("127.0.0.1", args.port))
        .map_err(|e| anyhow::anyhow!("cannot listen on 127.0.0.1:{}: {e}", args.port))?;
    let port = server
        .server_addr()
        .to_ip()
        .map(|a| a.port())
        .context("server address")?;
    let shared = Arc::new(Shared {
        control: Mutex::new(Control {
            q: args.q,
            speed: 1.0,
        }),
        latest: Mutex::new(Latest::default()),
        fresh: Condvar::new(),
    });
    {
        let shared = shared.clone();
        let (fps, quality) = (args.fps, args.quality);
        std::thread::spawn(move || {
            rayon::scope(|_| render_loop(scene, renderer, shared, fps, quality))
        });
    }
    let name = serde_json::to_string(&args.scene.display().to_string())?.replace('<', "\\u003c");
    let page = PAGE
        .replace("__QMAX__", &q_max.to_string())
        .replace("__Q0__", &format!("{:.2}", args.q))
        .replace("\"__SCENE__\"", &name);
    println!(
        "vt view: serving {} at http://127.0.0.1:{port}/ (Ctrl-C to stop)",
        args.scene.display()
    );
    std::io::stdout().flush().ok();

    for request in server.incoming_requests() {
        let url = request.url().to_string();
        let (path, query) = url.split_once('?').unwrap_or((&url, ""));
        let header = |k: &str, v: &str| {
            Header::from_bytes(k.as_bytes(), v.as_bytes()).expect("static header")
        };
        let result = match path {
            "/" => request.respond(
                Response::from_string(page.clone())
                    .with_header(header("Content-Type", "text/html; charset=utf-8")),
            ),
            "/state" => {
                let s = shared
                    .latest
                    .lock()
                    .expect("no panics hold the lock")
                    .status;
                request.respond(json(&s))
            }
            "/control" => match parse_control(query, q_max) {
                Ok((q, speed)) => {
                    let mut c = shared.control.lock().expect("no panics hold the lock");
                    if let Some(q) = q {
                        c.q = q;
                    }
                    if let Some(sp) = speed {
                        c.speed = sp;
                    }
                    drop(c);
                    let s = shared
                        .latest
                        .lock()
                        .expect("no panics hold the lock")
                        .status;
                    request.respond(json(&s))
                }
                Err(e) => request.respond(Response::from_string(e).with_status_code(400)),
            },
            "/frame.jpg" => {
                let jpeg = shared
                    .latest
                    .lock()
                    .expect("no panics hold the lock")
                    .jpeg
                    .clone();
                request.respond(
                    Response::from_data(jpeg.to_vec())
                        .with_header(header("Content-Type", "image/jpeg")),
                )
            }
            "/stream.mjpg" => {
                // Written straight to the socket and flushed per frame: a buffered response body
                // would hold back the last frame while playback is paused.
                let shared = shared.clone();
                let writer = request.into_writer();
                std::thread::spawn(move || stream_mjpeg(shared, writer));
                Ok(())
            }
            _ => request.respond(Response::from_string("not found").with_status_code(404)),
        };
        let _ = result;
    }
    Ok(())
}

fn json<T: Serialize>(v: &T) -> Response<std::io::Cursor<Vec<u8>>> {
    Response::from_string(serde_json::to_string(v).unwrap_or_default()).with_header(
        Header::from_bytes(&b"Content-Type"[..], &b"application/json"[..]).expect("static header"),
    )
}

/// `q=1.5&speed=0.5`; each optional; values checked.
fn parse_control(query: &str, q_max: f64) -> Result<(Option<f64>, Option<f64>), String> {
    let (mut q, mut speed) = (None, None);
    for pair in query.split('&').filter(|p| !p.is_empty()) {
        let (k, v) = pair.split_once('=').unwrap_or((pair, ""));
        let x: f64 = v
            .parse()
            .map_err(|_| format!("{k}: '{v}' is not a number"))?;
        match k {
            "q" if x.is_finite() && (0.0..=q_max).contains(&x) => q = Some(x),
            "q" => return Err(format!("q {x} is outside [0, {q_max}]")),
            "speed" if x.is_finite() && (0.0..=8.0).contains(&x) => speed = Some(x),
            "speed" => return Err(format!("speed {x} is outside [0, 8]")),
            _ => return Err(format!("unknown parameter '{k}'")),
        }
    }
    Ok((q, speed))
}

/// Renders at `fps * speed`, encodes JPEG, publishes. Paused (speed 0), it re-renders only when
/// the viewpoint moves, keeping the shown frame unless the object's source view changes.
fn render_loop(
    scene: LoadedScene,
    mut renderer: Renderer,
    shared: Arc<Shared>,
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
        let Control { q, speed } = *shared.control.lock().expect("no panics hold the lock");
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
            Some((_, _, c)) if !due && c.view == split_q(q).2 => c,
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
            let mut l = shared.latest.lock().expect("no panics hold the lock");
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
            next_tick += Duration::from_secs_f64(1.0 / (fps * speed));
            if next_tick < Instant::now() {
                next_tick = Instant::now();
            }
        }
    }
}

/// Serves one MJPEG client until it disconnects: every new frame becomes one part, each part ends
/// with the next boundary, and while nothing new is rendered (paused) the current frame is
/// repeated every 200 ms, because browsers display a part only when the following one arrives.
fn stream_mjpeg(shared: Arc<Shared>, mut out: Box<dyn Write + Send>) {
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
        // A new frame, or after 200 ms the current one again: browsers show a multipart part
        // only once the next one starts, so a paused picture must still be followed.
        let jpeg = {
            let mut l = shared.latest.lock().expect("no panics hold the lock");
            let deadline = Instant::now() + Duration::from_millis(200);
            while (l.seq == seen && Instant::now() < deadline) || l.jpeg.is_empty() {
                let left = deadline
                    .saturating_duration_since(Instant::now())
                    .max(Duration::from_millis(1));
                l = shared
                    .fresh
                    .wait_timeout(l, left)
                    .expect("no panics hold the lock")
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
