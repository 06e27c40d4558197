//! Recording kernel launches: a compute dispatch (a 2D grid of workgroups when one row is not
//! enough) or a ray-tracing launch, and for deferred exact tests the indirect second pass.

use crate::device::Recording;
use crate::interface::{Params, OUT_CELL, OUT_FIELDS, OUT_IDS, OUT_VERTEX};
use crate::pipeline::{Descriptors, Pipeline};
use ash::vk;
use std::collections::HashMap;

/// What a launch writes a point: OUTPUT_MODE, and with OUT_FIELDS how many fields (the
/// first of B_FIELD's buffers) and which of them are per cell (FIELD_COUNT, FIELD_CELLS).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub(crate) struct Output {
    pub mode: i32,
    pub fields: u32,
    pub cells: u32,
}

impl Output {
    pub const IDS: Output = Output { mode: OUT_IDS, fields: 0, cells: 0 };

    /// The value of the field bound first, per vertex or per cell (OUT_VERTEX, OUT_CELL).
    pub fn single(cell: bool) -> Output {
        Output { mode: if cell { OUT_CELL } else { OUT_VERTEX }, fields: 0, cells: 0 }
    }

    /// The ids and the values of the first `fields` bound fields, bit j of `cells` set for a
    /// per-cell field j (OUT_FIELDS); the ids alone without fields.
    pub fn fields(fields: u32, cells: u32) -> Output {
        match fields {
            0 => Output::IDS,
            _ => Output { mode: OUT_FIELDS, fields, cells },
        }
    }

    /// 4-byte words a point: its id (or value), then its fields' values.
    pub fn words(&self) -> usize {
        1 + self.fields as usize
    }
}

/// One compiled variant of a kernel's locate pipeline.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub(crate) struct Variant {
    /// SAMPLE_* of the interface, and what the launch writes.
    pub sample: i32,
    pub output: Output,
    /// Write generated points back (tests).
    pub record: bool,
    /// Locate the points query ordering sorted (order.rs), answers to their original indices.
    pub ordered: bool,
}

/// The locate pipelines of a locator and the descriptor set they bind.
pub(crate) struct Launcher {
    // Field order is drop order: the pipelines before their layout.
    pub pipelines: HashMap<Variant, Pipeline>,
    /// With deferred exact tests: each variant's exact second pass.
    pub exact_pipelines: HashMap<Variant, Pipeline>,
    pub desc: Descriptors,
    pub workgroup: u32,
}

impl Launcher {
    /// The launch of variant `v` (whose pipelines must exist); `deferred`: the deferred-sample
    /// list, when the locator defers exact tests.
    pub fn launch(&self, v: Variant, deferred: Option<vk::Buffer>) -> Launch<'_> {
        Launch {
            desc: &self.desc,
            pipeline: &self.pipelines[&v],
            exact: self.exact_pipelines.get(&v).zip(deferred),
            workgroup: self.workgroup,
        }
    }
}

/// Everything needed to record one kernel launch.
pub(crate) struct Launch<'a> {
    desc: &'a Descriptors,
    pipeline: &'a Pipeline,
    /// The exact second pass and the deferred-sample list.
    exact: Option<(&'a Pipeline, vk::Buffer)>,
    workgroup: u32,
}

impl Launch<'_> {
    /// Records one launch over `params.counts[0]` points.
    pub fn record(&self, r: &Recording, params: &Params) {
        let (dev, cmd, p) = (r.dev, r.cmd, self.pipeline);
        let n = params.counts[0] as u64;
        let bind = |p: &Pipeline| {
            // SAFETY: recording into a command buffer in the recording state, with live objects.
            unsafe {
                dev.cmd_bind_pipeline(cmd, p.bind_point, p.pipeline);
                dev.cmd_bind_descriptor_sets(cmd, p.bind_point, self.desc.layout, 0, &[self.desc.set], &[]);
                dev.cmd_push_constants(cmd, self.desc.layout, self.desc.stages, 0, bytemuck::bytes_of(params));
            }
        };
        if let Some((_, list)) = self.exact {
            // Empty the deferred-sample list: dispatch size (0, 1, 1), count 0.
            r.barrier();
            // SAFETY: as above; 16 bytes, far below vkCmdUpdateBuffer's limit.
            unsafe { dev.cmd_update_buffer(cmd, list, 0, bytemuck::cast_slice(&[0u32, 1, 1, 0])) };
            r.barrier();
        }
        bind(p);
        match &p.sbt {
            None => dispatch_points(r, n, self.workgroup),
            Some(sbt) => {
                let l = &r.ctx.limits;
                let max_width = l.max_workgroup_count[0] as u64 * l.max_workgroup_size[0] as u64;
                let width = n.min(max_width).max(1);
                let empty = vk::StridedDeviceAddressRegionKHR::default();
                let rt = r.ctx.rt.as_ref().expect("a ray-tracing pipeline exists only with ray tracing");
                let (w, h) = (width as u32, n.div_ceil(width) as u32);
                // SAFETY: as above; the shader binding table lives with the pipeline.
                unsafe { rt.pipeline.cmd_trace_rays(cmd, &sbt.raygen, &sbt.miss, &sbt.hit, &empty, w, h, 1) };
            }
        }
        if let Some((exact, list)) = self.exact {
            // The samples the f32 pass deferred, exactly: as many workgroups as it counted.
            r.barrier();
            bind(exact);
            // SAFETY: as above; the list starts with the dispatch size the first pass counted.
            unsafe { dev.cmd_dispatch_indirect(cmd, list, 0) };
        }
    }
}

/// Dispatches a compute pipeline over `n` points, one invocation each, in workgroups of
/// `workgroup`: a 2D grid of workgroups when one row is not enough (the shader linearises it).
pub(crate) fn dispatch_points(r: &Recording, n: u64, workgroup: u32) {
    let groups = n.div_ceil(workgroup as u64);
    let x = groups.min(r.ctx.limits.max_workgroup_count[0] as u64).max(1);
    // SAFETY: recording into a command buffer in the recording state, a compute pipeline bound.
    unsafe { r.dev.cmd_dispatch(r.cmd, x as u32, groups.div_ceil(x) as u32, 1) };
}
