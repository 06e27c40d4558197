//! The hub between the threads: the view state clients set, the raw frame the render
//! thread hands to the encoder, and the encoded frame the clients send. Each slot holds only
//! the newest value: a slow stage drops frames, it never queues them.

use rayon::prelude::*;
use std::sync::{Arc, Condvar, Mutex, MutexGuard};
use std::time::{Duration, Instant};
use tetloc_render as tr;

/// JPEG quality of frames while the view moves: it starts here and follows the bytes a
/// frame takes ([`JpegQuality`]).
const JPEG_QUALITY: u8 = 80;
const JPEG_QUALITY_RANGE: (u8, u8) = (40, 90);
/// Bytes a moving frame may take per megapixel (about 60 MB/s at 60 frames/s of 1024²:
/// loopback, an SSH tunnel or a LAN carries it; a slower link still gets the newest frame).
const JPEG_BYTES_PER_MEGAPIXEL: f64 = 1.0e6;

/// The quality of moving frames: lower when frames take more than their byte budget, higher
/// when they take less than half of it, 5 steps at a time.
pub struct JpegQuality(u8);

impl JpegQuality {
    pub fn new() -> JpegQuality {
        JpegQuality(JPEG_QUALITY)
    }
    pub fn get(&self) -> u8 {
        self.0
    }
    pub fn update(&mut self, bytes: usize, pixels: usize) {
        let budget = JPEG_BYTES_PER_MEGAPIXEL * pixels as f64 / 1e6;
        let (lo, hi) = JPEG_QUALITY_RANGE;
        if bytes as f64 > budget {
            self.0 = self.0.saturating_sub(5).max(lo);
        } else if (bytes as f64) < 0.5 * budget {
            self.0 = (self.0 + 5).min(hi);
        }
    }
}

/// What clients asked for.
pub struct Input {
    pub state: tr::ViewState,
    /// Bumped by every accepted state.
    pub gen: u64,
    /// The client that set it (0: the server).
    pub author: u64,
    /// The view is moving: small JPEG frames until it stops.
    pub moving: bool,
    pub last_event: Instant,
    /// The newest error of the render thread (a state it could not render), by generation.
    pub error: Option<(u64, String)>,
}

/// One rendered frame, not yet encoded: sRGB 8-bit RGB.
pub struct RawFrame {
    pub gen: u64,
    pub still: bool,
    pub width: u32,
    pub height: u32,
    pub rgb: Vec<u8>,
    pub march_ms: f64,
    pub gpu_ms: f64,
    /// The values the transfer function spans in this frame (the state's, else the field's
    /// range at the time step shown).
    pub range: (f32, f32),
    /// When the render thread took the state it shows (input-to-frame latency).
    pub started: Instant,
}

/// One encoded frame as a WebSocket message: a little-endian u32 length, a JSON header,
/// then the JPEG or PNG bytes.
pub struct Encoded {
    pub seq: u64,
    pub gen: u64,
    pub still: bool,
    pub message: tungstenite::Bytes,
    /// Where the image starts in `message`.
    pub image_at: usize,
}

impl Encoded {
    pub fn image(&self) -> &[u8] {
        &self.message[self.image_at..]
    }

    /// The JSON header (gen, size, range, timings).
    pub fn header(&self) -> &[u8] {
        &self.message[4..self.image_at]
    }
}

#[derive(Default)]
pub struct Published {
    pub seq: u64,
    pub latest: Option<Arc<Encoded>>,
    /// The newest still (PNG) frame, for `GET /frame.png`.
    pub still: Option<Arc<Encoded>>,
}

pub struct Hub {
    pub token: String,
    /// The `hello` message's `mesh` object: bounds, fields, backend, colormaps (set once
    /// the render thread has built its locator, before the URL is printed).
    describe: std::sync::OnceLock<serde_json::Value>,
    pub input: Mutex<Input>,
    pub input_changed: Condvar,
    raw: Mutex<Option<RawFrame>>,
    raw_ready: Condvar,
    pub out: Mutex<Published>,
    pub out_ready: Condvar,
    /// Open WebSocket clients, and the next client id.
    pub clients: Mutex<(usize, u64)>,
    /// What encoding a moving frame costs, in ns a pixel (the f64's bits; 0 until measured):
    /// the render thread sizes moving frames by the slower of its march and the encode, since
    /// the two run side by side and the slower sets the frame rate.
    jpeg_ns_per_pixel: std::sync::atomic::AtomicU64,
}

/// Locks a mutex whose holder may have panicked: the data (the newest frame or state) is
/// still the best there is.
pub fn lock<T>(m: &Mutex<T>) -> MutexGuard<'_, T> {
    m.lock().unwrap_or_else(|e| e.into_inner())
}

impl Hub {
    pub fn new(token: String, state: tr::ViewState) -> Hub {
        Hub {
            token,
            describe: std::sync::OnceLock::new(),
            input: Mutex::new(Input {
                state,
                gen: 1,
                author: 0,
                moving: false,
                last_event: Instant::now(),
                error: None,
            }),
            input_changed: Condvar::new(),
            raw: Mutex::new(None),
            raw_ready: Condvar::new(),
            out: Mutex::new(Published::default()),
            out_ready: Condvar::new(),
            clients: Mutex::new((0, 1)),
            jpeg_ns_per_pixel: std::sync::atomic::AtomicU64::new(0),
        }
    }

    /// The time encoding a moving frame of `pixels` would take, in ms (0 until one was encoded).
    pub fn jpeg_ms(&self, pixels: u64) -> f64 {
        let ns = f64::from_bits(self.jpeg_ns_per_pixel.load(std::sync::atomic::Ordering::Relaxed));
        ns * pixels as f64 / 1e6
    }

    /// Records a moving frame's encode (a running mean that follows the last few frames).
    fn record_jpeg(&self, pixels: u64, ms: f64) {
        use std::sync::atomic::Ordering::Relaxed;
        let now = ms * 1e6 / pixels.max(1) as f64;
        let old = f64::from_bits(self.jpeg_ns_per_pixel.load(Relaxed));
        let mean = if old == 0.0 { now } else { 0.7 * old + 0.3 * now };
        self.jpeg_ns_per_pixel.store(mean.to_bits(), Relaxed);
    }

    pub fn set_describe(&self, d: serde_json::Value) {
        let _ = self.describe.set(d);
    }

    pub fn describe(&self) -> &serde_json::Value {
        static NONE: serde_json::Value = serde_json::Value::Null;
        self.describe.get().unwrap_or(&NONE)
    }

    /// A client's new state (already validated); returns its generation.
    pub fn set_state(&self, state: tr::ViewState, moving: bool, author: u64) -> u64 {
        let mut i = lock(&self.input);
        i.state = state;
        i.gen += 1;
        let gen = i.gen;
        i.author = author;
        i.moving = moving;
        i.last_event = Instant::now();
        drop(i);
        self.input_changed.notify_all();
        // Clients waiting for frames also pass the new state on to the others.
        self.out_ready.notify_all();
        gen
    }

    /// The render thread hands a frame over, replacing one the encoder has not taken.
    pub fn put_raw(&self, f: RawFrame) {
        *lock(&self.raw) = Some(f);
        self.raw_ready.notify_one();
    }

    /// The still frame of the state current now, waiting up to `timeout` for it; or why the
    /// render thread could not draw that state (a step's file it could not read, say), since
    /// an older frame would show another view.
    pub fn current_still(&self, timeout: Duration) -> Result<Arc<Encoded>, Still> {
        let deadline = Instant::now() + timeout;
        let mut out = lock(&self.out);
        loop {
            let (gen, failed) = {
                let i = lock(&self.input);
                (i.gen, i.error.as_ref().filter(|(g, _)| *g == i.gen).map(|(_, e)| e.clone()))
            };
            if let Some(s) = out.still.as_ref().filter(|s| s.gen == gen) {
                return Ok(s.clone());
            }
            if let Some(e) = failed {
                return Err(Still::Failed(e));
            }
            let left = deadline.checked_duration_since(Instant::now()).ok_or(Still::NotYet)?;
            out = self
                .out_ready
                .wait_timeout(out, left.min(Duration::from_millis(50)))
                .unwrap_or_else(|e| e.into_inner())
                .0;
        }
    }
}

/// Why [`Hub::current_still`] has no frame.
#[derive(Debug)]
pub enum Still {
    /// None within the time allowed.
    NotYet,
    /// The current state could not be drawn: the render thread's error.
    Failed(String),
}

/// Starts the encode thread.
pub fn spawn_encoder(hub: Arc<Hub>) {
    std::thread::Builder::new()
        .name("view-encode".into())
        .spawn(move || {
            let mut quality = JpegQuality::new();
            loop {
                let raw = {
                    let mut slot = lock(&hub.raw);
                    loop {
                        if let Some(f) = slot.take() {
                            break f;
                        }
                        slot = hub.raw_ready.wait(slot).unwrap_or_else(|e| e.into_inner());
                    }
                };
                let seq = lock(&hub.out).seq + 1;
                let t = Instant::now();
                let enc = match encode(&raw, seq, quality.get()) {
                    Ok(e) => {
                        if !e.still {
                            let pixels = raw.width as usize * raw.height as usize;
                            hub.record_jpeg(pixels as u64, t.elapsed().as_secs_f64() * 1e3);
                            quality.update(e.image().len(), pixels);
                        }
                        Arc::new(e)
                    }
                    Err(e) => {
                        eprintln!("warning: view: cannot encode a frame: {e}");
                        continue;
                    }
                };
                let mut out = lock(&hub.out);
                out.seq = seq;
                if enc.still {
                    out.still = Some(enc.clone());
                }
                out.latest = Some(enc);
                drop(out);
                hub.out_ready.notify_all();
            }
        })
        .expect("spawning the encode thread");
}

/// Encodes a frame: PNG when still (lossless), JPEG of `quality` while moving.
pub fn encode(raw: &RawFrame, seq: u64, quality: u8) -> anyhow::Result<Encoded> {
    let t = Instant::now();
    let image = if raw.still { png(raw)? } else { jpeg(raw, quality)? };
    let encode_ms = t.elapsed().as_secs_f64() * 1e3;
    let header = serde_json::json!({
        "seq": seq,
        "gen": raw.gen,
        "still": raw.still,
        "format": if raw.still { "png" } else { "jpeg" },
        "quality": if raw.still { 100 } else { quality },
        "width": raw.width,
        "height": raw.height,
        "march_ms": raw.march_ms,
        "gpu_ms": raw.gpu_ms,
        "range": [raw.range.0, raw.range.1],
        "encode_ms": encode_ms,
        "bytes": image.len(),
        "latency_ms": raw.started.elapsed().as_secs_f64() * 1e3,
        // Wall-clock microseconds: a client on the same machine times the send from here.
        "encoded_at_us": std::time::SystemTime::now().duration_since(std::time::UNIX_EPOCH).map_or(0, |d| d.as_micros() as u64),
    })
    .to_string();
    let mut message = Vec::with_capacity(4 + header.len() + image.len());
    message.extend_from_slice(&(header.len() as u32).to_le_bytes());
    message.extend_from_slice(header.as_bytes());
    let image_at = message.len();
    message.extend_from_slice(&image);
    Ok(Encoded { seq, gen: raw.gen, still: raw.still, message: message.into(), image_at })
}

fn png(raw: &RawFrame) -> anyhow::Result<Vec<u8>> {
    let mut out = Vec::new();
    let mut enc = png::Encoder::new(&mut out, raw.width, raw.height);
    enc.set_color(png::ColorType::Rgb);
    enc.set_depth(png::BitDepth::Eight);
    enc.set_source_srgb(png::SrgbRenderingIntent::Perceptual);
    // Fast deflate: a still frame should follow the last event within ~150 ms.
    enc.set_compression(png::Compression::Fast);
    let mut w = enc.write_header()?;
    w.write_image_data(&raw.rgb)?;
    w.finish()?;
    Ok(out)
}

fn jpeg(raw: &RawFrame, quality: u8) -> anyhow::Result<Vec<u8>> {
    let (Ok(w), Ok(h)) = (u16::try_from(raw.width), u16::try_from(raw.height)) else {
        anyhow::bail!("a {}x{} frame is too large for JPEG", raw.width, raw.height);
    };
    let mut out = Vec::new();
    jpeg_encoder::Encoder::new(&mut out, quality).encode(&raw.rgb, w, h, jpeg_encoder::ColorType::Rgb)?;
    Ok(out)
}

/// sRGB 8-bit RGB of an image, in parallel (the same bytes as `Image::to_srgb8`).
pub fn srgb8(img: &tr::Image) -> Vec<u8> {
    let mut out = vec![0u8; img.pixels.len() * 3];
    out.par_chunks_mut(3 * 4096).zip(img.pixels.par_chunks(4096)).for_each(|(o, p)| {
        for (o, p) in o.chunks_mut(3).zip(p) {
            for k in 0..3 {
                o[k] = (tr::colorspace::linear_to_srgb(p[k]) * 255.0 + 0.5) as u8;
            }
        }
    });
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    fn raw(still: bool) -> RawFrame {
        let (width, height) = (40, 30);
        let rgb = (0..width * height * 3).map(|i| (i % 251) as u8).collect();
        RawFrame {
            gen: 3,
            still,
            width,
            height,
            rgb,
            march_ms: 1.0,
            gpu_ms: 0.5,
            range: (0.0, 1.0),
            started: Instant::now(),
        }
    }

    #[test]
    fn stills_are_lossless_png_and_moving_frames_jpeg() {
        let f = raw(true);
        let e = encode(&f, 7, 80).unwrap();
        let n = u32::from_le_bytes(e.message[..4].try_into().unwrap()) as usize;
        let header: serde_json::Value = serde_json::from_slice(&e.message[4..4 + n]).unwrap();
        assert_eq!((header["seq"].as_u64(), header["format"].as_str()), (Some(7), Some("png")));
        assert_eq!(e.image_at, 4 + n);
        let mut r = png::Decoder::new(std::io::Cursor::new(e.image())).read_info().unwrap();
        let mut buf = vec![0; r.output_buffer_size()];
        r.next_frame(&mut buf).unwrap();
        assert_eq!(buf, f.rgb, "a still frame is lossless");
        let m = encode(&raw(false), 8, 80).unwrap();
        let mut d = jpeg_decoder::Decoder::new(std::io::Cursor::new(m.image()));
        let px = d.decode().unwrap();
        assert_eq!(px.len(), f.rgb.len());
    }

    #[test]
    fn jpeg_quality_follows_the_byte_budget() {
        let mut q = JpegQuality::new();
        let mp = 1_000_000;
        q.update(3 * JPEG_BYTES_PER_MEGAPIXEL as usize, mp);
        assert_eq!(q.get(), JPEG_QUALITY - 5, "over budget: lower");
        for _ in 0..100 {
            q.update(3 * JPEG_BYTES_PER_MEGAPIXEL as usize, mp);
        }
        assert_eq!(q.get(), JPEG_QUALITY_RANGE.0);
        q.update((0.7 * JPEG_BYTES_PER_MEGAPIXEL) as usize, mp);
        assert_eq!(q.get(), JPEG_QUALITY_RANGE.0, "within budget: kept");
        for _ in 0..100 {
            q.update(1000, mp);
        }
        assert_eq!(q.get(), JPEG_QUALITY_RANGE.1);
    }

    #[test]
    fn srgb8_matches_the_png_writer() {
        let img = tr::Image { width: 3, height: 1, pixels: vec![[0.0, 0.5, 1.0], [0.2, 0.01, 0.9], [1.0, 1.0, 0.0]] };
        assert_eq!(srgb8(&img), img.to_srgb8());
    }
}
