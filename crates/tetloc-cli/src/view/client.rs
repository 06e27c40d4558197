//! One WebSocket client: its input in, the newest frame out.
//!
//! Frames go out only while the client has fewer than [`MAX_IN_FLIGHT`] unacknowledged
//! ones; frames published in between are skipped, so a slow client sees the newest view,
//! late, rather than a queue of old ones. The socket is non-blocking and polled every
//! [`POLL`]: one thread per client reads and writes without a second thread racing it for
//! the socket.
//!
//! Hostile input closes this client only: a message that is not JSON of the protocol, one
//! over [`MAX_MESSAGE`] bytes, or more than [`RATE`] messages a second (bursts of [`BURST`]).
//! A state that parses but cannot be shown (an unknown field, a bad range) is answered with
//! an error message and the connection stays.

use super::frames::{lock, Hub};
use serde::Deserialize;
use std::io::{ErrorKind, Read};
use std::net::TcpStream;
use std::sync::Arc;
use std::time::{Duration, Instant};
use tetloc_render as tr;
use tungstenite::protocol::frame::coding::CloseCode;
use tungstenite::protocol::{CloseFrame, Role, WebSocketConfig};
use tungstenite::{Message, WebSocket};

/// Largest message a client may send (a view state with a ParaView preset inside).
pub const MAX_MESSAGE: usize = tr::state::MAX_STATE_BYTES;
/// Messages a second a client may send on average, and in one burst.
pub const RATE: f64 = 240.0;
pub const BURST: f64 = 240.0;
/// Frames sent and not yet acknowledged.
pub const MAX_IN_FLIGHT: usize = 2;
/// Most WebSocket clients at once.
pub const MAX_CLIENTS: usize = 16;
const POLL: Duration = Duration::from_millis(2);

/// What a client sends.
#[derive(Deserialize)]
#[serde(tag = "type", rename_all = "lowercase")]
enum ClientMessage {
    /// The whole view state; `moving` while a drag goes on.
    State { state: Box<tr::ViewState>, moving: bool },
    /// The client has shown frame `seq`.
    Ack { seq: u64 },
}

/// Messages a second, refilled continuously up to a burst.
struct RateLimit {
    tokens: f64,
    at: Instant,
}

impl RateLimit {
    fn new() -> RateLimit {
        RateLimit { tokens: BURST, at: Instant::now() }
    }
    fn take(&mut self) -> bool {
        let now = Instant::now();
        self.tokens = (self.tokens + RATE * (now - self.at).as_secs_f64()).min(BURST);
        self.at = now;
        self.tokens -= 1.0;
        self.tokens >= 0.0
    }
}

/// Counts the client in and out of `hub.clients`.
struct Registration<'a>(&'a Hub);

impl Drop for Registration<'_> {
    fn drop(&mut self) {
        lock(&self.0.clients).0 -= 1;
    }
}

/// Serves one client after its handshake; `rest` holds bytes read past the request head.
pub fn run(stream: TcpStream, rest: Vec<u8>, hub: Arc<Hub>) -> std::io::Result<()> {
    let config = WebSocketConfig::default().max_message_size(Some(MAX_MESSAGE)).max_frame_size(Some(MAX_MESSAGE));
    let mut ws = WebSocket::from_partially_read(stream, rest, Role::Server, Some(config));
    let id = {
        let mut c = lock(&hub.clients);
        if c.0 >= MAX_CLIENTS {
            drop(c);
            return close(&mut ws, CloseCode::Again, "too many viewers");
        }
        c.0 += 1;
        c.1 += 1;
        c.1
    };
    let _registered = Registration(&hub);
    ws.get_mut().set_nonblocking(true)?;
    let (mut seen_gen, hello) = {
        let i = lock(&hub.input);
        (i.gen, serde_json::json!({ "type": "hello", "mesh": hub.describe(), "state": i.state, "gen": i.gen }))
    };
    send(&mut ws, Message::text(hello.to_string()))?;
    let mut limit = RateLimit::new();
    let (mut sent, mut error_seen) = (0u64, 0u64);
    // Frames sent and not yet acknowledged, oldest first.
    let mut in_flight = std::collections::VecDeque::new();
    loop {
        // Input.
        loop {
            let text = match ws.read() {
                Ok(Message::Text(t)) => t,
                Ok(Message::Binary(_)) => {
                    return close(&mut ws, CloseCode::Unsupported, "binary messages are not read")
                }
                Ok(Message::Close(_)) => return flush(&mut ws),
                Ok(_) => continue,
                Err(tungstenite::Error::Io(e)) if e.kind() == ErrorKind::WouldBlock => break,
                Err(tungstenite::Error::Capacity(_)) => return close(&mut ws, CloseCode::Size, "message too large"),
                Err(_) => return Ok(()),
            };
            if !limit.take() {
                return close(&mut ws, CloseCode::Policy, "too many messages");
            }
            match serde_json::from_str::<ClientMessage>(&text) {
                Err(_) => return close(&mut ws, CloseCode::Policy, "not a message of this viewer"),
                Ok(ClientMessage::Ack { seq }) => in_flight.retain(|&s| s > seq),
                Ok(ClientMessage::State { state, moving }) => match check(&hub, &state) {
                    Ok(()) => {
                        // The generation frames of this state will carry.
                        let gen = hub.set_state(*state, moving, id);
                        send(&mut ws, Message::text(format!(r#"{{"type":"accepted","gen":{gen}}}"#)))?;
                    }
                    Err(why) => {
                        let m = serde_json::json!({ "type": "error", "message": why, "rejected": true });
                        send(&mut ws, Message::text(m.to_string()))?;
                    }
                },
            }
        }
        // Another client's state, and errors of the render thread.
        let (news, error) = {
            let i = lock(&hub.input);
            let news = (i.gen > seen_gen && i.author != id)
                .then(|| serde_json::json!({ "type": "state", "state": i.state, "gen": i.gen }).to_string());
            seen_gen = seen_gen.max(i.gen);
            let error = i.error.as_ref().filter(|(g, _)| *g > error_seen).cloned();
            (news, error)
        };
        if let Some(n) = news {
            send(&mut ws, Message::text(n))?;
        }
        if let Some((g, message)) = error {
            error_seen = g;
            send(&mut ws, Message::text(serde_json::json!({ "type": "error", "message": message }).to_string()))?;
        }
        // The newest frame, if the client keeps up.
        let latest = lock(&hub.out).latest.clone().filter(|f| f.seq > sent);
        if let (Some(f), true) = (latest, in_flight.len() < MAX_IN_FLIGHT) {
            sent = f.seq;
            in_flight.push_back(sent);
            send(&mut ws, Message::Binary(f.message.clone()))?;
        }
        flush(&mut ws)?;
        let out = lock(&hub.out);
        drop(hub.out_ready.wait_timeout(out, POLL).unwrap_or_else(|e| e.into_inner()));
    }
}

/// Checks a state a client sent: valid, of a size the viewer draws, and its field one of
/// the mesh's.
pub fn check(hub: &Hub, state: &tr::ViewState) -> Result<(), String> {
    check_camera(&state.camera)?;
    state.validate().map_err(|e| e.to_string())?;
    super::scene::check_size(state.size)?;
    let known =
        hub.describe()["fields"].as_array().is_some_and(|f| f.iter().any(|f| f["name"] == state.field.as_str()));
    if !known {
        return Err(format!("no field '{}'", state.field));
    }
    if let Some(k) = state.time_step {
        let n = hub.describe()["times"].as_array().map_or(0, Vec::len);
        let source = hub.describe()["source"].as_str().unwrap_or("the mesh").to_string();
        tetloc_core::mesh::steps::check_step(&source, n, k).map_err(|e| e.to_string())?;
    }
    Ok(())
}

/// Largest camera coordinate: the camera is placed in float32, and the length of a
/// difference of points must not overflow there (3·(2·1e18)² < f32::MAX ≈ 3.4e38).
const MAX_CAMERA_COORDINATE: f64 = 1e18;

/// Names a camera number that float32 cannot hold or compute with (validation would
/// otherwise blame "eye equals target" on the overflow).
fn check_camera(c: &tr::CameraState) -> Result<(), String> {
    for (name, v) in [("eye", c.eye), ("target", c.target), ("up", c.up)] {
        let Some(x) = v.into_iter().find(|x| x.is_nan() || x.abs() > MAX_CAMERA_COORDINATE) else { continue };
        let why = if !x.is_finite() {
            "is not a finite number".to_string()
        } else if x.abs() > f64::from(f32::MAX) {
            "is out of float32 range".to_string()
        } else {
            format!("overflows float32 arithmetic (coordinates must be within ±{MAX_CAMERA_COORDINATE:e})")
        };
        return Err(format!("camera {name} {v:?}: {x:e} {why}"));
    }
    Ok(())
}

/// Sends, leaving what does not fit in the socket buffered for a later flush.
fn send(ws: &mut WebSocket<TcpStream>, m: Message) -> std::io::Result<()> {
    match ws.send(m) {
        Ok(()) => Ok(()),
        Err(tungstenite::Error::Io(e)) if e.kind() == ErrorKind::WouldBlock => Ok(()),
        Err(e) => Err(std::io::Error::other(e)),
    }
}

fn flush(ws: &mut WebSocket<TcpStream>) -> std::io::Result<()> {
    match ws.flush() {
        Ok(()) => Ok(()),
        Err(tungstenite::Error::Io(e)) if e.kind() == ErrorKind::WouldBlock => Ok(()),
        Err(tungstenite::Error::ConnectionClosed) => Ok(()),
        Err(e) => Err(std::io::Error::other(e)),
    }
}

/// Closes this client with a reason; the others go on. What the client still sends is
/// read and dropped for a moment, so that the close frame reaches it (closing a socket with
/// unread data would reset the connection instead).
fn close(ws: &mut WebSocket<TcpStream>, code: CloseCode, reason: &'static str) -> std::io::Result<()> {
    let _ = ws.get_mut().set_nonblocking(false);
    let _ = ws.close(Some(CloseFrame { code, reason: reason.into() }));
    let _ = ws.flush();
    let s = ws.get_mut();
    let _ = s.shutdown(std::net::Shutdown::Write);
    let _ = s.set_read_timeout(Some(Duration::from_millis(200)));
    let (deadline, mut sink) = (Instant::now() + Duration::from_secs(2), [0u8; 16 * 1024]);
    while Instant::now() < deadline && matches!(s.read(&mut sink), Ok(n) if n > 0) {}
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rate_limit_allows_a_burst_then_refuses() {
        let mut r = RateLimit::new();
        let allowed = (0..1000).take_while(|_| r.take()).count();
        assert!((BURST as usize..BURST as usize + 5).contains(&allowed), "{allowed}");
    }

    #[test]
    fn camera_numbers_out_of_float32_reach_are_named() {
        let c = |eye: f64, target: f64| tr::CameraState {
            eye: [eye, 1.0, 2.0],
            target: [target, 0.0, 0.0],
            up: [0.0, 0.0, 1.0],
            zoom: 1.0,
        };
        assert_eq!(check_camera(&c(3.0, 0.0)), Ok(()));
        assert_eq!(check_camera(&c(-1e17, 1e17)), Ok(()));
        let e = check_camera(&c(1e39, 0.0)).unwrap_err();
        assert!(e.contains("eye") && e.contains("1e39") && e.contains("out of float32 range"), "{e}");
        let e = check_camera(&c(3.0, 1e30)).unwrap_err();
        assert!(e.contains("target") && e.contains("overflows float32"), "{e}");
        let e = check_camera(&c(f64::NAN, 0.0)).unwrap_err();
        assert!(e.contains("not a finite number"), "{e}");
    }

    #[test]
    fn messages_parse_or_fail() {
        assert!(matches!(serde_json::from_str(r#"{"type":"ack","seq":4}"#), Ok(ClientMessage::Ack { seq: 4 })));
        assert!(serde_json::from_str::<ClientMessage>(r#"{"type":"open","path":"/etc/passwd"}"#).is_err());
        assert!(serde_json::from_str::<ClientMessage>(r#"{"type":"state","state":{},"moving":true}"#).is_err());
    }
}
