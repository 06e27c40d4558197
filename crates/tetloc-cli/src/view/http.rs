//! The HTTP side: a request head read in bounded memory and time, the token checked before
//! anything else (403 without it, for every path and for the WebSocket), then one of seven
//! answers: the page (embedded in the binary), `GET /frame.png` (the still frame of the
//! current view) and `GET /frame.json` (its header: size, the range it was drawn with,
//! timings), `GET /mesh.json` (what the page's hello says of the mesh: fields, bounds, time
//! steps), `GET /state.json`, `PUT /state.json` (a script sets the view), or the WebSocket
//! upgrade. No path maps to a file.

use super::frames::{lock, Hub, Still};
use std::collections::VecDeque;
use std::io::{ErrorKind, Read, Write};
use std::net::{Shutdown, TcpListener, TcpStream};
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

/// The page, with its script and style, served as it is.
const PAGE: &str = include_str!("page.html");
/// Largest request head read.
const MAX_HEAD: usize = 8 * 1024;
/// Most connections served at once (WebSocket clients included).
const MAX_CONNECTIONS: usize = 64;
/// How long a client may take to send its whole request head (not each read: a client
/// trickling a byte at a time would hold its slot for good). Browsers and scripts send the
/// head in one packet; 5 s leaves room for a slow tunnel.
const HEAD_DEADLINE: Duration = Duration::from_secs(5);
/// How long an authenticated client may take to send a `PUT /state.json` body (at most
/// `MAX_STATE_BYTES`, 256 KiB: 20 s is ~13 KB/s).
const BODY_DEADLINE: Duration = Duration::from_secs(20);
/// How long `/frame.png` waits for the still frame of the current view.
const STILL_TIMEOUT: Duration = Duration::from_secs(60);

/// Connections still sending their request head (not yet authenticated), oldest first.
/// With every slot taken, a new connection evicts the oldest of these: clients that never
/// finish a head cannot lock out one that sends its head at once (a token holder's).
#[derive(Default)]
struct Pending {
    next: u64,
    conns: VecDeque<(u64, TcpStream)>,
}

impl Pending {
    /// Registers a connection (a handle to shut it down); returns its id.
    fn add(&mut self, stream: &TcpStream) -> Option<u64> {
        let handle = stream.try_clone().ok()?;
        self.next += 1;
        self.conns.push_back((self.next, handle));
        Some(self.next)
    }

    /// Its head is read: no longer evictable. False if it was evicted meanwhile.
    fn remove(&mut self, id: u64) -> bool {
        let before = self.conns.len();
        self.conns.retain(|(i, _)| *i != id);
        self.conns.len() < before
    }

    /// Closes the oldest; its thread's read fails and the thread ends. False if none.
    fn evict_oldest(&mut self) -> bool {
        let Some((_, s)) = self.conns.pop_front() else { return false };
        let _ = s.shutdown(Shutdown::Both);
        true
    }
}

/// Accepts connections until the process ends.
pub fn serve(listener: TcpListener, hub: Arc<Hub>) {
    let live = Arc::new(AtomicUsize::new(0));
    let pending = Arc::new(Mutex::new(Pending::default()));
    for stream in listener.incoming() {
        let Ok(stream) = stream else { continue };
        // Only this thread counts up, so the load below cannot go stale upwards. Evicted
        // threads end at once but count until then: at most twice the slots, all told.
        let n = live.load(Ordering::SeqCst);
        if n >= 2 * MAX_CONNECTIONS || n >= MAX_CONNECTIONS && !lock(&pending).evict_oldest() {
            let _ = respond(&stream, 503, "text/plain", b"too many connections\n");
            continue;
        }
        live.fetch_add(1, Ordering::SeqCst);
        let id = lock(&pending).add(&stream);
        let (hub, done, pend) = (hub.clone(), live.clone(), pending.clone());
        let spawned = std::thread::Builder::new().name("view-conn".into()).spawn(move || {
            let _ = handle(stream, &hub, || id.is_none_or(|id| lock(&pend).remove(id)));
            // An early error skips the removal above; its handle must not stay listed.
            if let Some(id) = id {
                lock(&pend).remove(id);
            }
            done.fetch_sub(1, Ordering::SeqCst);
        });
        if spawned.is_err() {
            live.fetch_sub(1, Ordering::SeqCst);
            if let Some(id) = id {
                lock(&pending).remove(id);
            }
        }
    }
}

/// A parsed request head.
#[derive(Debug, PartialEq)]
pub struct Request {
    pub method: String,
    pub path: String,
    pub token: Option<String>,
    pub headers: Vec<(String, String)>,
}

impl Request {
    pub fn header(&self, name: &str) -> Option<&str> {
        self.headers.iter().find(|(n, _)| n.eq_ignore_ascii_case(name)).map(|(_, v)| v.as_str())
    }
}

/// Parses a complete request head (up to and including the blank line).
pub fn parse_head(head: &[u8]) -> Option<Request> {
    let mut headers = [httparse::EMPTY_HEADER; 64];
    let mut req = httparse::Request::new(&mut headers);
    let httparse::Status::Complete(_) = req.parse(head).ok()? else { return None };
    let target = req.path?;
    let (path, query) = target.split_once('?').unwrap_or((target, ""));
    let token = query.split('&').find_map(|kv| kv.strip_prefix("token=")).map(str::to_string);
    let headers =
        req.headers.iter().map(|h| (h.name.to_string(), String::from_utf8_lossy(h.value).into_owned())).collect();
    Some(Request { method: req.method?.to_string(), path: path.to_string(), token, headers })
}

/// Whether `given` is `token`, in time that does not depend on where they differ.
pub fn token_matches(given: Option<&str>, token: &str) -> bool {
    let Some(given) = given else { return false };
    let (a, b) = (given.as_bytes(), token.as_bytes());
    a.len() == b.len() && a.iter().zip(b).fold(0u8, |acc, (x, y)| acc | (x ^ y)) == 0
}

/// One read that fails once `deadline` has passed (a socket timeout bounds one read only).
fn read_by(stream: &mut TcpStream, buf: &mut [u8], deadline: Instant) -> std::io::Result<usize> {
    let left = deadline.saturating_duration_since(Instant::now());
    if left.is_zero() {
        return Err(ErrorKind::TimedOut.into());
    }
    stream.set_read_timeout(Some(left))?;
    stream.read(buf)
}

/// Reads up to the end of the head by `deadline`; returns the head and any bytes read past it.
fn read_head(stream: &mut TcpStream, deadline: Instant) -> std::io::Result<Option<(Vec<u8>, Vec<u8>)>> {
    let mut buf = Vec::with_capacity(1024);
    let mut chunk = [0u8; 1024];
    loop {
        let n = read_by(stream, &mut chunk, deadline)?;
        if n == 0 {
            return Ok(None);
        }
        buf.extend_from_slice(&chunk[..n]);
        if let Some(end) = buf.windows(4).position(|w| w == b"\r\n\r\n") {
            let rest = buf.split_off(end + 4);
            return Ok(Some((buf, rest)));
        }
        if buf.len() > MAX_HEAD {
            return Ok(None);
        }
    }
}

/// Serves one connection; `head_read` takes it off the evictable list (false: evicted).
fn handle(mut stream: TcpStream, hub: &Arc<Hub>, head_read: impl FnOnce() -> bool) -> std::io::Result<()> {
    stream.set_write_timeout(Some(Duration::from_secs(30)))?;
    stream.set_nodelay(true)?;
    let head = read_head(&mut stream, Instant::now() + HEAD_DEADLINE);
    if !head_read() {
        return Ok(());
    }
    // Past the deadline: close without an answer (a client this slow may not read one).
    let Some((head, rest)) = head? else {
        return respond(&stream, 400, "text/plain", b"bad request\n");
    };
    let Some(req) = parse_head(&head) else {
        return respond(&stream, 400, "text/plain", b"bad request\n");
    };
    if !token_matches(req.token.as_deref(), &hub.token) {
        return respond(
            &stream,
            403,
            "text/plain",
            b"403 forbidden: open the URL that tetloc view printed, with its token\n",
        );
    }
    if (req.method.as_str(), req.path.as_str()) == ("PUT", "/state.json") {
        return put_state(stream, &req, rest, hub);
    }
    if req.method != "GET" {
        return respond(&stream, 405, "text/plain", b"only GET (and PUT /state.json)\n");
    }
    match req.path.as_str() {
        "/" | "/index.html" => respond(&stream, 200, "text/html; charset=utf-8", PAGE.as_bytes()),
        "/frame.png" | "/frame.json" => match hub.current_still(STILL_TIMEOUT) {
            Ok(f) if req.path == "/frame.png" => respond(&stream, 200, "image/png", f.image()),
            Ok(f) => respond(&stream, 200, "application/json", f.header()),
            Err(Still::NotYet) => respond(&stream, 503, "text/plain", b"no frame yet\n"),
            // Unprocessable: the view set cannot be drawn (the state says why it is not shown).
            Err(Still::Failed(why)) => respond(&stream, 422, "text/plain", format!("{why}\n").as_bytes()),
        },
        "/mesh.json" => respond(&stream, 200, "application/json", hub.describe().to_string().as_bytes()),
        "/state.json" => {
            let state = lock(&hub.input).state.to_json();
            respond(&stream, 200, "application/json", state.as_bytes())
        }
        "/ws" => match accept_websocket(&stream, &req) {
            Ok(()) => super::client::run(stream, rest, hub.clone()),
            Err(why) => respond(&stream, 400, "text/plain", format!("{why}\n").as_bytes()),
        },
        _ => respond(&stream, 404, "text/plain", b"not found\n"),
    }
}

/// `PUT /state.json`: a script sets the view (as a page does when its view stops moving).
fn put_state(mut stream: TcpStream, req: &Request, mut body: Vec<u8>, hub: &Hub) -> std::io::Result<()> {
    let max = tetloc_render::state::MAX_STATE_BYTES;
    let Some(len) = req.header("content-length").and_then(|l| l.trim().parse::<usize>().ok()).filter(|&l| l <= max)
    else {
        return respond(
            &stream,
            400,
            "text/plain",
            format!("need a Content-Length of at most {max} bytes\n").as_bytes(),
        );
    };
    let deadline = Instant::now() + BODY_DEADLINE;
    let mut chunk = [0u8; 16 * 1024];
    while body.len() < len {
        match read_by(&mut stream, &mut chunk, deadline)? {
            0 => return Err(ErrorKind::UnexpectedEof.into()),
            n => body.extend_from_slice(&chunk[..n]),
        }
    }
    body.truncate(len);
    let text = String::from_utf8_lossy(&body);
    let path = std::path::Path::new("PUT /state.json");
    // `check` before `ViewState::parse`'s validation: it names out-of-range camera numbers.
    let state = match serde_json::from_str::<tetloc_render::ViewState>(&text) {
        Ok(s) => super::client::check(hub, &s).map(|()| s).map_err(|e| format!("{}: {e}", path.display())),
        Err(_) => Err(tetloc_render::ViewState::parse(&text, path).err().map_or_else(String::new, |e| e.to_string())),
    };
    match state {
        Ok(s) => {
            let gen = hub.set_state(s, false, 0);
            respond(&stream, 200, "application/json", format!("{{\"gen\":{gen}}}\n").as_bytes())
        }
        Err(why) => respond(&stream, 400, "text/plain", format!("{why}\n").as_bytes()),
    }
}

/// Answers a WebSocket upgrade (RFC 6455) and checks that a browser's page is our own.
fn accept_websocket(mut stream: &TcpStream, req: &Request) -> Result<(), &'static str> {
    let upgrade = req.header("upgrade").is_some_and(|u| u.eq_ignore_ascii_case("websocket"));
    let key = req.header("sec-websocket-key").ok_or("not a WebSocket upgrade")?;
    if !upgrade || req.header("sec-websocket-version") != Some("13") {
        return Err("not a WebSocket (version 13) upgrade");
    }
    // A browser says where the page came from: only our own (the token guards the rest).
    if let (Some(origin), Some(host)) = (req.header("origin"), req.header("host")) {
        let from = origin.split_once("://").map_or(origin, |(_, h)| h);
        if from != host {
            return Err("the page is not this server's");
        }
    }
    let accept = tungstenite::handshake::derive_accept_key(key.trim().as_bytes());
    let answer = format!(
        "HTTP/1.1 101 Switching Protocols\r\nUpgrade: websocket\r\nConnection: Upgrade\r\nSec-WebSocket-Accept: {accept}\r\n\r\n"
    );
    stream.write_all(answer.as_bytes()).map_err(|_| "write failed")
}

fn respond(mut stream: &TcpStream, status: u16, content_type: &str, body: &[u8]) -> std::io::Result<()> {
    let reason = match status {
        200 => "OK",
        400 => "Bad Request",
        403 => "Forbidden",
        404 => "Not Found",
        405 => "Method Not Allowed",
        422 => "Unprocessable Content",
        _ => "Service Unavailable",
    };
    // The page allows nothing from elsewhere: its own script and style, frames as blobs.
    let head = format!(
        "HTTP/1.1 {status} {reason}\r\nContent-Type: {content_type}\r\nContent-Length: {}\r\nCache-Control: no-store\r\n\
         Content-Security-Policy: default-src 'none'; script-src 'unsafe-inline'; style-src 'unsafe-inline'; img-src 'self' blob: data:; connect-src 'self'\r\n\
         X-Content-Type-Options: nosniff\r\nReferrer-Policy: no-referrer\r\nConnection: close\r\n\r\n",
        body.len()
    );
    stream.write_all(head.as_bytes())?;
    stream.write_all(body)?;
    stream.flush()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn heads_and_tokens() {
        let r =
            parse_head(b"GET /frame.png?x=1&token=abc HTTP/1.1\r\nHost: h:1\r\nUpgrade: WebSocket\r\n\r\n").unwrap();
        assert_eq!((r.method.as_str(), r.path.as_str(), r.token.as_deref()), ("GET", "/frame.png", Some("abc")));
        assert_eq!(r.header("upgrade"), Some("WebSocket"));
        assert!(parse_head(b"GET / HTTP/1.1\r\n").is_none(), "incomplete");
        assert!(parse_head(b"\x00\x01garbage\r\n\r\n").is_none());
        assert!(token_matches(Some("abc"), "abc"));
        assert!(!token_matches(Some("abd"), "abc"));
        assert!(!token_matches(Some("ab"), "abc"));
        assert!(!token_matches(None, "abc"));
    }

    #[test]
    fn websocket_upgrades_are_checked() {
        let head = |extra: &str| {
            parse_head(
                format!(
                    "GET /ws?token=t HTTP/1.1\r\nHost: 127.0.0.1:5\r\nUpgrade: websocket\r\nSec-WebSocket-Version: 13\r\n{extra}\r\n"
                )
                .as_bytes(),
            )
            .unwrap()
        };
        let listener = TcpListener::bind("127.0.0.1:0").unwrap();
        let _client = TcpStream::connect(listener.local_addr().unwrap()).unwrap();
        let (server, _) = listener.accept().unwrap();
        assert_eq!(accept_websocket(&server, &head("")), Err("not a WebSocket upgrade"));
        let foreign = head("Sec-WebSocket-Key: dGhlIHNhbXBsZSBub25jZQ==\r\nOrigin: http://evil.example\r\n");
        assert_eq!(accept_websocket(&server, &foreign), Err("the page is not this server's"));
        let ours = head("Sec-WebSocket-Key: dGhlIHNhbXBsZSBub25jZQ==\r\nOrigin: http://127.0.0.1:5\r\n");
        assert_eq!(accept_websocket(&server, &ours), Ok(()));
    }
}
