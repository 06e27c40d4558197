//! Whole jobs on top of [`Renderer`]: images and orbits to files, frame-rate measurement,
//! and comparing two backends on the same frame.

use crate::error::{RenderError, Result};
use crate::image::{psnr, GifWriter, Image};
use crate::render::{FrameStats, Marcher, Renderer};
use std::path::{Path, PathBuf};
use std::time::Instant;

/// What [`render_to_file`] wrote.
#[derive(Clone, Debug)]
pub struct RenderReport {
    pub files: Vec<PathBuf>,
    /// One entry per frame.
    pub frames: Vec<FrameStats>,
}

impl RenderReport {
    pub fn total(&self) -> FrameStats {
        FrameStats::sum(&self.frames)
    }
}

enum Output {
    Png,
    Gif,
}

fn output_kind(out: &Path) -> Result<Output> {
    match tetloc_io::output::extension(out).as_str() {
        "png" => Ok(Output::Png),
        "gif" => Ok(Output::Gif),
        _ => Err(RenderError::Invalid(format!("{}: the output file must end in .png or .gif", out.display()))),
    }
}

/// The files [`render_to_file`] will write for `out` and `frames` frames (one PNG, numbered
/// PNGs, or one GIF), each checked before any rendering: extension, directory, permission.
pub fn check_outputs(out: &Path, frames: u32) -> Result<Vec<PathBuf>> {
    let files = match output_kind(out)? {
        Output::Png if frames > 1 => (0..frames).map(|i| frame_path(out, i)).collect(),
        _ => vec![out.to_path_buf()],
    };
    for f in &files {
        tetloc_io::output::check_output(f, &["png", "gif"])?;
    }
    Ok(files)
}

/// `out_0000.png` for frame 0 of `out.png`.
pub fn frame_path(out: &Path, frame: u32) -> PathBuf {
    let stem = out.file_stem().map(|s| s.to_string_lossy().into_owned()).unwrap_or_default();
    let ext = out.extension().map(|e| e.to_string_lossy().into_owned()).unwrap_or_else(|| "png".into());
    out.with_file_name(format!("{stem}_{frame:04}.{ext}"))
}

/// Renders `options().frames` frames and writes them: one PNG at `out`, numbered PNGs
/// (`out_0000.png`, ...) for an orbit, or one animated GIF when `out` ends in `.gif`.
pub fn render_to_file(renderer: &Renderer, locator: &mut dyn Marcher, out: &Path) -> Result<RenderReport> {
    let kind = output_kind(out)?;
    let o = renderer.options();
    let n = o.frames;
    let mut report = RenderReport { files: Vec::new(), frames: Vec::new() };
    let mut gif = match kind {
        // A whole orbit takes about 4 s, however many frames it has.
        Output::Gif => Some(GifWriter::create(out, o.width, o.height, (400 / n).clamp(2, 100) as u16)?),
        Output::Png => None,
    };
    for i in 0..n {
        let (img, stats) = renderer.render(locator, &renderer.camera(i))?;
        report.frames.push(stats);
        match &mut gif {
            Some(g) => g.add(&img)?,
            None => {
                let path = if n == 1 { out.to_path_buf() } else { frame_path(out, i) };
                img.write_png(&path)?;
                report.files.push(path);
            }
        }
    }
    if let Some(g) = gif {
        g.finish()?;
        report.files.push(out.to_path_buf());
    }
    Ok(report)
}

/// Frame rate of one backend (the right-hand columns of the paper's Table 1).
#[derive(Clone, Debug)]
pub struct FpsReport {
    pub backend: String,
    pub width: u32,
    pub height: u32,
    /// Frames timed (after one untimed warm-up frame).
    pub frames: u32,
    /// Wall-clock time of the frames, and frames per second by it.
    pub seconds: f64,
    pub fps: f64,
    /// The GPU marcher: GPU time of the frames (timestamps around each march), and frames
    /// per second by it — the frame rate without the image download.
    pub gpu_seconds: Option<f64>,
    pub gpu_fps: Option<f64>,
    pub samples_per_frame: f64,
    /// Share of the time spent in `locator.sample`.
    pub sample_fraction: f64,
}

impl std::fmt::Display for FpsReport {
    /// e.g. `cpu: 3.21 FPS at 1024x1024 (12.3 M samples a frame, 85 % in the locator)`, or
    /// `soft-bvh: 142.10 FPS at 1024x1024 on the GPU (12.3 M samples a frame; 20.2 FPS by the
    /// wall clock, downloads and untimed marches included)`.
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        if let Some(gpu_fps) = self.gpu_fps {
            return write!(
                f,
                "{}: {:.2} FPS at {}x{} on the GPU ({:.1} M samples a frame; {:.2} FPS by the wall clock, downloads and untimed marches included)",
                self.backend,
                gpu_fps,
                self.width,
                self.height,
                self.samples_per_frame / 1e6,
                self.fps
            );
        }
        write!(
            f,
            "{}: {:.2} FPS at {}x{} ({:.1} M samples a frame, {:.0} % in the locator)",
            self.backend,
            self.fps,
            self.width,
            self.height,
            self.samples_per_frame / 1e6,
            100.0 * self.sample_fraction
        )
    }
}

/// Renders warm-up frames (at least one, and for at least `WARMUP_SECONDS`, so that a GPU's
/// clocks have ramped up), then `frames` frames of an orbit, and reports frames per second.
pub fn measure_fps(renderer: &Renderer, locator: &mut dyn Marcher, frames: u32) -> Result<FpsReport> {
    if frames == 0 {
        return Err(RenderError::Invalid("measure_fps needs at least one frame".into()));
    }
    let warm = Instant::now();
    while {
        renderer.render(locator, &renderer.orbit_camera(0, frames))?;
        warm.elapsed().as_secs_f64() < WARMUP_SECONDS
    } {}
    let start = Instant::now();
    let mut stats = Vec::with_capacity(frames as usize);
    for i in 0..frames {
        stats.push(renderer.render(locator, &renderer.orbit_camera(i, frames))?.1);
    }
    let seconds = start.elapsed().as_secs_f64();
    let total = FrameStats::sum(&stats);
    let o = renderer.options();
    Ok(FpsReport {
        backend: locator.name().to_string(),
        width: o.width,
        height: o.height,
        frames,
        seconds,
        fps: frames as f64 / seconds,
        gpu_seconds: (total.gpu_seconds > 0.0).then_some(total.gpu_seconds),
        gpu_fps: (total.gpu_seconds > 0.0).then(|| frames as f64 / total.gpu_seconds),
        samples_per_frame: total.samples as f64 / frames as f64,
        sample_fraction: total.sample_seconds / seconds,
    })
}

/// Least time `measure_fps` renders before it starts timing.
pub const WARMUP_SECONDS: f64 = 0.5;

/// The same frame rendered with two backends.
#[derive(Clone, Debug)]
pub struct Comparison {
    pub psnr_db: f64,
    pub images: [Image; 2],
    pub stats: [FrameStats; 2],
}

/// Renders frame 0 with `a` and with `b`; backends that compute the same thing give images
/// whose PSNR is high (infinite when identical).
pub fn compare_locators(renderer: &Renderer, a: &mut dyn Marcher, b: &mut dyn Marcher) -> Result<Comparison> {
    let cam = renderer.camera(0);
    let (ia, sa) = renderer.render(a, &cam)?;
    let (ib, sb) = renderer.render(b, &cam)?;
    Ok(Comparison { psnr_db: psnr(&ia, &ib)?, images: [ia, ib], stats: [sa, sb] })
}
