//! The HTTP layer shared by the viewer and the marking page: std's `TcpListener` on 127.0.0.1
//! with `httparse` for the request line and headers, so nothing is allocated on a client's word.
//!
//! - A request head is at most [`MAX_HEAD`] bytes (431 beyond).
//! - Bodies: a server that takes none ([`Limits::max_body`] 0) refuses any request declaring one,
//!   unread (413), and answers only GET (405); one that takes them accepts GET and POST with a
//!   `Content-Length` of at most `max_body` bytes (413 beyond or chunked, 400 unreadable).
//! - Each connection has its own thread, at most [`MAX_CONNECTIONS`] at once (503 beyond);
//!   connections idle for [`IDLE_TIMEOUT`] and clients that take no data for [`WRITE_TIMEOUT`]
//!   are dropped.
//! - The routes are the handler's: fixed paths, no files served.

use std::io::{Read, Write};
use std::net::{TcpListener, TcpStream};
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::Arc;
use std::time::Duration;

use serde::Serialize;

use crate::{Error, Result};

/// Largest request head (request line and headers), bytes.
pub const MAX_HEAD: usize = 8192;
/// Most connections served at once; more get 503.
pub const MAX_CONNECTIONS: usize = 512;
/// A connection that sends nothing for this long is closed.
pub const IDLE_TIMEOUT: Duration = Duration::from_secs(15);
/// A client that takes no data for this long is dropped.
pub const WRITE_TIMEOUT: Duration = Duration::from_secs(15);

/// The request methods served.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Method {
    Get,
    Post,
}

/// What one request asked for.
pub(crate) struct Request {
    pub method: Method,
    pub path: String,
    pub query: String,
    /// At most the server's `max_body` bytes (empty for GET).
    pub body: Vec<u8>,
    pub keep_alive: bool,
    /// The `Host` header, if any.
    pub host: Option<String>,
    /// The `Content-Type` header, lower case, if any.
    pub content_type: Option<String>,
}

/// A response body.
pub(crate) enum Body {
    Owned(Vec<u8>),
    Shared(Arc<Vec<u8>>),
    Text(Arc<String>),
}

impl Body {
    fn bytes(&self) -> &[u8] {
        match self {
            Body::Owned(b) => b,
            Body::Shared(b) => b,
            Body::Text(t) => t.as_bytes(),
        }
    }
}

/// What a handler answers.
pub(crate) enum Reply {
    /// A whole response, sent with `Content-Length`.
    Full {
        status: u16,
        content_type: &'static str,
        body: Body,
    },
    /// The handler wrote to the connection itself (a stream); the connection ends.
    Taken,
}

impl Reply {
    pub fn new(status: u16, content_type: &'static str, body: Body) -> Self {
        Reply::Full {
            status,
            content_type,
            body,
        }
    }

    pub fn text(status: u16, message: impl Into<String>) -> Self {
        Self::new(
            status,
            "text/plain; charset=utf-8",
            Body::Owned(message.into().into_bytes()),
        )
    }

    pub fn json<T: Serialize>(status: u16, value: &T) -> Self {
        Self::new(
            status,
            "application/json",
            Body::Owned(serde_json::to_vec(value).unwrap_or_default()),
        )
    }

    pub fn not_found() -> Self {
        Self::text(404, "not found")
    }
}

/// A server's routes.
pub(crate) trait Handler: Send + Sync + 'static {
    /// Answers one request; may write to `conn` itself and return [`Reply::Taken`].
    fn handle(&self, req: &Request, conn: &mut TcpStream) -> Reply;
}

/// How much a server accepts.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Limits {
    /// Largest request body, bytes (0: none, and GET only).
    pub max_body: usize,
    /// Stack of each connection's thread, bytes.
    pub stack: usize,
}

/// Binds 127.0.0.1:`port` (0: any free port) and says which port it got.
pub(crate) fn bind(port: u16) -> Result<(TcpListener, u16)> {
    let err = |cause| Error::Listen { port, cause };
    let listener = TcpListener::bind(("127.0.0.1", port)).map_err(err)?;
    let got = listener.local_addr().map_err(err)?.port();
    Ok((listener, got))
}

/// Serves connections until the process ends, a thread per connection.
pub(crate) fn serve<H: Handler>(listener: TcpListener, limits: Limits, handler: Arc<H>) {
    let active = Arc::new(AtomicUsize::new(0));
    for conn in listener.incoming() {
        let Ok(mut conn) = conn else {
            // Out of file descriptors or similar: let some connections finish.
            std::thread::sleep(Duration::from_millis(20));
            continue;
        };
        if active.load(Ordering::SeqCst) >= MAX_CONNECTIONS {
            let _ = conn.set_write_timeout(Some(Duration::from_millis(200)));
            let _ = respond(
                &mut conn,
                503,
                "text/plain",
                b"busy: too many connections",
                true,
            );
            continue;
        }
        active.fetch_add(1, Ordering::SeqCst);
        let guard = ActiveGuard(active.clone());
        let handler = handler.clone();
        let spawned = std::thread::Builder::new()
            .name("vt-view-conn".into())
            .stack_size(limits.stack)
            .spawn(move || {
                let _guard = guard;
                serve_connection(conn, limits, &*handler);
            });
        // When no thread can be made, the connection (moved into the failed closure) is closed.
        drop(spawned);
    }
}

/// Decrements the connection count when a connection's thread ends (also by panic).
struct ActiveGuard(Arc<AtomicUsize>);
impl Drop for ActiveGuard {
    fn drop(&mut self) {
        self.0.fetch_sub(1, Ordering::SeqCst);
    }
}

/// Writes a whole response with `Content-Length`.
pub(crate) fn respond(
    conn: &mut TcpStream,
    status: u16,
    content_type: &str,
    body: &[u8],
    close: bool,
) -> std::io::Result<()> {
    let reason = match status {
        200 => "OK",
        400 => "Bad Request",
        403 => "Forbidden",
        404 => "Not Found",
        405 => "Method Not Allowed",
        409 => "Conflict",
        413 => "Content Too Large",
        415 => "Unsupported Media Type",
        431 => "Request Header Fields Too Large",
        500 => "Internal Server Error",
        503 => "Service Unavailable",
        _ => "Error",
    };
    let head = format!(
        "HTTP/1.1 {status} {reason}\r\nContent-Type: {content_type}\r\nContent-Length: {}\r\nCache-Control: no-cache, no-store\r\nConnection: {}\r\n\r\n",
        body.len(),
        if close { "close" } else { "keep-alive" }
    );
    conn.write_all(head.as_bytes())?;
    conn.write_all(body)?;
    conn.flush()
}

/// Reads one request (head at most [`MAX_HEAD`] bytes, body at most `max_body`) from `conn`,
/// keeping any bytes after it in `buf` for the next request. `Ok(None)`: the client closed or
/// went idle. `Err(status)`: a request to refuse with that status, then close.
fn read_request(
    conn: &mut TcpStream,
    buf: &mut Vec<u8>,
    max_body: usize,
) -> Result<Option<Request>, (u16, &'static str)> {
    let mut chunk = [0u8; 2048];
    loop {
        let mut headers = [httparse::EMPTY_HEADER; 32];
        let mut req = httparse::Request::new(&mut headers);
        match req.parse(buf) {
            Ok(httparse::Status::Complete(len)) => {
                let method = req.method.unwrap_or("");
                let target = req.path.unwrap_or("/").to_string();
                let version = req.version.unwrap_or(1);
                let mut length: Option<Option<usize>> = None;
                let mut chunked = false;
                let mut close = version == 0;
                let (mut host, mut content_type) = (None, None);
                for h in req.headers.iter() {
                    let v = String::from_utf8_lossy(h.value).trim().to_ascii_lowercase();
                    if h.name.eq_ignore_ascii_case("host") {
                        host = Some(v);
                    } else if h.name.eq_ignore_ascii_case("content-type") {
                        content_type = Some(v);
                    } else if h.name.eq_ignore_ascii_case("content-length") {
                        length = Some(v.parse::<usize>().ok());
                    } else if h.name.eq_ignore_ascii_case("transfer-encoding") {
                        chunked = true;
                    } else if h.name.eq_ignore_ascii_case("connection") {
                        close |= v.contains("close");
                    }
                }
                let declared = chunked || length.is_some_and(|l| l != Some(0));
                let method = if max_body == 0 {
                    if declared {
                        // Never read (or allocate for) a body: this server takes none.
                        return Err((413, "request bodies are not accepted"));
                    }
                    if method != "GET" {
                        return Err((405, "only GET is served"));
                    }
                    Method::Get
                } else {
                    let method = match method {
                        "GET" => Method::Get,
                        "POST" => Method::Post,
                        _ => return Err((405, "only GET and POST are served")),
                    };
                    if chunked {
                        return Err((413, "chunked request bodies are not accepted"));
                    }
                    match length {
                        Some(None) => return Err((400, "unreadable Content-Length")),
                        Some(Some(n)) if n > max_body => {
                            return Err((413, "request body too large"))
                        }
                        Some(Some(n)) if n > 0 && method == Method::Get => {
                            return Err((413, "GET requests take no body"))
                        }
                        _ => {}
                    }
                    method
                };
                let body_len = length.flatten().unwrap_or(0);
                buf.drain(..len);
                // The body: what already arrived, then the rest (bounded above).
                while buf.len() < body_len {
                    let want = (body_len - buf.len()).min(chunk.len());
                    match conn.read(&mut chunk[..want]) {
                        Ok(0) | Err(_) => return Ok(None),
                        Ok(n) => buf.extend_from_slice(&chunk[..n]),
                    }
                }
                let body: Vec<u8> = buf.drain(..body_len).collect();
                let (path, query) = target.split_once('?').unwrap_or((&target, ""));
                return Ok(Some(Request {
                    method,
                    path: path.to_string(),
                    query: query.to_string(),
                    body,
                    keep_alive: !close,
                    host,
                    content_type,
                }));
            }
            Ok(httparse::Status::Partial) => {
                if buf.len() >= MAX_HEAD {
                    return Err((431, "request head too large"));
                }
            }
            Err(httparse::Error::TooManyHeaders) => return Err((431, "too many headers")),
            Err(_) => return Err((400, "malformed request")),
        }
        let want = MAX_HEAD.saturating_sub(buf.len()).clamp(1, chunk.len());
        match conn.read(&mut chunk[..want]) {
            Ok(0) | Err(_) => return Ok(None),
            Ok(n) => buf.extend_from_slice(&chunk[..n]),
        }
    }
}

/// Serves one connection: requests one after another (keep-alive) until it closes, goes idle,
/// or the handler takes it over.
fn serve_connection(mut conn: TcpStream, limits: Limits, handler: &dyn Handler) {
    let _ = conn.set_read_timeout(Some(IDLE_TIMEOUT));
    let _ = conn.set_write_timeout(Some(WRITE_TIMEOUT));
    let _ = conn.set_nodelay(true);
    let mut buf = Vec::with_capacity(1024);
    loop {
        let req = match read_request(&mut conn, &mut buf, limits.max_body) {
            Ok(Some(r)) => r,
            Ok(None) => return,
            Err((status, why)) => {
                let _ = respond(&mut conn, status, "text/plain", why.as_bytes(), true);
                return;
            }
        };
        let close = !req.keep_alive;
        let sent = match handler.handle(&req, &mut conn) {
            Reply::Full {
                status,
                content_type,
                body,
            } => respond(&mut conn, status, content_type, body.bytes(), close),
            Reply::Taken => return,
        };
        if sent.is_err() || close {
            return;
        }
    }
}
