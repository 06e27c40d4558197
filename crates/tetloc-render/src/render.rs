//! The sample-based volume ray marcher (paper, section 6.3), over any [`BatchLocator`].
//!
//! Every ray is clipped to the mesh bounds (and, with surfaces, ended at the nearest surface
//! hit) and sampled at `t = t0 + (k + ½)·step`. All rays march in lock-step: each round,
//! every active ray contributes its next sample position(s) to one batch handed to
//! `locator.sample`, so a GPU backend sees batches of up to a million points. Samples are
//! mapped through the transfer function and composited front to back; a ray stops at 99 %
//! opacity or at its end. With empty-space skipping, samples whose occupancy-grid cell
//! holds no tet are never sent — the positions of the samples that are sent do not change.

use crate::camera::{clip_to_box, Camera, Ray};
use crate::error::{RenderError, Result};
use crate::image::Image;
use crate::options::{RenderOptions, SurfaceSpec};
use crate::skip::OccupancyGrid;
use crate::surface::{SurfaceBvh, TriMesh};
use crate::tf::TfTable;
use crate::vec::{at, dot, len, sub, Vec3};
use rayon::prelude::*;
use std::sync::Arc;
use std::time::Instant;
use tetloc_core::{BatchLocator, Mesh};

/// A ray stops once it is this opaque.
pub const OPACITY_CUTOFF: f32 = 0.99;

/// Occupancy cells are about this many default steps (mean tet sizes) wide. Finer cells
/// follow sparse shapes more closely (on the test torus 1 step skips 1.7x, 2 steps 1.4x,
/// 4 steps 1.2x); the grid is capped at 256 cells an axis, which is what large meshes get.
const CELL_STEPS: f32 = 1.0;

/// The most samples one ray takes in a round, when few rays are left.
const MAX_SAMPLES_PER_ROUND: usize = 64;

/// Counts and timings of one frame.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct FrameStats {
    pub rays: usize,
    /// Sample points handed to the locator.
    pub samples: u64,
    /// Of those, samples inside the mesh that were composited (before each ray's cutoff).
    pub in_mesh_samples: u64,
    /// Batches handed to the locator (1 a frame for the GPU marcher).
    pub rounds: u32,
    /// Seconds inside `locator.sample` (the GPU marcher: the GPU time of the march).
    pub sample_seconds: f64,
    pub seconds: f64,
    /// The GPU marcher: GPU time of the frame (timestamps); 0 for the host marcher.
    pub gpu_seconds: f64,
}

impl FrameStats {
    fn add(&mut self, o: &FrameStats) {
        self.rays += o.rays;
        self.samples += o.samples;
        self.in_mesh_samples += o.in_mesh_samples;
        self.rounds += o.rounds;
        self.sample_seconds += o.sample_seconds;
        self.seconds += o.seconds;
        self.gpu_seconds += o.gpu_seconds;
    }

    /// Totals over several frames.
    pub fn sum<'a>(it: impl IntoIterator<Item = &'a FrameStats>) -> FrameStats {
        let mut s = FrameStats::default();
        it.into_iter().for_each(|f| s.add(f));
        s
    }
}

impl std::fmt::Display for FrameStats {
    /// One line for the CLI, e.g. `262144 rays, 968744 samples (88.1 % inside the mesh) in
    /// 5 batches, 0.50 s (83 % in the locator)`.
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let pct = |a: f64, b: f64| if b > 0.0 { 100.0 * a / b } else { 0.0 };
        if self.gpu_seconds > 0.0 {
            return write!(
                f,
                "{} rays, {} samples ({:.1} % inside the mesh) marched on the GPU in {:.2} ms ({:.3} s with transfers)",
                self.rays,
                self.samples,
                pct(self.in_mesh_samples as f64, self.samples as f64),
                1e3 * self.gpu_seconds,
                self.seconds
            );
        }
        write!(
            f,
            "{} rays, {} samples ({:.1} % inside the mesh) in {} batches, {:.2} s ({:.0} % in the locator)",
            self.rays,
            self.samples,
            pct(self.in_mesh_samples as f64, self.samples as f64),
            self.rounds,
            self.seconds,
            pct(self.sample_seconds, self.seconds)
        )
    }
}

/// A mesh, a field and options made ready to render: the baked transfer function, the
/// step, the occupancy grid and the surface BVH. Render as many frames as you like with
/// any locator of the same mesh.
pub struct Renderer {
    mesh: Arc<Mesh>,
    pub(crate) field: String,
    opts: RenderOptions,
    /// Linear RGB and the alpha of one step.
    pub(crate) table: TfTable,
    range: (f32, f32),
    step: f32,
    grid: Option<Arc<OccupancyGrid>>,
    surface: Option<Arc<SurfaceBvh>>,
}

/// What renders a [`Renderer`]'s frames: the host marcher over any [`BatchLocator`] (every
/// locator is a `Marcher`), or a marcher that runs whole frames elsewhere (the GPU marcher,
/// `crate::gpu`).
pub trait Marcher {
    fn name(&self) -> &str;
    /// Per pixel of `camera`'s image (row-major, top row first): premultiplied linear RGB
    /// and opacity of the volume in front of any surface, the shaded surface composited
    /// behind it, no background.
    fn march_frame(&mut self, renderer: &Renderer, camera: &Camera) -> Result<(Vec<[f32; 4]>, FrameStats)>;
}

impl<L: BatchLocator> Marcher for L {
    fn name(&self) -> &str {
        BatchLocator::name(self)
    }
    fn march_frame(&mut self, renderer: &Renderer, camera: &Camera) -> Result<(Vec<[f32; 4]>, FrameStats)> {
        renderer.march(self, &camera.rays())
    }
}

/// The host marcher over a boxed or borrowed locator.
pub struct HostMarcher<'a>(pub &'a mut dyn BatchLocator);

impl Marcher for HostMarcher<'_> {
    fn name(&self) -> &str {
        self.0.name()
    }
    fn march_frame(&mut self, renderer: &Renderer, camera: &Camera) -> Result<(Vec<[f32; 4]>, FrameStats)> {
        renderer.march(self.0, &camera.rays())
    }
}

/// One ray in flight.
#[derive(Clone, Copy)]
struct RayState {
    pixel: u32,
    ray: Ray,
    t0: f32,
    /// Samples `k < n` lie before the ray's end.
    n: u32,
    /// The next sample index to consider.
    k: u32,
    /// Premultiplied linear RGB and opacity accumulated so far.
    acc: [f32; 4],
}

impl Renderer {
    pub fn new(mesh: Arc<Mesh>, field: &str, opts: &RenderOptions) -> Result<Renderer> {
        Self::build(mesh, field, opts, None)
    }

    /// A renderer of the same mesh with another field or other options. What depends on
    /// neither is kept: the occupancy grid (the mesh's only), the surface when the surface
    /// option is the same, the field's range when the field is; so that a viewer's
    /// transfer-function edits rebuild nothing but the table.
    pub fn with_options(&self, field: &str, opts: &RenderOptions) -> Result<Renderer> {
        Self::build(self.mesh.clone(), field, opts, Some(self))
    }

    /// A renderer of another time step of the same mesh: `mesh` holds the same points and
    /// cells with that step's fields. The occupancy grid and the surface (geometry only) are
    /// kept; a range not set in `opts` is the new step's, as a fresh renderer of that step
    /// has it, so a viewer's frame of step K is `render --time-step K`'s image.
    pub fn for_step(&self, mesh: Arc<Mesh>, field: &str, opts: &RenderOptions) -> Result<Renderer> {
        let geometry = |i: &tetloc_core::mesh::MeshInfo| (i.n_points, i.n_tets, i.n_cells, i.bounds_min, i.bounds_max);
        if geometry(&self.mesh.info) != geometry(&mesh.info) {
            return Err(RenderError::Invalid(format!(
                "{}: a time step's mesh differs from the one rendered ({} tets against {})",
                mesh.info.source, mesh.info.n_tets, self.mesh.info.n_tets
            )));
        }
        Self::build(mesh, field, opts, Some(self))
    }

    fn build(mesh: Arc<Mesh>, field: &str, opts: &RenderOptions, old: Option<&Renderer>) -> Result<Renderer> {
        opts.validate()?;
        let values = &mesh.field(field)?.values;
        // The old range holds for the same field of the same values only (not another step's).
        let old_range =
            old.filter(|o| o.field == field && o.opts.range.is_none() && Arc::ptr_eq(&o.mesh, &mesh)).map(|o| o.range);
        let range = match (opts.range, old_range) {
            (Some(r), _) => r,
            (None, Some(r)) => r,
            (None, None) => {
                let (lo, hi) = values
                    .par_iter()
                    .filter(|v| v.is_finite())
                    .fold(|| (f32::INFINITY, f32::NEG_INFINITY), |(a, b), &v| (a.min(v), b.max(v)))
                    .reduce(|| (f32::INFINITY, f32::NEG_INFINITY), |(a, b), (c, d)| (a.min(c), b.max(d)));
                if lo > hi {
                    return Err(RenderError::Invalid(format!(
                        "field '{field}' has no finite values to map to colours"
                    )));
                }
                // A constant field gets a small range around its value, so that it maps to
                // the middle of the transfer function rather than to its (transparent) start.
                let pad = if lo == hi { lo.abs().max(1.0) * 1e-3 } else { 0.0 };
                (lo - pad, hi + pad)
            }
        };
        let tf = opts.tf.load()?;
        let info = &mesh.info;
        let diagonal = len(sub(info.bounds_max, info.bounds_min));
        if !diagonal.is_finite() {
            return Err(RenderError::Invalid(format!(
                "{}: the mesh bounds {:?}..{:?} are too large to render in f32",
                info.source, info.bounds_min, info.bounds_max
            )));
        }
        let mean_tet = (info.total_volume / info.n_tets as f64).cbrt() as f32;
        // Degenerate meshes (flat, or all slivers) still get a usable step.
        let default_step =
            [mean_tet, info.mean_edge_length, diagonal / 1000.0, 1.0].into_iter().find(|&s| s > 0.0).unwrap();
        let step = opts.step.unwrap_or(default_step);
        // Extinction σ = (transfer-function opacity) × opacity scale / diagonal; a step of
        // length Δ then has alpha 1 − exp(−σΔ), baked into the table once per renderer.
        let sigma_unit = opts.opacity / if diagonal > 0.0 { diagonal } else { 1.0 };
        let table = tf.bake(range.0, range.1).with_step_alpha(sigma_unit * step);
        let old_grid = old.and_then(|o| o.grid.clone());
        let grid = opts
            .skip
            .then(|| old_grid.unwrap_or_else(|| Arc::new(OccupancyGrid::build(&mesh, CELL_STEPS * default_step))));
        let old_surface = old.filter(|o| o.opts.surface == opts.surface).map(|o| o.surface.clone());
        let surface = match &opts.surface {
            _ if old_surface.is_some() => old_surface.flatten(),
            None => None,
            Some(SurfaceSpec::Boundary) => Some(Arc::new(SurfaceBvh::build(&TriMesh::boundary(&mesh)))),
            // Surfaces given by the user are in the file's coordinates; rays run in the
            // working frame.
            Some(SurfaceSpec::File(path)) => {
                Some(Arc::new(SurfaceBvh::build(&TriMesh::load(path)?.in_frame(&mesh.info.frame))))
            }
            Some(SurfaceSpec::Mesh(tris)) => Some(Arc::new(SurfaceBvh::build(&tris.in_frame(&mesh.info.frame)))),
        };
        Ok(Renderer { mesh, field: field.to_string(), opts: opts.clone(), table, range, step, grid, surface })
    }

    /// Places the camera and sets the image size, keeping everything else (a viewer's
    /// camera moves): `camera` and `zoom` as in [`RenderOptions`].
    pub fn set_view(
        &mut self,
        camera: Option<crate::camera::LookAt>,
        zoom: f32,
        width: u32,
        height: u32,
    ) -> Result<()> {
        let opts = RenderOptions { camera, zoom, width, height, ..self.opts.clone() };
        opts.validate()?;
        self.opts = opts;
        Ok(())
    }

    pub fn mesh(&self) -> &Arc<Mesh> {
        &self.mesh
    }
    pub fn options(&self) -> &RenderOptions {
        &self.opts
    }
    /// The value range the transfer function spans: `options().range`, else the field's
    /// finite minimum and maximum (widened a little around a constant field's value).
    pub fn range(&self) -> (f32, f32) {
        self.range
    }
    pub fn step(&self) -> f32 {
        self.step
    }
    pub fn grid(&self) -> Option<&OccupancyGrid> {
        self.grid.as_deref()
    }
    pub fn field(&self) -> &str {
        &self.field
    }
    pub fn has_surface(&self) -> bool {
        self.surface.is_some()
    }

    /// Where `ray` hits the surface, and the surface's shaded linear colour there: a
    /// headlight Lambert, lit from the eye so that either side of a face shows.
    pub fn surface_hit(&self, ray: &Ray) -> Option<(f32, Vec3)> {
        let hit = self.surface.as_ref()?.intersect(ray, 0.0, f32::INFINITY)?;
        let lambert = dot(hit.normal, ray.dir).abs();
        let rgb = self.opts.surface_color.map(crate::colorspace::srgb_to_linear);
        Some((hit.t, rgb.map(|c| c * (0.2 + 0.8 * lambert))))
    }

    /// The camera of orbit frame `frame` of `options().frames`.
    pub fn camera(&self, frame: u32) -> Camera {
        self.orbit_camera(frame, self.opts.frames)
    }

    /// Frame `i` of an orbit of `n`: the view's azimuth (or the explicit eye, about the
    /// target along the up axis) advanced by `i · 360 / n` degrees.
    pub fn orbit_camera(&self, i: u32, n: u32) -> Camera {
        self.orbit_camera_sized(i, n, self.opts.width, self.opts.height)
    }

    /// [`Self::camera`]`(0)` for an image of another size (a viewer's frames while the
    /// view moves).
    pub fn camera_sized(&self, width: u32, height: u32) -> Camera {
        self.orbit_camera_sized(0, 1, width.max(1), height.max(1))
    }

    fn orbit_camera_sized(&self, i: u32, n: u32, width: u32, height: u32) -> Camera {
        let o = &self.opts;
        let turn = i as f32 * 360.0 / n.max(1) as f32;
        match o.camera {
            Some(look) => {
                // The user places the camera in the file's coordinates; rays run in the
                // mesh's working frame (mesh::Frame: centred and scaled for meshes far from
                // the origin), which a positive scale maps without turning.
                let frame = &self.mesh.info.frame;
                let to_working = |x: Vec3| frame.to_working(x.map(f64::from));
                let look = crate::camera::LookAt { eye: to_working(look.eye), target: to_working(look.target), ..look };
                let eye = rotate_about(sub(look.eye, look.target), look.up, turn.to_radians());
                let eye = std::array::from_fn(|k| look.target[k] + eye[k]);
                Camera::look_at(crate::camera::LookAt { eye, ..look }, o.zoom, width, height)
                    .expect("a valid camera stays valid when turned about its up axis")
            }
            None => Camera::fitted(
                self.mesh.info.bounds_min,
                self.mesh.info.bounds_max,
                o.azimuth + turn,
                o.elevation,
                o.zoom,
                width,
                height,
            ),
        }
    }

    /// Renders one image from `camera`.
    pub fn render(&self, marcher: &mut dyn Marcher, camera: &Camera) -> Result<(Image, FrameStats)> {
        let (rgba, stats) = marcher.march_frame(self, camera)?;
        let bg = self.opts.background.map(crate::colorspace::srgb_to_linear);
        let pixels = rgba.par_iter().map(|c| std::array::from_fn(|k| c[k] + (1.0 - c[3]) * bg[k])).collect();
        Ok((Image { width: camera.width, height: camera.height, pixels }, stats))
    }

    /// Marches `rays` and returns, per ray, premultiplied linear RGB and opacity of the
    /// volume in front of any surface, with the shaded surface composited behind it (no
    /// background).
    pub fn march(&self, locator: &mut dyn BatchLocator, rays: &[Ray]) -> Result<(Vec<[f32; 4]>, FrameStats)> {
        let start = Instant::now();
        let mut stats = FrameStats { rays: rays.len(), ..Default::default() };
        let (lo, hi) = (self.mesh.info.bounds_min, self.mesh.info.bounds_max);

        // Per ray: the volume interval, and the shaded surface colour where one is hit.
        let setup: Vec<(Option<RayState>, Option<Vec3>)> = rays
            .par_iter()
            .enumerate()
            .map(|(i, ray)| {
                let hit = self.surface_hit(ray);
                let shade = hit.map(|h| h.1);
                let state = clip_to_box(ray, lo, hi).map(|(t0, t1)| {
                    let t1 = hit.map_or(t1, |h| t1.min(h.0));
                    let n = ((t1 - t0) / self.step - 0.5).ceil().clamp(0.0, u32::MAX as f32) as u32;
                    RayState { pixel: i as u32, ray: *ray, t0, n, k: 0, acc: [0.0; 4] }
                });
                (state.filter(|s| s.n > 0), shade)
            })
            .collect();
        let mut out = vec![[0f32; 4]; rays.len()];
        let mut shades = vec![None; rays.len()];
        let mut active = Vec::with_capacity(rays.len());
        for (i, (state, shade)) in setup.into_iter().enumerate() {
            shades[i] = shade;
            active.extend(state);
        }

        let mut slots: Vec<Vec3> = Vec::new();
        let mut counts: Vec<u32> = Vec::new();
        let mut batch: Vec<Vec3> = Vec::new();
        let mut values: Vec<f32> = Vec::new();
        while !active.is_empty() {
            // Few rays left: take several samples each, to keep batches large.
            let m = (self.opts.batch_target / active.len()).clamp(1, MAX_SAMPLES_PER_ROUND);
            slots.resize(active.len() * m, [0.0; 3]);
            counts.resize(active.len(), 0);
            active.par_iter_mut().zip(slots.par_chunks_mut(m)).zip(counts.par_iter_mut()).for_each(|((s, slot), c)| {
                *c = 0;
                while (*c as usize) < m {
                    match self.next_sample(s) {
                        Some(p) => {
                            slot[*c as usize] = p;
                            *c += 1;
                        }
                        None => break,
                    }
                }
            });
            // Compact the slots into one batch (a memory-bound copy: not worth threads).
            batch.clear();
            for (slot, &c) in slots.chunks(m).zip(&counts) {
                batch.extend_from_slice(&slot[..c as usize]);
            }
            values.resize(batch.len(), 0.0);
            if !batch.is_empty() {
                let t = Instant::now();
                self.sample(locator, &batch, &mut values)?;
                stats.sample_seconds += t.elapsed().as_secs_f64();
                stats.samples += batch.len() as u64;
                stats.rounds += 1;
            }

            // Composite each ray's samples in order; note rays that are finished.
            let mut offsets = Vec::with_capacity(counts.len());
            let mut off = 0usize;
            for &c in &counts {
                offsets.push(off);
                off += c as usize;
            }
            let in_mesh: u64 = active
                .par_iter_mut()
                .zip(counts.par_iter())
                .zip(offsets.par_iter())
                .map(|((s, &c), &o)| self.composite(s, &values[o..o + c as usize]))
                .sum();
            stats.in_mesh_samples += in_mesh;

            // A ray is finished when opaque or out of samples (`next_sample` leaves k ≥ n).
            active.retain(|s| {
                let done = s.acc[3] >= OPACITY_CUTOFF || s.k >= s.n;
                if done {
                    out[s.pixel as usize] = s.acc;
                }
                !done
            });
        }

        out.par_iter_mut().zip(shades.par_iter()).for_each(|(c, shade)| {
            if let Some(rgb) = shade {
                for k in 0..3 {
                    c[k] += (1.0 - c[3]) * rgb[k];
                }
                c[3] = 1.0;
            }
        });
        stats.seconds = start.elapsed().as_secs_f64();
        Ok((out, stats))
    }

    /// The field at sample points of the working frame. The locators take points in the
    /// file's coordinates: at the identity frame these are the same f32 points; for a mesh
    /// far from the origin they are taken to the file's coordinates in f64 (an f32 point
    /// there would have lost the precision the working frame keeps).
    fn sample(&self, locator: &mut dyn BatchLocator, points: &[Vec3], values: &mut [f32]) -> Result<()> {
        let frame = &self.mesh.info.frame;
        if frame.is_identity() {
            return Ok(locator.sample(points, &self.field, values)?);
        }
        let file: Vec<[f64; 3]> = points.par_iter().map(|&p| frame.to_file(p)).collect();
        let mut ids = vec![0i32; points.len()];
        let mut wide = vec![0f64; points.len()];
        locator.sample_many64(&file, &[self.field.as_str()], &mut ids, &mut wide)?;
        values.par_iter_mut().zip(&wide).for_each(|(v, &w)| *v = w as f32);
        Ok(())
    }

    /// The position of the ray's next sample that may be inside a tet, advancing `s.k` past
    /// it; `None` (with `s.k = s.n`) when the ray has no more.
    #[inline]
    fn next_sample(&self, s: &mut RayState) -> Option<Vec3> {
        while s.k < s.n {
            let k = s.k;
            let t = s.t0 + (k as f32 + 0.5) * self.step;
            let p = at(s.ray.origin, s.ray.dir, t);
            let Some(grid) = &self.grid else {
                s.k += 1;
                return Some(p);
            };
            if grid.may_contain(p) {
                s.k += 1;
                return Some(p);
            }
            // The first sample at or past the point where the empty region may end; it is
            // tested again on the next pass of the loop.
            let t_skip = grid.skip_to(&s.ray, t, p);
            let next = ((t_skip - s.t0) / self.step - 0.5).ceil();
            s.k = if next > (k + 1) as f32 { next.min(s.n as f32) as u32 } else { k + 1 };
        }
        None
    }

    /// Composites one round's samples of a ray; returns how many were inside the mesh.
    #[inline]
    fn composite(&self, s: &mut RayState, values: &[f32]) -> u64 {
        let mut used = 0;
        for &v in values {
            // Outside every tet: transparent.
            if v.is_nan() {
                continue;
            }
            used += 1;
            let [r, g, b, alpha] = self.table.lookup(v);
            let w = (1.0 - s.acc[3]) * alpha;
            s.acc[0] += w * r;
            s.acc[1] += w * g;
            s.acc[2] += w * b;
            s.acc[3] += w;
            if s.acc[3] >= OPACITY_CUTOFF {
                break;
            }
        }
        used
    }
}

/// `v` rotated by `angle` radians about the axis `axis` (Rodrigues).
fn rotate_about(v: Vec3, axis: Vec3, angle: f32) -> Vec3 {
    let Some(k) = crate::vec::normalize(axis) else { return v };
    let (c, s) = (angle.cos(), angle.sin());
    let kxv = crate::vec::cross(k, v);
    let kdv = dot(k, v);
    std::array::from_fn(|i| v[i] * c + kxv[i] * s + k[i] * kdv * (1.0 - c))
}

#[cfg(test)]
mod tests;
