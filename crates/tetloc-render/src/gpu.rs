//! The GPU marcher: whole frames marched on the GPU by a tetloc-vulkan kernel
//! ([`tetloc_vulkan::VolumeMarcher`]), with this crate's camera, transfer-function table,
//! occupancy grid and surfaces, so that the image means the same as the host marcher's.
//!
//! Layering: tetloc-vulkan knows nothing of this crate; it takes the scene as plain numbers
//! (`MarchScene`, `MarchView`). This module, behind the `vulkan` feature, fills them in.

use crate::camera::Camera;
use crate::error::{RenderError, Result};
use crate::render::{FrameStats, Marcher, Renderer, OPACITY_CUTOFF};
use crate::skip::BLOCK;
use rayon::prelude::*;
use std::time::Instant;
use tetloc_vulkan::{MarchGrid, MarchScene, MarchView, VolumeMarcher, VulkanLocator};

/// A Vulkan kernel marching a [`Renderer`]'s frames on the GPU. Built for one renderer:
/// frames of another renderer (another field, step or grid) are refused.
pub struct GpuMarcher {
    march: VolumeMarcher,
    /// The renderer it was built for (field, step, skipping), to refuse another.
    key: (String, u32, bool),
}

fn key(r: &Renderer) -> (String, u32, bool) {
    (r.field().to_string(), r.step().to_bits(), r.grid().is_some())
}

impl GpuMarcher {
    /// Binds `locator`'s mesh and structure (no second upload) and uploads the renderer's
    /// transfer function and occupancy grid.
    pub fn new(locator: VulkanLocator, renderer: &Renderer) -> Result<GpuMarcher> {
        let t = &renderer.table;
        let grid = renderer.grid().map(|g| MarchGrid {
            lo: g.lo,
            hi: g.hi,
            cell: g.cell,
            inv_cell: g.inv_cell,
            margin: g.margin,
            dims: g.dims,
            block_dims: g.block_dims,
            block: BLOCK,
            occupied: g.occupied.clone(),
            blocks: g.blocks.clone(),
        });
        let scene = MarchScene {
            field: renderer.field().to_string(),
            step: renderer.step(),
            cutoff: OPACITY_CUTOFF,
            tf: t.entries.clone(),
            tf_lo: t.lo,
            tf_inv_range: t.inv_range,
            grid,
        };
        Ok(GpuMarcher { march: VolumeMarcher::new(locator, &scene)?, key: key(renderer) })
    }
}

impl GpuMarcher {
    /// Benchmarks: march each frame `n` more times, untimed, so that the GPU's clocks stay
    /// up between frames (see `VolumeMarcher::set_busy_dispatches`).
    pub fn set_busy_dispatches(&mut self, n: u32) {
        self.march.set_busy_dispatches(n);
    }
}

impl GpuMarcher {
    /// Makes this marcher march `renderer`'s frames: another transfer function, range,
    /// opacity or step of the same field, with skipping as before (a viewer's edits). Any
    /// other change needs a new marcher.
    pub fn retarget(&mut self, renderer: &Renderer) -> Result<()> {
        let k = key(renderer);
        if (&k.0, k.2) != (&self.key.0, self.key.2) {
            return Err(RenderError::Invalid(format!(
                "this GPU marcher marches field '{}'; build one for '{}' (or for other skipping)",
                self.key.0, k.0
            )));
        }
        let t = &renderer.table;
        self.march.set_tf(&t.entries, t.lo, t.inv_range, renderer.step())?;
        self.key = k;
        Ok(())
    }

    /// [`Self::retarget`] to a renderer of another time step of this marcher's mesh
    /// (`Mesh::with_fields`; the same field and skipping): the search structure stays on the
    /// GPU and only the step's field is uploaded. False, with nothing changed, where the
    /// step cannot be taken so (another geometry or field): build a new marcher.
    pub fn take_step(&mut self, renderer: &Renderer) -> Result<bool> {
        let k = key(renderer);
        if (&k.0, k.2) != (&self.key.0, self.key.2) || !self.march.take_fields(renderer.mesh(), renderer.field())? {
            return Ok(false);
        }
        self.retarget(renderer)?;
        Ok(true)
    }
}

impl GpuMarcher {
    /// Marches a frame into 8-bit sRGB over the renderer's background, composited and
    /// encoded on the GPU, so that 4 bytes a pixel are downloaded instead of 32: one RGBA u32
    /// a pixel (R in the low byte), as [`Renderer::render`] then `Image::to_srgb8` give it
    /// (up to the rounding of the GPU's `pow`). The stats carry no sample counts.
    pub fn march_srgb8(&mut self, renderer: &Renderer, camera: &Camera) -> Result<(Vec<u32>, FrameStats)> {
        let start = Instant::now();
        let surface = self.check_and_shade(renderer, camera)?;
        let background = renderer.options().background.map(crate::colorspace::srgb_to_linear);
        let mut rgba = vec![0u32; camera.width as usize * camera.height as usize];
        let s = self.march.render_rgba8(&view(camera, surface.as_deref()), background, &mut rgba)?;
        let stats = stats(rgba.len(), &s, start);
        Ok((rgba, stats))
    }

    /// Refuses another renderer's frames; the per-pixel surface hits when there is a surface.
    fn check_and_shade(&self, renderer: &Renderer, camera: &Camera) -> Result<Option<Vec<[f32; 4]>>> {
        if key(renderer) != self.key {
            return Err(RenderError::Invalid(format!(
                "this GPU marcher was built for field '{}' with another step or skipping; build one per renderer",
                self.key.0
            )));
        }
        let w = camera.width;
        // Surfaces are static: hit and shade on the CPU, one entry per pixel.
        Ok(renderer.has_surface().then(|| {
            (0..w * camera.height)
                .into_par_iter()
                .map(|i| match renderer.surface_hit(&camera.ray(i % w, i / w)) {
                    Some((t, [r, g, b])) => [t, r, g, b],
                    None => [f32::INFINITY, 0.0, 0.0, 0.0],
                })
                .collect()
        }))
    }
}

fn view<'a>(camera: &Camera, surface: Option<&'a [[f32; 4]]>) -> MarchView<'a> {
    MarchView {
        eye: camera.eye,
        forward: camera.forward(),
        right: camera.right(),
        up: camera.up(),
        tan_half_y: camera.tan_half_y(),
        width: camera.width,
        height: camera.height,
        surface,
    }
}

fn stats(rays: usize, s: &tetloc_vulkan::MarchStats, start: Instant) -> FrameStats {
    FrameStats {
        rays,
        samples: s.samples,
        in_mesh_samples: s.in_mesh_samples,
        rounds: 1,
        sample_seconds: s.gpu_seconds,
        seconds: start.elapsed().as_secs_f64(),
        gpu_seconds: s.gpu_seconds,
    }
}

impl Marcher for GpuMarcher {
    fn name(&self) -> &str {
        self.march.kernel().name()
    }

    fn march_frame(&mut self, renderer: &Renderer, camera: &Camera) -> Result<(Vec<[f32; 4]>, FrameStats)> {
        let start = Instant::now();
        let surface = self.check_and_shade(renderer, camera)?;
        let mut rgba = vec![[0f32; 4]; camera.width as usize * camera.height as usize];
        let s = self.march.render(&view(camera, surface.as_deref()), &mut rgba)?;
        let stats = stats(rgba.len(), &s, start);
        Ok((rgba, stats))
    }
}
