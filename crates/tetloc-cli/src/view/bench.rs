//! `tetloc view-bench URL` (hidden): a viewer's client without a browser, for machines that
//! have none. It orbits the camera continuously (an input event every 1/`rate` s, as a
//! dragging mouse sends them; those due while a frame was decoded go as one), receives and
//! decodes every frame, acknowledges it as the page does, and after each orbit stops and
//! waits for the lossless still frame. It reports delivered frames/s, input-to-frame
//! latency (from an input to the first frame that shows it or a later input), still-frame
//! latency (from the last input to the still frame), and where a frame's time goes: march,
//! encode, send (from the end of encoding to the arrival here, over loopback on the same
//! clock) and decode.
//!
//! With `--time-steps P` it plays a series instead, as the page's play button does: every
//! step in turn, P times over, each sent as a stop and followed by its still frame. It
//! reports the step-to-still-frame latency and the steps shown a second.

use anyhow::{Context, Result};
use std::collections::BTreeMap;
use std::io::ErrorKind;
use std::net::TcpStream;
use std::time::{Duration, Instant};
use tetloc_render as tr;
use tungstenite::{Message, WebSocket};

/// Longest nap while nothing arrives (a sleep, unlike a socket's timeout, is not rounded up to
/// a kernel tick).
const IDLE: Duration = Duration::from_micros(250);

#[derive(clap::Args)]
pub struct BenchArgs {
    /// The URL `tetloc view` printed (http://HOST:PORT/?token=T).
    url: String,
    /// Seconds of each orbit.
    #[arg(long, default_value_t = 5.0)]
    seconds: f64,
    /// Orbits, each followed by a stop and its still frame.
    #[arg(long, default_value_t = 3)]
    orbits: u32,
    /// Input events a second while orbiting.
    #[arg(long, default_value_t = 120.0)]
    rate: f64,
    /// Degrees the camera turns per input event.
    #[arg(long, default_value_t = 1.0)]
    degrees: f64,
    /// Also write every frame's numbers here (CSV).
    #[arg(long)]
    frames_csv: Option<std::path::PathBuf>,
    /// Play the series' time steps this many times over instead of orbiting.
    #[arg(long, default_value_t = 0)]
    time_steps: u32,
}

/// One frame as received.
struct Frame {
    gen: u64,
    still: bool,
    bytes: usize,
    width: u64,
    height: u64,
    march_ms: f64,
    gpu_ms: f64,
    encode_ms: f64,
    send_ms: f64,
    decode_ms: f64,
    at: Instant,
}

pub fn run(a: BenchArgs) -> Result<()> {
    let rest = a.url.strip_prefix("http://").context("the URL must start with http://")?;
    let (host, query) = rest.split_once('/').context("no path in the URL")?;
    let token = query.split_once("token=").map(|(_, t)| t).context("no token in the URL")?;
    let stream = TcpStream::connect(host).with_context(|| format!("connecting to {host}"))?;
    stream.set_nodelay(true)?;
    let (mut ws, _) = tungstenite::client::client(format!("ws://{host}/ws?token={token}"), stream)
        .map_err(|e| anyhow::anyhow!("WebSocket handshake: {e}"))?;
    ws.get_mut().set_read_timeout(Some(Duration::from_millis(1)))?;
    let hello = loop {
        if let Message::Text(t) = ws.read()? {
            break serde_json::from_str::<serde_json::Value>(&t)?;
        }
    };
    let mut state: tr::ViewState = serde_json::from_value(hello["state"].clone())?;
    let mut gen = hello["gen"].as_u64().context("no gen in hello")?;
    // From here the socket never blocks: inputs go out on their schedule, whatever arrives (a
    // socket's read timeout is counted in kernel ticks, several milliseconds, and held the
    // inputs back to about the frame rate).
    ws.get_mut().set_nonblocking(true)?;
    if a.time_steps > 0 {
        return play(&mut ws, &hello, state, gen, a.time_steps);
    }
    let start = Instant::now();
    let mut sent: BTreeMap<u64, Instant> = BTreeMap::new();
    let mut frames: Vec<Frame> = Vec::new();
    let mut input_latency = Vec::new();
    let mut still_latency = Vec::new();
    let step = Duration::from_secs_f64(1.0 / a.rate);
    for _ in 0..a.orbits {
        let orbit_start = Instant::now();
        let mut next_input = Instant::now();
        while orbit_start.elapsed().as_secs_f64() < a.seconds {
            let now = Instant::now();
            if now >= next_input {
                // Events due while a frame was decoded go out as one, as a browser coalesces
                // mouse moves: the camera keeps its speed, inputs stay at `rate` or fewer.
                let due = 1 + ((now - next_input).as_secs_f64() / step.as_secs_f64()) as u32;
                turn(&mut state.camera, f64::from(due) * a.degrees.to_radians());
                send_state(&mut ws, &state, true)?;
                gen += 1;
                sent.insert(gen, Instant::now());
                next_input += step * due;
            }
            if !receive(&mut ws, &mut frames)? {
                std::thread::sleep(next_input.saturating_duration_since(Instant::now()).min(IDLE));
            }
        }
        // Stop: the page sends the last state as not moving (mouse up).
        send_state(&mut ws, &state, false)?;
        gen += 1;
        let stopped = Instant::now();
        sent.insert(gen, stopped);
        loop {
            if !receive(&mut ws, &mut frames)? {
                std::thread::sleep(IDLE);
            }
            if frames.last().is_some_and(|f| f.still && f.gen >= gen) {
                still_latency.push((frames.last().unwrap().at - stopped).as_secs_f64() * 1e3);
                break;
            }
            anyhow::ensure!(stopped.elapsed() < Duration::from_secs(120), "no still frame within 120 s");
        }
    }
    let elapsed = start.elapsed().as_secs_f64();
    // The frames of the view before the first input (the still the server had) say nothing.
    let first_input = *sent.values().next().context("no input sent")?;
    frames.retain(|f| f.at >= first_input);
    // Input-to-frame: each input, to the first frame that shows it or a later input.
    for (&g, &t) in &sent {
        if let Some(f) = frames.iter().find(|f| f.gen >= g && f.at >= t) {
            input_latency.push((f.at - t).as_secs_f64() * 1e3);
        }
    }
    let moving: Vec<&Frame> = frames.iter().filter(|f| !f.still).collect();
    let moving_seconds = a.seconds * a.orbits as f64;
    let mean = |v: &mut dyn Iterator<Item = f64>| {
        let v: Vec<f64> = v.collect();
        if v.is_empty() {
            f64::NAN
        } else {
            v.iter().sum::<f64>() / v.len() as f64
        }
    };
    let summary = serde_json::json!({
        "backend": hello["mesh"]["backend"],
        "tets": hello["mesh"]["tets"],
        "size": state.size,
        "seconds": elapsed,
        "inputs": sent.len(),
        "frames": frames.len(),
        "moving_frames": moving.len(),
        "moving_fps": moving.len() as f64 / moving_seconds,
        "moving_frame_pixels_mean": mean(&mut moving.iter().map(|f| (f.width * f.height) as f64)),
        "input_to_frame_ms": percentiles(&mut input_latency),
        "still_ms": percentiles(&mut still_latency),
        "moving_split_ms_mean": {
            "march": mean(&mut moving.iter().map(|f| f.march_ms)),
            "gpu": mean(&mut moving.iter().map(|f| f.gpu_ms)),
            "encode": mean(&mut moving.iter().map(|f| f.encode_ms)),
            "send": mean(&mut moving.iter().map(|f| f.send_ms)),
            "decode": mean(&mut moving.iter().map(|f| f.decode_ms)),
            "bytes": mean(&mut moving.iter().map(|f| f.bytes as f64)),
        },
        "still_split_ms_mean": {
            "march": mean(&mut frames.iter().filter(|f| f.still).map(|f| f.march_ms)),
            "encode": mean(&mut frames.iter().filter(|f| f.still).map(|f| f.encode_ms)),
            "send": mean(&mut frames.iter().filter(|f| f.still).map(|f| f.send_ms)),
            "decode": mean(&mut frames.iter().filter(|f| f.still).map(|f| f.decode_ms)),
            "bytes": mean(&mut frames.iter().filter(|f| f.still).map(|f| f.bytes as f64)),
        },
    });
    println!("{}", serde_json::to_string_pretty(&summary)?);
    if let Some(path) = &a.frames_csv {
        let mut csv = String::from("t_ms,gen,still,width,height,bytes,march_ms,gpu_ms,encode_ms,send_ms,decode_ms\n");
        for f in &frames {
            csv += &format!(
                "{:.3},{},{},{},{},{},{:.3},{:.3},{:.3},{:.3},{:.3}\n",
                (f.at - start).as_secs_f64() * 1e3,
                f.gen,
                f.still,
                f.width,
                f.height,
                f.bytes,
                f.march_ms,
                f.gpu_ms,
                f.encode_ms,
                f.send_ms,
                f.decode_ms
            );
        }
        std::fs::write(path, csv).with_context(|| format!("writing {}", path.display()))?;
    }
    let _ = ws.close(None);
    Ok(())
}

/// Plays every time step `passes` times over, each a stop waited for until its still frame;
/// prints the latencies.
fn play(
    ws: &mut WebSocket<TcpStream>,
    hello: &serde_json::Value,
    mut state: tr::ViewState,
    mut gen: u64,
    passes: u32,
) -> Result<()> {
    let n = hello["mesh"]["times"].as_array().map_or(0, Vec::len);
    anyhow::ensure!(n >= 2, "--time-steps: the mesh has {n} time steps (a series of two or more is needed)");
    // As the page does: the colours' range pinned to the first step's.
    if state.tf.range.is_none() {
        let fields = hello["mesh"]["fields"].as_array().context("no fields in hello")?;
        let field = fields.iter().find(|f| f["name"] == state.field.as_str());
        let range = field.and_then(|f| f["range"].as_array()).context("no range of the field shown")?;
        let at = |k: usize| range.get(k).and_then(|v| v.as_f64()).map(|v| v as f32);
        state.tf.range = Some([at(0).context("range")?, at(1).context("range")?]);
    }
    let (start, mut frames, mut latency) = (Instant::now(), Vec::new(), Vec::new());
    // From the step after the one shown, so that every input changes the step.
    let shown = state.time_step.unwrap_or(0);
    for _ in 0..passes {
        for k in (1..=n).map(|k| (shown + k) % n) {
            state.time_step = Some(k);
            send_state(ws, &state, false)?;
            gen += 1;
            let sent = Instant::now();
            loop {
                if !receive(ws, &mut frames)? {
                    std::thread::sleep(IDLE);
                }
                if frames.last().is_some_and(|f: &Frame| f.still && f.gen >= gen) {
                    latency.push((frames.last().unwrap().at - sent).as_secs_f64() * 1e3);
                    break;
                }
                anyhow::ensure!(sent.elapsed() < Duration::from_secs(600), "no still frame of step {k} within 600 s");
            }
        }
    }
    let elapsed = start.elapsed().as_secs_f64();
    let summary = serde_json::json!({
        "backend": hello["mesh"]["backend"],
        "tets": hello["mesh"]["tets"],
        "size": state.size,
        "time_steps": n,
        "steps_shown": latency.len(),
        "steps_per_second": latency.len() as f64 / elapsed,
        "step_to_still_ms": percentiles(&mut latency),
    });
    println!("{}", serde_json::to_string_pretty(&summary)?);
    let _ = ws.close(None);
    Ok(())
}

/// Turns the eye about the target, around the camera's up axis.
fn turn(c: &mut tr::CameraState, angle: f64) {
    let v: [f64; 3] = std::array::from_fn(|k| c.eye[k] - c.target[k]);
    let n = c.up.iter().map(|x| x * x).sum::<f64>().sqrt();
    let k = c.up.map(|x| x / n);
    let (cos, sin) = (angle.cos(), angle.sin());
    let kxv = [k[1] * v[2] - k[2] * v[1], k[2] * v[0] - k[0] * v[2], k[0] * v[1] - k[1] * v[0]];
    let kdv: f64 = (0..3).map(|i| k[i] * v[i]).sum();
    c.eye = std::array::from_fn(|i| c.target[i] + v[i] * cos + kxv[i] * sin + k[i] * kdv * (1.0 - cos));
}

fn send_state(ws: &mut WebSocket<TcpStream>, state: &tr::ViewState, moving: bool) -> Result<()> {
    let m = serde_json::json!({ "type": "state", "state": state, "moving": moving });
    send(ws, Message::text(m.to_string()))
}

/// Sends on the non-blocking socket: what does not fit now stays queued in `ws` and goes
/// with a later send or read.
fn send(ws: &mut WebSocket<TcpStream>, m: Message) -> Result<()> {
    match ws.send(m) {
        Err(tungstenite::Error::Io(e)) if e.kind() == ErrorKind::WouldBlock => Ok(()),
        r => Ok(r?),
    }
}

/// Reads what has arrived without waiting, decodes frames and acknowledges them; says
/// whether anything came.
fn receive(ws: &mut WebSocket<TcpStream>, frames: &mut Vec<Frame>) -> Result<bool> {
    let mut any = false;
    loop {
        let m = match ws.read() {
            Ok(m) => m,
            Err(tungstenite::Error::Io(e)) if e.kind() == ErrorKind::WouldBlock => return Ok(any),
            Err(e) => return Err(e.into()),
        };
        any = true;
        let at = Instant::now();
        let data = match m {
            Message::Binary(b) => b,
            Message::Text(t) if t.contains("\"error\"") => anyhow::bail!("the server says: {t}"),
            _ => continue,
        };
        let n = u32::from_le_bytes(data[..4].try_into()?) as usize;
        let h: serde_json::Value = serde_json::from_slice(&data[4..4 + n])?;
        let image = &data[4 + n..];
        let t = Instant::now();
        let still = h["still"].as_bool().unwrap_or(false);
        if still {
            let mut r = png::Decoder::new(std::io::Cursor::new(image)).read_info()?;
            let mut buf = vec![0; r.output_buffer_size()];
            r.next_frame(&mut buf)?;
        } else {
            jpeg_decoder::Decoder::new(image).decode()?;
        }
        let decode_ms = t.elapsed().as_secs_f64() * 1e3;
        let now_us = std::time::SystemTime::now().duration_since(std::time::UNIX_EPOCH)?.as_micros() as f64;
        let num = |k: &str| h[k].as_f64().unwrap_or(f64::NAN);
        frames.push(Frame {
            gen: h["gen"].as_u64().unwrap_or(0),
            still,
            bytes: image.len(),
            width: h["width"].as_u64().unwrap_or(0),
            height: h["height"].as_u64().unwrap_or(0),
            march_ms: num("march_ms"),
            gpu_ms: num("gpu_ms"),
            encode_ms: num("encode_ms"),
            send_ms: (now_us - num("encoded_at_us")) / 1e3 - (at.elapsed().as_secs_f64() * 1e3),
            decode_ms,
            at,
        });
        send(ws, Message::text(serde_json::json!({ "type": "ack", "seq": h["seq"] }).to_string()))?;
    }
}

/// Median, 90th and 99th percentiles and the mean.
fn percentiles(v: &mut [f64]) -> serde_json::Value {
    if v.is_empty() {
        return serde_json::Value::Null;
    }
    v.sort_by(f64::total_cmp);
    let at = |p: f64| v[((v.len() - 1) as f64 * p).round() as usize];
    serde_json::json!({
        "n": v.len(),
        "p50": at(0.5),
        "p90": at(0.9),
        "p99": at(0.99),
        "mean": v.iter().sum::<f64>() / v.len() as f64,
    })
}
