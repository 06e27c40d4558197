//! Query ordering (`shaders/order.comp`): before a launch, its points are sorted along the
//! Morton curve over the mesh bounds (a counting sort into `ORDER_BINS` cells), the kernel
//! locates them in that order and writes each answer at the point's original index. Random
//! points over a mesh of more than a few GiB otherwise miss the address-translation caches
//! on nearly every read (NOTES.md, "The random-query collapse").

use super::launch::dispatch_points;
use crate::device::{Device, Recording};
use crate::error::VkResult;
use crate::interface::*;
use crate::memory::{Buffer, BufferDesc, MemKind};
use crate::pipeline::{Binding, Descriptors, Pipeline, Program, Spec};
use crate::shaders;
use ash::vk;
use std::collections::HashMap;

const _: () = assert!(ORDER_BINS == 1 << (3 * ORDER_AXIS_BITS) && ORDER_BLOCKS * ORDER_GROUP == ORDER_BINS);
const _: () = assert!(ORDER_BLOCKS.is_multiple_of(ORDER_GROUP));

/// Batches smaller than this are located as given: ordering costs four dispatches.
pub const ORDER_MIN_POINTS: usize = 1 << 15;

/// The ordering passes' buffers for launches of up to `capacity` points, their descriptor
/// set, and their pipelines by (pass, sample mode).
pub(crate) struct Ordering {
    // Field order is drop order: the pipelines before their layout.
    pipelines: HashMap<(u32, i32), Pipeline>,
    desc: Descriptors,
    /// Each point's key and the block offsets: only held, the descriptor set names them.
    _keys: Buffer,
    _blocks: Buffer,
    bins: Buffer,
    /// The ordered points and the original index of each (the locate pipelines bind them).
    pub points: Buffer,
    pub perm: Buffer,
    /// Random points are made in the order of their tets (`ORDER_TET_FIRST`).
    tet_first: bool,
}

impl Ordering {
    /// Buffers for `capacity` points; `bindings`: the mesh's and the query points' (the keys
    /// pass reads host points or generates them from the mesh); `tet_first`: random points
    /// are made in the order of their tets (a counting sort of the sample indices first).
    pub fn new(dev: &mut Device, capacity: usize, bindings: &[Binding], tet_first: bool) -> VkResult<Ordering> {
        let n = capacity as u64;
        let mut make = |name: &str, bytes: u64| dev.create_buffer(BufferDesc::io(MemKind::Query, bytes), name, None);
        let keys = make("order keys", 4 * n)?;
        let bins = make("order bins", 4 * ORDER_BINS as u64)?;
        let blocks = make("order blocks", 4 * ORDER_BLOCKS as u64)?;
        let points = make("ordered points", 12 * n)?;
        let perm = make("order permutation", 4 * n)?;
        let mut all = bindings.to_vec();
        all.extend([
            Binding::buffer(B_ORDER_KEYS, &keys),
            Binding::buffer(B_ORDER_BINS, &bins),
            Binding::buffer(B_ORDER_BLOCKS, &blocks),
            Binding::buffer(B_ORDER_POINTS, &points),
            Binding::buffer(B_ORDER_PERM, &perm),
        ]);
        let desc = Descriptors::new(dev.ctx(), &all, vk::ShaderStageFlags::COMPUTE)?;
        Ok(Ordering { pipelines: HashMap::new(), desc, _keys: keys, _blocks: blocks, bins, points, perm, tet_first })
    }

    /// Whether points of `sample` mode are made in tet order first.
    pub(super) fn tets_first(&self, sample: i32) -> bool {
        self.tet_first && sample == SAMPLE_RANDOM
    }

    /// Creates the passes' pipelines for points of `sample` mode (SAMPLE_*), once; `spec`: the
    /// mesh's split-array constants.
    pub fn prepare(&mut self, dev: &mut Device, sample: i32, spec: &Spec) -> VkResult<()> {
        let tet_first = self.tets_first(sample);
        let mut passes = vec![ORDER_KEYS, ORDER_SCAN_BINS, ORDER_SCAN_BLOCKS, ORDER_SCATTER];
        if tet_first {
            passes.extend([ORDER_TET_KEYS, ORDER_TET_SCATTER]);
        }
        for pass in passes {
            if self.pipelines.contains_key(&(pass, sample)) {
                continue;
            }
            // Generated points are recorded by the keys pass: the scatter pass moves them.
            let spec = spec
                .clone()
                .set(sc::ORDER_PASS, pass)
                .set(sc::SAMPLE_MODE, sample as u32)
                .set(sc::RECORD_POINTS, (sample != SAMPLE_HOST) as u32)
                .set(sc::ORDER_TET_FIRST, tet_first as u32);
            let p = Program::Compute(shaders::ORDER).pipeline(dev, self.desc.layout, false, &spec)?;
            self.pipelines.insert((pass, sample), p);
        }
        Ok(())
    }

    /// Records the ordering of one launch's points (`params`, as the locate launch's);
    /// `prepare` must have run for `sample`. Ends with a barrier: the launch may follow.
    pub fn record(&self, r: &Recording, params: &Params, sample: i32) {
        let (dev, cmd) = (r.dev, r.cmd);
        let n = params.counts[0] as u64;
        // A counting sort: clear the bins, key and count, the two scans, scatter.
        let sort = |keys: u32, scatter: u32| {
            [
                None,
                Some((keys, None)),
                Some((ORDER_SCAN_BINS, Some(ORDER_BLOCKS))),
                Some((ORDER_SCAN_BLOCKS, Some(1))),
                Some((scatter, None)),
            ]
        };
        let mut steps = vec![];
        if self.tets_first(sample) {
            steps.extend(sort(ORDER_TET_KEYS, ORDER_TET_SCATTER));
        }
        steps.extend(sort(ORDER_KEYS, ORDER_SCATTER));
        for step in steps {
            let Some((pass, groups)) = step else {
                // SAFETY: recording into a command buffer in the recording state; the bins
                // buffer is live and a transfer destination.
                unsafe { dev.cmd_fill_buffer(cmd, self.bins.buffer, 0, vk::WHOLE_SIZE, 0) };
                r.barrier();
                continue;
            };
            let p = &self.pipelines[&(pass, sample)];
            // SAFETY: recording into a command buffer in the recording state, with a live
            // pipeline and descriptor set of the same layout.
            unsafe {
                dev.cmd_bind_pipeline(cmd, p.bind_point, p.pipeline);
                dev.cmd_bind_descriptor_sets(cmd, p.bind_point, self.desc.layout, 0, &[self.desc.set], &[]);
                dev.cmd_push_constants(cmd, self.desc.layout, self.desc.stages, 0, bytemuck::bytes_of(params));
            }
            match groups {
                // SAFETY: as above.
                Some(g) => unsafe { dev.cmd_dispatch(cmd, g, 1, 1) },
                None => dispatch_points(r, n, ORDER_GROUP),
            }
            r.barrier();
        }
    }
}
