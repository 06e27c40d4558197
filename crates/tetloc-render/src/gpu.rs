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

impl Marcher for GpuMarcher {
    fn name(&self) -> &str {
        self.march.kernel().name()
    }

    fn march_frame(&mut self, renderer: &Renderer, camera: &Camera) -> Result<(Vec<[f32; 4]>, FrameStats)> {
        if key(renderer) != self.key {
            return Err(RenderError::Invalid(format!(
                "this GPU marcher was built for field '{}' with another step or skipping; build one per renderer",
                self.key.0
            )));
        }
        let start = Instant::now();
        let (w, h) = (camera.width, camera.height);
        // Surfaces are static: hit and shade on the CPU, one entry per pixel.
        let surface: Option<Vec<[f32; 4]>> = renderer.has_surface().then(|| {
            (0..w * h)
                .into_par_iter()
                .map(|i| match renderer.surface_hit(&camera.ray(i % w, i / w)) {
                    Some((t, [r, g, b])) => [t, r, g, b],
                    None => [f32::INFINITY, 0.0, 0.0, 0.0],
                })
                .collect()
        });
        let view = MarchView {
            eye: camera.eye,
            forward: camera.forward(),
            right: camera.right(),
            up: camera.up(),
            tan_half_y: camera.tan_half_y(),
            width: w,
            height: h,
            surface: surface.as_deref(),
        };
        let mut rgba = vec![[0f32; 4]; w as usize * h as usize];
        let s = self.march.render(&view, &mut rgba)?;
        let stats = FrameStats {
            rays: rgba.len(),
            samples: s.samples,
            in_mesh_samples: s.in_mesh_samples,
            rounds: 1,
            sample_seconds: s.gpu_seconds,
            seconds: start.elapsed().as_secs_f64(),
            gpu_seconds: s.gpu_seconds,
        };
        Ok((rgba, stats))
    }
}
