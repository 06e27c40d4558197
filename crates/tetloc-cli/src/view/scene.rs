//! The render thread: the locator, the marcher and the renderer of the view state current
//! now. A camera move renders with what there is; a transfer-function or step edit rebuilds
//! the renderer (the occupancy grid and the surface are kept) and re-uploads the table; a
//! field change builds a new locator.

use super::frames::{lock, Hub, RawFrame};
use crate::backend::BackendOptions;
use crate::render::{build_marcher, check_samples_per_ray, kept_or_built, step_renderer, AnyMarcher};
use crate::time_steps::Series;
use anyhow::Result;
use std::sync::Arc;
use std::time::{Duration, Instant};
use tetloc_core::locate::{Points, Values};
use tetloc_core::mesh::steps::no_steps;
use tetloc_core::{BatchLocator, Mesh, Result as CoreResult};
use tetloc_render as tr;

/// With no event for this long, a moving view gets its full-size lossless frame.
const QUIET: Duration = Duration::from_millis(80);
/// Frame time (the slower of march and encode) that moving frames are sized for: 60 frames/s
/// with room to spare.
const TARGET_MS: f64 = 14.0;
/// Smallest fraction of the still size a moving frame is rendered at, per side.
const MIN_SCALE: f64 = 0.125;
/// Most pixels a viewer frame may have: 2^22 (2048², 2560x1440 fits). A host render takes
/// about 130 bytes a pixel (rays, their march state, the image: 0.55 GB measured at 2048²;
/// 8192² took 9 GB), and a GPU render cannot be stopped midway: one state must not ask more.
/// `tetloc render` draws larger images.
pub const MAX_FRAME_PIXELS: u64 = 1 << 22;

/// Refuses a frame size over [`MAX_FRAME_PIXELS`].
pub fn check_size([w, h]: [u32; 2]) -> Result<(), String> {
    if u64::from(w) * u64::from(h) > MAX_FRAME_PIXELS {
        return Err(format!(
            "size {w}x{h}: a viewer frame has at most {MAX_FRAME_PIXELS} pixels (2048x2048); \
             `tetloc render` draws larger images"
        ));
    }
    Ok(())
}

pub struct Scene {
    mesh: Arc<Mesh>,
    /// The file's time steps (`None`: a snapshot) and the one shown.
    series: Option<Series>,
    time_step: usize,
    backend: String,
    opts: BackendOptions,
    renderer: tr::Renderer,
    /// `None` only while a new one is built (the old one is dropped first, to free its memory).
    marcher: Option<AnyMarcher>,
    /// The marcher's name (the backend `auto` chose).
    marcher_name: String,
}

impl Scene {
    /// `mesh` is `series`' step `state.time_step` (the first when `None`).
    pub fn new(
        mesh: Arc<Mesh>,
        series: Option<Series>,
        backend: &str,
        opts: BackendOptions,
        state: &tr::ViewState,
    ) -> Result<Scene> {
        let renderer = tr::Renderer::new(mesh.clone(), &state.field, &state.render_options()?)?;
        check_samples_per_ray(&mesh, renderer.step())?;
        let marcher = build_marcher(&opts, &mesh, backend, &renderer, false)?;
        let marcher_name = tr::Marcher::name(&marcher).to_string();
        Ok(Scene {
            mesh,
            series,
            time_step: state.time_step.unwrap_or(0),
            backend: backend.to_string(),
            opts,
            renderer,
            marcher: Some(marcher),
            marcher_name,
        })
    }

    /// Shows time step `k`: the mesh with its fields, a renderer of it (grid and surface
    /// kept), and the marcher given the step's fields (its search structures kept) or, where
    /// it cannot take them, a new one.
    fn show_step(&mut self, k: usize, field: &str, opts: &tr::RenderOptions) -> Result<()> {
        let Some(series) = &self.series else {
            return Err(no_steps(&self.mesh.info.source, k).into());
        };
        // Unknown until the step is shown: a failure below leaves the next state to rebuild.
        self.time_step = usize::MAX;
        let (mesh, renderer) = step_renderer(series, k, &self.renderer, field, opts)?;
        let (opts, backend) = (&self.opts, &self.backend);
        kept_or_built(&mut self.marcher, &renderer, || build_marcher(opts, &mesh, backend, &renderer, false))?;
        (self.mesh, self.renderer, self.time_step) = (mesh, renderer, k);
        Ok(())
    }

    pub fn marcher_name(&self) -> &str {
        &self.marcher_name
    }

    /// Makes the renderer and marcher show `state`.
    fn apply(&mut self, state: &tr::ViewState) -> Result<()> {
        let want = state.render_options()?;
        let step = state.time_step.unwrap_or(0);
        if step != self.time_step {
            self.show_step(step, &state.field, &want)?;
        }
        let have = self.renderer.options();
        let same_look = tr::RenderOptions {
            camera: have.camera,
            zoom: have.zoom,
            width: have.width,
            height: have.height,
            ..want.clone()
        } == *have;
        if state.field != self.renderer.field() || !same_look {
            let renderer = self.renderer.with_options(&state.field, &want)?;
            check_samples_per_ray(&self.mesh, renderer.step())?;
            let retargeted = match self.marcher.as_mut() {
                Some(AnyMarcher::Gpu(m)) => m.retarget(&renderer).is_ok(),
                Some(AnyMarcher::Host(_)) => true,
                None => false,
            };
            if !retargeted {
                self.marcher = None;
                self.marcher = Some(build_marcher(&self.opts, &self.mesh, &self.backend, &renderer, false)?);
            }
            self.renderer = renderer;
        }
        self.renderer.set_view(want.camera, want.zoom, want.width, want.height)?;
        Ok(())
    }

    /// Renders the current view at `width`×`height` as 8-bit sRGB RGB. The GPU marcher
    /// composites and encodes on the GPU and downloads 4 bytes a pixel; the host marcher's
    /// linear image is encoded here. A host render stops between batches once `stop` says
    /// the frame is no longer wanted (`None`); a GPU frame is one call, and always finishes.
    fn render(&mut self, width: u32, height: u32, stop: &dyn Fn() -> bool) -> Result<Option<Frame>> {
        let cam = self.renderer.camera_sized(width, height);
        match self.marcher.as_mut() {
            Some(AnyMarcher::Host(l)) => {
                let mut s = Stoppable { inner: &mut **l, stop, stopped: false };
                let r = self.renderer.render(&mut tr::HostMarcher(&mut s), &cam);
                if s.stopped {
                    return Ok(None);
                }
                let (image, stats) = r?;
                Ok(Some((super::frames::srgb8(&image), stats)))
            }
            Some(AnyMarcher::Gpu(m)) => {
                let (rgba, stats) = m.march_srgb8(&self.renderer, &cam)?;
                let rgb = rgba.iter().flat_map(|p| {
                    let [r, g, b, _] = p.to_le_bytes();
                    [r, g, b]
                });
                Ok(Some((rgb.collect(), stats)))
            }
            None => anyhow::bail!("no marcher (an earlier rebuild failed)"),
        }
    }
}

/// A rendered frame: 8-bit sRGB RGB and its statistics.
type Frame = (Vec<u8>, tr::FrameStats);

/// A host locator whose batches fail once `stop` says so: a newer state supersedes a still
/// frame within one batch of samples, rather than waiting seconds for a large frame.
struct Stoppable<'a> {
    inner: &'a mut dyn BatchLocator,
    stop: &'a dyn Fn() -> bool,
    stopped: bool,
}

impl Stoppable<'_> {
    fn check(&mut self) -> tetloc_core::Result<()> {
        self.stopped = self.stopped || (self.stop)();
        if self.stopped {
            return Err(tetloc_core::Error::Invalid("superseded by a newer view".into()));
        }
        Ok(())
    }
}

impl BatchLocator for Stoppable<'_> {
    fn name(&self) -> &str {
        self.inner.name()
    }
    fn query(&mut self, points: Points<'_>, fields: &[&str], ids: &mut [i32], values: Values<'_>) -> CoreResult<()> {
        self.check()?;
        self.inner.query(points, fields, ids, values)
    }
    // The renderer's calls: forwarded, since backends override them for speed.
    fn sample(&mut self, points: &[[f32; 3]], field: &str, values: &mut [f32]) -> CoreResult<()> {
        self.check()?;
        self.inner.sample(points, field, values)
    }
    fn sample_many64(
        &mut self,
        points: &[[f64; 3]],
        fields: &[&str],
        ids: &mut [i32],
        values: &mut [f64],
    ) -> CoreResult<()> {
        self.check()?;
        self.inner.sample_many64(points, fields, ids, values)
    }
    fn preferred_batch(&self) -> Option<usize> {
        self.inner.preferred_batch()
    }
}

/// What the page needs to know of the mesh: bounds, fields with their ranges, the
/// backend, the built-in colormaps (sampled, for the editor's colour bar) and the home camera.
pub fn describe(mesh: &Mesh, times: &[f64], state: &tr::ViewState, backend: &str) -> serde_json::Value {
    use rayon::prelude::*;
    let i = &mesh.info;
    let fields: Vec<_> = mesh
        .fields
        .iter()
        .map(|f| {
            let (lo, hi) = f
                .values
                .par_iter()
                .filter(|v| v.is_finite())
                .fold(|| (f32::INFINITY, f32::NEG_INFINITY), |(a, b), &v| (a.min(v), b.max(v)))
                .reduce(|| (f32::INFINITY, f32::NEG_INFINITY), |(a, b), (c, d)| (a.min(c), b.max(d)));
            let range = if lo <= hi { serde_json::json!([lo, hi]) } else { serde_json::Value::Null };
            let location = match f.location {
                tetloc_core::FieldLocation::Vertex => "point",
                tetloc_core::FieldLocation::Cell => "cell",
            };
            serde_json::json!({ "name": f.name, "location": location, "range": range })
        })
        .collect();
    let colormaps: serde_json::Map<String, serde_json::Value> = tr::Colormap::ALL
        .iter()
        .map(|m| {
            let t = m.table();
            let samples: Vec<[f32; 3]> = (0..32).map(|k| t[k * (t.len() - 1) / 31]).collect();
            (m.name().to_string(), serde_json::json!(samples))
        })
        .collect();
    let lo = i.frame.to_file(i.bounds_min);
    let hi = i.frame.to_file(i.bounds_max);
    let home = tr::CameraState::fitted(mesh, 30.0, 25.0, 1.0);
    serde_json::json!({
        "source": i.source,
        "tets": i.n_tets,
        "bounds": [lo, hi],
        "fields": fields,
        "backend": backend,
        "colormaps": colormaps,
        "home": home,
        "size": state.size,
        // Each time step's time (empty for a snapshot); the fields' ranges are the first
        // shown step's, and each frame's header carries the range it was drawn with.
        "times": times,
    })
}

/// Starts the render thread, which builds the scene (locators need not move between
/// threads) and then renders for good; returns the backend's name once the scene is built.
pub fn spawn(
    mesh: Arc<Mesh>,
    series: Option<Series>,
    backend: &str,
    opts: BackendOptions,
    state: tr::ViewState,
    hub: Arc<Hub>,
) -> Result<String> {
    let (tx, rx) = std::sync::mpsc::channel();
    let backend = backend.to_string();
    std::thread::Builder::new().name("view-render".into()).spawn(move || {
        match Scene::new(mesh, series, &backend, opts, &state) {
            Ok(mut scene) => {
                let _ = tx.send(Ok(scene.marcher_name().to_string()));
                render_loop(&mut scene, &hub)
            }
            Err(e) => {
                let _ = tx.send(Err(e));
            }
        }
    })?;
    rx.recv()?
}

fn render_loop(scene: &mut Scene, hub: &Hub) {
    let mut applied = 0u64;
    let mut rendered = 0u64;
    let mut still_gen = 0u64;
    let mut scale = 1.0f64;
    loop {
        // The next job: a new state (moving or still), or the still frame of a view that
        // stopped moving.
        let (gen, state, still, started) = {
            let mut i = lock(&hub.input);
            loop {
                let quiet_for = i.last_event.elapsed();
                if i.gen != rendered {
                    break (i.gen, i.state.clone(), !i.moving, Instant::now());
                }
                if still_gen != i.gen && quiet_for >= QUIET {
                    break (i.gen, i.state.clone(), true, Instant::now());
                }
                let wait = if still_gen != i.gen { QUIET - quiet_for } else { Duration::from_secs(3600) };
                i = hub.input_changed.wait_timeout(i, wait).unwrap_or_else(|e| e.into_inner()).0;
            }
        };
        if gen != applied {
            if let Err(e) = scene.apply(&state) {
                lock(&hub.input).error = Some((gen, format!("{e:#}")));
                hub.out_ready.notify_all();
                // Shown as an error; the last frame stays.
                (rendered, still_gen, applied) = (gen, gen, gen);
                continue;
            }
            applied = gen;
        }
        let [w, h] = state.size;
        let s = if still { 1.0 } else { scale };
        let (sw, sh) = (((w as f64 * s).round() as u32).max(1), ((h as f64 * s).round() as u32).max(1));
        let t = Instant::now();
        // A still frame (full size, maybe large) gives way to any newer state; moving
        // frames always finish, or a fast drag would show none.
        let stop = || still && lock(&hub.input).gen != gen;
        let (rgb, stats) = match scene.render(sw, sh, &stop) {
            Ok(Some(r)) => r,
            Ok(None) => continue,
            Err(e) => {
                lock(&hub.input).error = Some((gen, format!("{e:#}")));
                hub.out_ready.notify_all();
                (rendered, still_gen) = (gen, gen);
                continue;
            }
        };
        let march_ms = t.elapsed().as_secs_f64() * 1e3;
        // A moving frame's time: the slower of its march and its JPEG encode, which run side
        // by side (at agulhas 36M, 1024² on the H200 the encode took 26 ms against a 9 ms march).
        let frame_ms = march_ms.max(hub.jpeg_ms(u64::from(sw) * u64::from(sh))).max(1e-3);
        if !still {
            // Moving frames: the size whose frame would take the target time (a frame's time
            // goes with its pixels, the square of the scale), within a factor 2 a frame.
            let want = scale * (TARGET_MS / frame_ms).sqrt();
            scale = want.clamp(scale / 2.0, scale * 2.0).clamp(MIN_SCALE, 1.0);
        } else {
            // The next drag starts at the size a still frame's time suggests.
            scale = (TARGET_MS / frame_ms).sqrt().clamp(MIN_SCALE, 1.0);
        }
        rendered = gen;
        if still {
            still_gen = gen;
        }
        hub.put_raw(RawFrame {
            gen,
            still,
            width: sw,
            height: sh,
            rgb,
            march_ms,
            gpu_ms: stats.gpu_seconds * 1e3,
            range: scene.renderer.range(),
            started,
        });
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::cell::Cell;

    /// Answers every point with tet 0 and value 1.
    struct Ones;

    impl BatchLocator for Ones {
        fn name(&self) -> &str {
            "ones"
        }
        fn query(&mut self, _: Points<'_>, _: &[&str], ids: &mut [i32], values: Values<'_>) -> CoreResult<()> {
            ids.fill(0);
            if let Values::F32(v) = values {
                v.fill(1.0);
            }
            Ok(())
        }
    }

    #[test]
    fn a_stoppable_locator_fails_its_batches_once_told_to_stop() {
        let (want_stop, mut ones) = (Cell::new(false), Ones);
        let stop = || want_stop.get();
        let mut s = Stoppable { inner: &mut ones, stop: &stop, stopped: false };
        let mut v = [0.0f32; 2];
        s.sample(&[[0.0; 3]; 2], "f", &mut v).unwrap();
        assert_eq!(v, [1.0, 1.0]);
        want_stop.set(true);
        assert!(s.sample(&[[0.0; 3]; 2], "f", &mut v).is_err() && s.stopped);
        want_stop.set(false);
        assert!(s.sample_many64(&[[0.0; 3]], &["f"], &mut [0], &mut [0.0]).is_err(), "stopped stays stopped");
    }

    #[test]
    fn frame_sizes_are_bounded_by_a_pixel_budget() {
        assert_eq!(check_size([2048, 2048]), Ok(()));
        assert_eq!(check_size([8192, 512]), Ok(()));
        let e = check_size([2049, 2048]).unwrap_err();
        assert!(e.contains("2049x2048") && e.contains("4194304 pixels"), "{e}");
        assert!(check_size([8192, 8192]).is_err());
    }
}
