//! Locate once, interpolate many, on the GPU (issue 32 item 3): the CSR map of
//! [`tetloc_core::ops::Weights`] goes up once; then each batch of steps' fields (k components
//! a vertex) goes up once and comes back as their values at the points (`shaders/weights.comp`,
//! one invocation a point). On a device with shaderFloat64 the products equal
//! [`Weights::apply`]'s bit for bit (f64 weights, sums in f64 in the same order); without it
//! they are f32 sums.

use crate::context::Context;
use crate::device::Device;
use crate::error::{VkError, VkResult};
use crate::interface::{Params, B_STEP_OUT, B_STEP_VALUES, B_WEIGHTS_COLS, B_WEIGHTS_ROWS, B_WEIGHTS_VALUES};
use crate::memory::{Buffer, BufferDesc, MemKind, STAGING_BYTES};
use crate::pipeline::{Binding, Descriptors, Pipeline, Program, Spec};
use crate::shaders;
use ash::vk;
use std::sync::Arc;
use tetloc_core::ops::weights::Weights;

const WORKGROUP: u64 = 256;
/// Bytes of one batch's values and products together (more steps a batch, fewer submissions).
const BATCH_BYTES: u64 = 256 << 20;

/// A [`Weights`] map on one device, ready to apply to any number of steps.
pub struct GpuWeights {
    // Field order is drop order: the pipeline, set and buffers before the device.
    pipeline: Pipeline,
    desc: Descriptors,
    _map: [Buffer; 3],
    /// The batch buffers (values in, products out), grown as needed.
    batch: Option<(Buffer, Buffer)>,
    n_points: usize,
    n_vertices: usize,
    dev: Device,
}

impl GpuWeights {
    /// Uploads `w` to `ctx`'s device.
    pub fn new(ctx: &Arc<Context>, w: &Weights) -> VkResult<GpuWeights> {
        let nnz = w.vertices.len();
        if nnz >= u32::MAX as usize || w.n_points() >= u32::MAX as usize {
            let bytes = (nnz * 12) as u64;
            return Err(VkError::TooLarge { name: "weights".into(), bytes, limit: 12 << 32, what: "u32 indices" });
        }
        let mut dev = Device::new(ctx, STAGING_BYTES, None)?;
        let f64 = ctx.info().float64;
        let storage = vk::BufferUsageFlags::STORAGE_BUFFER;
        let rows: Vec<u32> = w.offsets.iter().map(|&o| o as u32).collect();
        // A buffer is never empty: one element more than an empty map holds.
        let mut cols = w.vertices.clone();
        cols.push(0);
        let weights: Vec<u8> = match f64 {
            true => bytemuck::cast_slice(&w.weights).iter().chain(&[0; 8]).copied().collect(),
            false => w.weights.iter().map(|&x| x as f32).chain([0.0]).flat_map(f32::to_le_bytes).collect(),
        };
        let rows = dev.upload("weights rows", MemKind::Structure, storage, bytemuck::cast_slice(&rows))?;
        let cols = dev.upload("weights columns", MemKind::Structure, storage, bytemuck::cast_slice(&cols))?;
        let weights = dev.upload("weights", MemKind::Structure, storage, &weights)?;
        let unbound = dev.unbound();
        let bindings = [
            Binding::buffer(B_WEIGHTS_ROWS, &rows),
            Binding::buffer(B_WEIGHTS_COLS, &cols),
            Binding::buffer(B_WEIGHTS_VALUES, &weights),
            Binding::buffer(B_STEP_VALUES, unbound),
            Binding::buffer(B_STEP_OUT, unbound),
        ];
        let program = Program::Compute(shaders::WEIGHTS);
        let desc = Descriptors::new(ctx, &bindings, program.stages())?;
        let pipeline = program.pipeline(&mut dev, desc.layout, f64, &Spec::default())?;
        Ok(GpuWeights {
            pipeline,
            desc,
            _map: [rows, cols, weights],
            batch: None,
            n_points: w.n_points(),
            n_vertices: w.n_vertices,
            dev,
        })
    }

    /// Each step's per-vertex field of `k` components (`n_vertices × k` values, vertex after
    /// vertex) at the points: `out` gets `steps.len() × n_points × k` values, step after step,
    /// each point's `k` in turn, NaN for points outside. What [`Weights::apply`] gives each step.
    pub fn apply_steps(&mut self, steps: &[&[f32]], k: usize, out: &mut [f32]) -> tetloc_core::Result<()> {
        let (step_in, step_out) = (self.n_vertices * k, self.n_points * k);
        if k == 0 || steps.iter().any(|s| s.len() != step_in) || out.len() != steps.len() * step_out {
            let lens: Vec<usize> = steps.iter().map(|s| s.len()).collect();
            return Err(tetloc_core::Error::Invalid(format!(
                "weights of {} points over {} vertices applied to steps of {lens:?} values of {k} components into {}",
                self.n_points,
                self.n_vertices,
                out.len()
            )));
        }
        if steps.is_empty() || self.n_points == 0 {
            return Ok(());
        }
        // As many steps a batch as BATCH_BYTES hold (at least one), within one buffer each.
        let max = self.dev.max_buffer();
        let per_step = 4 * (step_in + step_out) as u64;
        let fit = (BATCH_BYTES / per_step).min(max / (4 * step_in.max(step_out) as u64));
        if fit == 0 && 4 * step_in.max(step_out) as u64 > max {
            let bytes = 4 * step_in.max(step_out) as u64;
            let e = VkError::TooLarge { name: "a step's values".into(), bytes, limit: max, what: "one buffer" };
            return Err(e.into());
        }
        let batch = (fit.max(1) as usize).min(steps.len());
        // u32 indices in the shader: a batch's values and products.
        let batch = batch.min((u32::MAX as usize / step_in.max(step_out)).max(1));
        self.ensure_batch(batch * step_in, batch * step_out)?;
        for (group, out) in steps.chunks(batch).zip(out.chunks_mut(batch * step_out)) {
            let (values, products) = self.batch.as_ref().expect("ensure_batch made it");
            for (s, step) in group.iter().enumerate() {
                self.dev.write(values, (s * step_in * 4) as u64, bytemuck::cast_slice(step))?;
            }
            let params = Params {
                counts: [self.n_points as u32, self.n_vertices as u32, k as u32, group.len() as u32],
                ..Default::default()
            };
            let (pipeline, desc) = (&self.pipeline, &self.desc);
            let limits = &self.dev.ctx().limits;
            let groups = (self.n_points as u64).div_ceil(WORKGROUP);
            let x = groups.min(limits.max_workgroup_count[0] as u64).max(1);
            let y = groups.div_ceil(x);
            self.dev.run(|r| {
                // SAFETY: recording into a command buffer in the recording state, with live objects.
                unsafe {
                    r.dev.cmd_bind_pipeline(r.cmd, pipeline.bind_point, pipeline.pipeline);
                    r.dev.cmd_bind_descriptor_sets(r.cmd, pipeline.bind_point, desc.layout, 0, &[desc.set], &[]);
                    r.dev.cmd_push_constants(r.cmd, desc.layout, desc.stages, 0, bytemuck::bytes_of(&params));
                    r.dev.cmd_dispatch(r.cmd, x as u32, y as u32, 1);
                }
            })?;
            self.dev.download(products, 0, bytemuck::cast_slice_mut(out))?;
        }
        Ok(())
    }

    /// Batch buffers of at least `values` and `products` floats, bound.
    fn ensure_batch(&mut self, values: usize, products: usize) -> VkResult<()> {
        let big_enough = |b: &Buffer, n: usize| b.size >= (n * 4) as u64;
        if self.batch.as_ref().is_some_and(|(v, p)| big_enough(v, values) && big_enough(p, products)) {
            return Ok(());
        }
        let unbound = self.dev.unbound();
        self.desc.write(&[Binding::buffer(B_STEP_VALUES, unbound), Binding::buffer(B_STEP_OUT, unbound)]);
        self.batch = None;
        let v = self.dev.create_buffer(BufferDesc::io(MemKind::Query, (values * 4) as u64), "step values", None)?;
        let p = self.dev.create_buffer(BufferDesc::io(MemKind::Query, (products * 4) as u64), "step products", None)?;
        self.desc.write(&[Binding::buffer(B_STEP_VALUES, &v), Binding::buffer(B_STEP_OUT, &p)]);
        self.batch = Some((v, p));
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::context::test_context;
    use tetloc_core::{CpuLocator, Mesh};

    /// The products of many steps, batched, equal `Weights::apply`'s bit for bit (f64
    /// devices), for 1 and 3 components, with points outside (NaN rows), on a mesh of tets and
    /// on one of quadratic tets (10 weights a row).
    #[test]
    fn gpu_weights_equal_the_cpu_apply() {
        let Some(ctx) = test_context("gpu_weights_equal_the_cpu_apply") else { return };
        let linear = tetloc_core::gen::generate(tetloc_core::gen::Shape::Jets, 3_000, 2);
        let quadratic = tetloc_testdata::KuhnGrid::new(3).jitter(0.1, 3).order(2).raw();
        for (what, raw) in [("jets", linear), ("quadratic", quadratic)] {
            let mesh = Arc::new(Mesh::new(raw, what).unwrap());
            let (lo, hi) = mesh.file_bounds();
            let mut s = 7u64;
            let mut unit = || {
                s = s.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
                (s >> 11) as f64 / (1u64 << 53) as f64
            };
            let pts: Vec<[f64; 3]> =
                (0..5_000).map(|_| std::array::from_fn(|k| lo[k] + (hi[k] - lo[k]) * (1.2 * unit() - 0.1))).collect();
            let w = Weights::locate(&mut CpuLocator::new(mesh.clone()), &mesh, &pts).unwrap();
            assert!(w.cells.iter().any(|&c| c < 0) && w.cells.iter().any(|&c| c >= 0), "{what}: in and out");
            let mut gpu = GpuWeights::new(&ctx, &w).unwrap();
            for k in [1usize, 3] {
                let steps: Vec<Vec<f32>> = (0..7)
                    .map(|s| (0..w.n_vertices * k).map(|i| ((i * 31 + s * 17) % 101) as f32 * 0.37 - 9.0).collect())
                    .collect();
                let refs: Vec<&[f32]> = steps.iter().map(|s| s.as_slice()).collect();
                let mut got = vec![0f32; steps.len() * w.n_points() * k];
                gpu.apply_steps(&refs, k, &mut got).unwrap();
                for (s, step) in steps.iter().enumerate() {
                    let mut want = vec![0f32; w.n_points() * k];
                    w.apply(step, k, &mut want).unwrap();
                    let got = &got[s * want.len()..(s + 1) * want.len()];
                    if ctx.info().float64 {
                        let bits = |v: &[f32]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
                        assert!(bits(got) == bits(&want), "{what}, k = {k}, step {s}: not the CPU's bits");
                    } else {
                        let close = got.iter().zip(&want).all(|(a, b)| {
                            a.is_nan() == b.is_nan() && (a.is_nan() || (a - b).abs() <= 1e-4 * (1.0 + b.abs()))
                        });
                        assert!(close, "{what}, k = {k}, step {s}");
                    }
                }
            }
            // Bad shapes are errors, not panics.
            assert!(gpu.apply_steps(&[&[1.0]], 1, &mut [0.0; 1]).is_err());
        }
        assert_eq!(ctx.validation_errors(), 0);
    }
}
