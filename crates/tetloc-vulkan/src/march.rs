//! The volume ray marcher on the GPU (paper, section 6.3): one invocation per pixel runs the
//! whole march of `shaders/common/march.glsl` — camera ray, box clipping, exact empty-space
//! skipping, transfer function, front-to-back compositing to the opacity cutoff — locating
//! every sample with the locator's own kernel: soft-bvh in a compute shader (a neighbour walk
//! from the previous sample, BVH traversal as the fallback), the rt kernels in a ray
//! generation shader that traces through their hit groups.
//!
//! A [`VolumeMarcher`] takes a [`VulkanLocator`] and binds its mesh and structure buffers
//! (no second upload); the scene (transfer function, occupancy grid) is plain data that
//! tetloc-render fills in, so this crate knows nothing of cameras or colormaps beyond the
//! numbers. Frame times come from GPU timestamps around the one dispatch.

use crate::error::{VkError, VkResult};
use crate::interface::*;
use crate::locator::VulkanLocator;
use crate::memory::{Buffer, BufferDesc, MemKind};
use crate::pipeline::{Binding, Descriptors, Pipeline};
use crate::Kernel;
use ash::vk;
use std::sync::Arc;
use std::time::Instant;
use tetloc_core::{BatchLocator, Mesh};

/// An occupancy grid for exact empty-space skipping (tetloc-render's `OccupancyGrid`).
#[derive(Clone, Debug)]
pub struct MarchGrid {
    pub lo: [f32; 3],
    pub hi: [f32; 3],
    pub cell: [f32; 3],
    pub inv_cell: [f32; 3],
    /// How far before a region's exit a skip lands.
    pub margin: f32,
    pub dims: [u32; 3],
    pub block_dims: [u32; 3],
    /// Cells along a block's edge.
    pub block: u32,
    /// Per cell, x fastest.
    pub occupied: Vec<bool>,
    /// Per block, x fastest.
    pub blocks: Vec<bool>,
}

/// What stays the same from frame to frame.
#[derive(Clone, Debug)]
pub struct MarchScene {
    pub field: String,
    pub step: f32,
    /// A ray stops once this opaque.
    pub cutoff: f32,
    /// Transfer function: linear RGB and step alpha, at least 2 entries, linearly filtered
    /// over `[tf_lo, tf_lo + 1 / tf_inv_range]`.
    pub tf: Vec<[f32; 4]>,
    pub tf_lo: f32,
    pub tf_inv_range: f32,
    /// Empty-space skipping when set.
    pub grid: Option<MarchGrid>,
}

/// One frame's camera (tetloc-render's `Camera`) and surface.
#[derive(Clone, Copy, Debug)]
pub struct MarchView<'a> {
    pub eye: [f32; 3],
    /// Unit vectors.
    pub forward: [f32; 3],
    pub right: [f32; 3],
    pub up: [f32; 3],
    pub tan_half_y: f32,
    pub width: u32,
    pub height: u32,
    /// Per pixel: the ray parameter where it hits a surface (+inf: none) and the surface's
    /// shaded linear RGB.
    pub surface: Option<&'a [[f32; 4]]>,
}

/// What one frame cost.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct MarchStats {
    /// GPU time of the march (timestamps around the dispatch), or the submission's host
    /// time on a device without timestamps.
    pub gpu_seconds: f64,
    /// Samples located, and of those the ones inside the mesh (composited).
    pub samples: u64,
    pub in_mesh_samples: u64,
}

/// A locator's kernel marching whole frames on the GPU.
pub struct VolumeMarcher {
    // Field order is drop order: the pipeline and the march's buffers before the locator.
    pipeline: Pipeline,
    desc: Descriptors,
    params: MarchParams,
    /// The push constants (the locator's launch parameters: bounds, ray).
    push: Params,
    params_buf: Buffer,
    tf: Buffer,
    _occupancy: Buffer,
    _neighbors: Option<Buffer>,
    surface: Option<(Buffer, usize)>,
    pixels: Option<(Buffer, usize)>,
    query_pool: Option<vk::QueryPool>,
    busy: u32,
    /// False after a [`Self::take_fields`] that could not upload the new field: the old one
    /// is freed, so no frame is marched.
    field_bound: bool,
    loc: VulkanLocator,
}

impl VolumeMarcher {
    pub fn new(mut loc: VulkanLocator, scene: &MarchScene) -> tetloc_core::Result<VolumeMarcher> {
        let bad = |m: String| Err(tetloc_core::Error::Invalid(m));
        if scene.tf.len() < 2 || scene.step.is_nan() || scene.step <= 0.0 {
            return bad(format!(
                "march: {} transfer-function entries (need 2) and step {}",
                scene.tf.len(),
                scene.step
            ));
        }
        let mut res = loc.resources(&scene.field)?;
        // A march program that walks between samples, on a structure without the neighbour
        // table (soft-bvh without its walk start), brings its own.
        let neighbors = res.bind_own_neighbors("march tet neighbours")?;
        let dev = res.dev;
        let ctx = dev.ctx().clone();
        let storage = vk::BufferUsageFlags::STORAGE_BUFFER;
        let tf = dev.upload("march transfer function", MemKind::Structure, storage, bytemuck::cast_slice(&scene.tf))?;
        let (lo, hi) = (res.mesh.info.bounds_min, res.mesh.info.bounds_max);
        let mut p = MarchParams {
            eye_step: [0.0, 0.0, 0.0, scene.step],
            right_cutoff: [0.0, 0.0, 0.0, scene.cutoff],
            size: [0, 0, 0, scene.tf.len() as u32],
            box_lo_tf_lo: [lo[0], lo[1], lo[2], scene.tf_lo],
            box_hi_tf_inv: [hi[0], hi[1], hi[2], scene.tf_inv_range],
            ..Default::default()
        };
        let occupancy = match &scene.grid {
            Some(g) => {
                let cells = g.occupied.len();
                let words = cells.div_ceil(32);
                let mut bits = vec![0u32; words + g.blocks.len().div_ceil(32)];
                for (i, _) in g.occupied.iter().enumerate().filter(|(_, &o)| o) {
                    bits[i / 32] |= 1 << (i % 32);
                }
                for (i, _) in g.blocks.iter().enumerate().filter(|(_, &o)| o) {
                    bits[words + i / 32] |= 1 << (i % 32);
                }
                p.size[2] |= MARCH_SKIP;
                p.occ_lo_margin = [g.lo[0], g.lo[1], g.lo[2], g.margin];
                p.occ_hi = [g.hi[0], g.hi[1], g.hi[2], 0.0];
                p.occ_cell = [g.cell[0], g.cell[1], g.cell[2], 0.0];
                p.occ_inv = [g.inv_cell[0], g.inv_cell[1], g.inv_cell[2], 0.0];
                p.occ_dims = [g.dims[0], g.dims[1], g.dims[2], words as u32];
                p.occ_blocks = [g.block_dims[0], g.block_dims[1], g.block_dims[2], g.block];
                dev.upload("march occupancy grid", MemKind::Structure, storage, bytemuck::cast_slice(&bits))?
            }
            None => dev.upload("march occupancy grid", MemKind::Structure, storage, &[0; 16])?,
        };
        let params_desc = BufferDesc::device(
            MemKind::Query,
            std::mem::size_of::<MarchParams>() as u64,
            storage | vk::BufferUsageFlags::TRANSFER_DST,
        );
        let params_buf = dev.create_buffer(params_desc, "march parameters", None)?;

        // One descriptor set: the locator's resources, then the march's own.
        let mut bindings = res.bindings;
        let unbound = dev.unbound();
        bindings.extend([
            Binding::buffer(B_MARCH, &params_buf),
            Binding::buffer(B_TF, &tf),
            Binding::buffer(B_OCCUPANCY, &occupancy),
            Binding::buffer(B_SURFACE, unbound),
            Binding::buffer(B_PIXELS, unbound),
        ]);
        let program = res.plan.march;
        let desc = Descriptors::new(&ctx, &bindings, program.stages())?;
        let pipeline = program.pipeline(dev, desc.layout, res.f64, &res.spec)?;
        let query_pool = if ctx.limits.timestamp_valid_bits > 0 {
            let info = vk::QueryPoolCreateInfo::default().query_type(vk::QueryType::TIMESTAMP).query_count(2);
            // SAFETY: plain query-pool creation; destroyed in Drop.
            Some(unsafe { ctx.device.create_query_pool(&info, None) }.map_err(VkError::vk("vkCreateQueryPool"))?)
        } else {
            None
        };
        Ok(VolumeMarcher {
            pipeline,
            desc,
            params: p,
            push: res.params,
            params_buf,
            tf,
            _occupancy: occupancy,
            _neighbors: neighbors,
            surface: None,
            pixels: None,
            query_pool,
            busy: 0,
            field_bound: true,
            loc,
        })
    }

    pub fn kernel(&self) -> Kernel {
        self.loc.kernel()
    }

    pub fn locator(&self) -> &VulkanLocator {
        &self.loc
    }

    /// Another transfer function and step for the same field and grid (a viewer's edits):
    /// only the table is uploaded again.
    pub fn set_tf(&mut self, tf: &[[f32; 4]], tf_lo: f32, tf_inv_range: f32, step: f32) -> tetloc_core::Result<()> {
        if tf.len() < 2 || step.is_nan() || step <= 0.0 {
            return Err(tetloc_core::Error::Invalid(format!(
                "march: {} transfer-function entries (need 2) and step {step}",
                tf.len()
            )));
        }
        let storage = vk::BufferUsageFlags::STORAGE_BUFFER;
        let buf = self.loc.device().upload(
            "march transfer function",
            MemKind::Structure,
            storage,
            bytemuck::cast_slice(tf),
        )?;
        // No frame is in flight: `render` waits for its submission.
        self.desc.write(&[Binding::buffer(B_TF, &buf)]);
        self.tf = buf;
        self.params.eye_step[3] = step;
        self.params.size[3] = tf.len() as u32;
        self.params.box_lo_tf_lo[3] = tf_lo;
        self.params.box_hi_tf_inv[3] = tf_inv_range;
        Ok(())
    }

    /// Marches `mesh`'s field `field` from now on: another time step of the locator's mesh
    /// (`BatchLocator::take_fields`), whose field alone is uploaded. False, with nothing
    /// changed, where the geometry is not the same or the field's location (points, cells)
    /// is not.
    pub fn take_fields(&mut self, mesh: &Arc<Mesh>, field: &str) -> tetloc_core::Result<bool> {
        // The pipeline is specialised to the field's location: another one needs a new marcher.
        let location = |m: &Mesh| m.field(field).map(|f| f.location);
        if location(mesh)? != location(self.loc.mesh())? || !self.loc.take_fields(mesh) {
            return Ok(false);
        }
        // The old field is freed now: until the new one is bound, no frame is marched.
        self.field_bound = false;
        let res = self.loc.resources(field)?;
        let bound = res.bindings.into_iter().filter(|b| b.slot == B_FIELD).collect::<Vec<_>>();
        // No frame is in flight: `render` waits for its submission.
        self.desc.write(&bound);
        self.field_bound = true;
        Ok(true)
    }

    /// Benchmarks: march each frame `n` more times, untimed, before the timed march, so that
    /// the GPU stays busy between frames (image downloads) and its clocks stay up.
    pub fn set_busy_dispatches(&mut self, n: u32) {
        self.busy = n;
    }

    /// Marches one frame. `out` (width × height, row-major, top row first) receives each
    /// pixel's premultiplied linear RGB and opacity, surface included, no background.
    pub fn render(&mut self, view: &MarchView, out: &mut [[f32; 4]]) -> tetloc_core::Result<MarchStats> {
        let n = view.width as usize * view.height as usize;
        if n == 0 || out.len() != n {
            return Err(tetloc_core::Error::Invalid(format!(
                "march: a {}x{} frame into {} pixels",
                view.width,
                view.height,
                out.len()
            )));
        }
        if let Some(s) = view.surface {
            if s.len() != n {
                return Err(tetloc_core::Error::Invalid(format!("march: {} surface entries for {n} pixels", s.len())));
            }
        }
        Ok(self.render_frame(view, Out::Linear(out))?)
    }

    /// Marches one frame into 8-bit sRGB over `background` (linear RGB), composited and
    /// encoded on the GPU: `out` receives one RGBA u32 a pixel (R in the low byte), and only
    /// those 4 bytes a pixel are downloaded. The stats carry no sample counts.
    pub fn render_rgba8(
        &mut self,
        view: &MarchView,
        background: [f32; 3],
        out: &mut [u32],
    ) -> tetloc_core::Result<MarchStats> {
        let n = view.width as usize * view.height as usize;
        if n == 0 || out.len() != n || view.surface.is_some_and(|s| s.len() != n) {
            return Err(tetloc_core::Error::Invalid(format!(
                "march: a {}x{} frame into {} pixels",
                view.width,
                view.height,
                out.len()
            )));
        }
        Ok(self.render_frame(view, Out::Rgba8(out, background))?)
    }

    fn render_frame(&mut self, view: &MarchView, mut out: Out) -> VkResult<MarchStats> {
        if !self.field_bound {
            return Err(VkError::Mesh("march: the field of the last time step could not be uploaded".into()));
        }
        let n = view.width as usize * view.height as usize;
        let dev = self.loc.device();
        let ctx = dev.ctx().clone();
        if let (Some(rt), Some(_)) = (&ctx.rt, &self.pipeline.sbt) {
            if n > rt.max_dispatch as usize {
                return Err(VkError::Mesh(format!(
                    "{n} pixels: more rays than one launch may have ({})",
                    rt.max_dispatch
                )));
            }
        }
        if self.pixels.as_ref().is_none_or(|(_, cap)| *cap < n) {
            self.pixels = None;
            let bytes = (n * std::mem::size_of::<Pixel>()) as u64;
            let b = dev.create_buffer(BufferDesc::io(MemKind::Query, bytes), "march pixels", None)?;
            self.desc.write(&[Binding::buffer(B_PIXELS, &b)]);
            self.pixels = Some((b, n));
        }
        let mut p = self.params;
        p.eye_step[..3].copy_from_slice(&view.eye);
        p.fwd_tan = [view.forward[0], view.forward[1], view.forward[2], view.tan_half_y];
        p.right_cutoff[..3].copy_from_slice(&view.right);
        p.up[..3].copy_from_slice(&view.up);
        p.size[0] = view.width;
        p.size[1] = view.height;
        if let Out::Rgba8(_, bg) = &out {
            p.size[2] |= MARCH_RGBA8;
            p.background = [bg[0], bg[1], bg[2], 0.0];
        }
        if let Some(s) = view.surface {
            p.size[2] |= MARCH_SURFACE;
            if self.surface.as_ref().is_none_or(|(_, cap)| *cap < n) {
                self.surface = None;
                let b = dev.create_buffer(BufferDesc::io(MemKind::Query, (n * 16) as u64), "march surface", None)?;
                self.desc.write(&[Binding::buffer(B_SURFACE, &b)]);
                self.surface = Some((b, n));
            }
            let buf = &self.surface.as_ref().expect("made above").0;
            dev.write(buf, 0, bytemuck::cast_slice(s))?;
        }

        let (pl, desc, params_buf, pool) = (&self.pipeline, &self.desc, self.params_buf.buffer, self.query_pool);
        let (w, h, push, busy) = (view.width, view.height, self.push, self.busy);
        let t = Instant::now();
        // SAFETY: recording into the device object's command buffer with live objects; the
        // params update is far below vkCmdUpdateBuffer's 64 KiB limit and a multiple of 4 bytes.
        dev.run(|r| unsafe {
            let (dev, cmd) = (r.dev, r.cmd);
            dev.cmd_update_buffer(cmd, params_buf, 0, bytemuck::bytes_of(&p));
            if let Some(pool) = pool {
                dev.cmd_reset_query_pool(cmd, pool, 0, 2);
            }
            dev.cmd_bind_pipeline(cmd, pl.bind_point, pl.pipeline);
            dev.cmd_bind_descriptor_sets(cmd, pl.bind_point, desc.layout, 0, &[desc.set], &[]);
            dev.cmd_push_constants(cmd, desc.layout, desc.stages, 0, bytemuck::bytes_of(&push));
            for i in 0..=busy {
                r.barrier();
                if let (Some(pool), true) = (pool, i == busy) {
                    dev.cmd_write_timestamp(cmd, vk::PipelineStageFlags::TOP_OF_PIPE, pool, 0);
                }
                match &pl.sbt {
                    None => dev.cmd_dispatch(cmd, w.div_ceil(MARCH_TILE), h.div_ceil(MARCH_TILE), 1),
                    Some(sbt) => {
                        let empty = vk::StridedDeviceAddressRegionKHR::default();
                        let rt = r.ctx.rt.as_ref().expect("a ray-tracing pipeline exists only with ray tracing");
                        rt.pipeline.cmd_trace_rays(cmd, &sbt.raygen, &sbt.miss, &sbt.hit, &empty, w, h, 1);
                    }
                }
            }
            r.barrier();
            if let Some(pool) = pool {
                dev.cmd_write_timestamp(cmd, vk::PipelineStageFlags::BOTTOM_OF_PIPE, pool, 1);
            }
        })?;
        let host_seconds = t.elapsed().as_secs_f64();
        let gpu_seconds = match pool {
            Some(pool) => {
                let mut ticks = [0u64; 2];
                // SAFETY: both queries were written by the completed submission (never read
                // a query that was reset but not written: that hangs some drivers).
                unsafe { ctx.device.get_query_pool_results(pool, 0, &mut ticks, vk::QueryResultFlags::TYPE_64) }
                    .map_err(VkError::vk("vkGetQueryPoolResults"))?;
                let bits = ctx.limits.timestamp_valid_bits;
                let mask = if bits >= 64 { u64::MAX } else { (1u64 << bits) - 1 };
                (ticks[1].wrapping_sub(ticks[0]) & mask) as f64 * ctx.limits.timestamp_period_ns * 1e-9
            }
            None => host_seconds,
        };

        let buf = &self.pixels.as_ref().expect("made above").0;
        let mut stats = MarchStats { gpu_seconds, ..Default::default() };
        match &mut out {
            Out::Rgba8(rgba, _) => dev.download(buf, 0, bytemuck::cast_slice_mut(rgba))?,
            Out::Linear(out) => {
                let mut pixels = vec![Pixel::default(); n];
                dev.download(buf, 0, bytemuck::cast_slice_mut(&mut pixels))?;
                for (o, px) in out.iter_mut().zip(&pixels) {
                    *o = px.rgba;
                    stats.samples += px.count[0] as u64;
                    stats.in_mesh_samples += px.count[1] as u64;
                }
            }
        }
        Ok(stats)
    }
}

/// Where a frame goes: linear premultiplied RGBA with counts, or 8-bit sRGB over a background.
enum Out<'a> {
    Linear(&'a mut [[f32; 4]]),
    Rgba8(&'a mut [u32], [f32; 3]),
}

impl Drop for VolumeMarcher {
    fn drop(&mut self) {
        if let Some(pool) = self.query_pool {
            // SAFETY: every submission using the pool has completed (run() waits).
            unsafe { self.loc.context().device.destroy_query_pool(pool, None) };
        }
    }
}
