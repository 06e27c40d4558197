//! A microbenchmark of random reads over growing spans of device memory: the measurement
//! behind issue 12's random-query collapse. A locate query touches a handful of 16–64-byte
//! records (grid cell, tets, vertices, neighbours, nodes) at addresses that look random when
//! the queries are; this probe reads tet-sized records (uvec4) at hashed addresses within a
//! span that grows, through the same split-buffer layout as the mesh, and reports reads/s.
//! A rate that falls off a cliff past some span, while coalesced reads over the same span do
//! not, is address translation (TLB reach), not DRAM bandwidth.

use crate::context::Context;
use crate::device::{Device, Split};
use crate::error::{VkError, VkResult};
use crate::interface::{
    Params, B_OUT, B_TETS, B_TETS_HI, MAX_CHUNKS, MEMPROBE_DEPENDENT, MEMPROBE_INDEPENDENT, MEMPROBE_INIT,
    MEMPROBE_SEQUENTIAL,
};
use crate::memory::{BufferDesc, MemKind, Recording};
use crate::pipeline::{Binding, Descriptors, Pipeline, Program, Spec};
use crate::{interface::sc, shaders};
use ash::vk;
use std::sync::Arc;
use std::time::Instant;

/// Bytes per element: one tet record (uvec4).
pub const ELEMENT_BYTES: u64 = 16;
const WORKGROUP: u64 = 256;

/// How the probe's addresses follow each other.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Pattern {
    /// Coalesced: neighbouring invocations read neighbouring elements (the bandwidth baseline).
    Sequential,
    /// Hashed addresses, independent of the values read (many reads in flight).
    Independent,
    /// Each address is a hash of the value just read (one read in flight per invocation, like
    /// a walk's next tet).
    Dependent,
}

impl Pattern {
    pub const ALL: [Pattern; 3] = [Pattern::Sequential, Pattern::Independent, Pattern::Dependent];

    pub fn name(self) -> &'static str {
        match self {
            Pattern::Sequential => "sequential",
            Pattern::Independent => "independent",
            Pattern::Dependent => "dependent",
        }
    }

    fn mode(self) -> u32 {
        match self {
            Pattern::Sequential => MEMPROBE_SEQUENTIAL,
            Pattern::Independent => MEMPROBE_INDEPENDENT,
            Pattern::Dependent => MEMPROBE_DEPENDENT,
        }
    }
}

/// What to measure.
#[derive(Clone, Debug)]
pub struct MemProbeOptions {
    /// Spans to read within, in bytes (rounded down to whole elements); the largest is allocated.
    pub spans: Vec<u64>,
    /// Invocations per run and reads per invocation.
    pub invocations: u32,
    pub reads: u32,
    /// Seconds of warm-up load before the first span (the clocks ramp up), timed runs per point.
    pub warmup_seconds: f64,
    pub repeats: usize,
    /// Split arrays above this many bytes (a test hook; default: the device's limits).
    pub max_buffer_bytes: Option<u64>,
}

impl Default for MemProbeOptions {
    fn default() -> Self {
        MemProbeOptions {
            // 1 MiB to 48 GiB.
            spans: [1u64, 2, 4, 8, 16, 32, 64, 128, 256, 512, 1024, 2048, 4096, 8192, 16384, 32768, 49152]
                .iter()
                .map(|mib| mib << 20)
                .collect(),
            invocations: 1 << 18,
            reads: 32,
            warmup_seconds: 1.0,
            repeats: 5,
            max_buffer_bytes: None,
        }
    }
}

/// One measured point.
#[derive(Clone, Debug)]
pub struct MemProbeRow {
    pub device: String,
    pub span_bytes: u64,
    pub pattern: &'static str,
    pub reads: u64,
    /// Median GPU seconds of one run.
    pub median_s: f64,
    pub reads_per_s: f64,
}

/// The probe's state on one device: the split array and the pipeline.
pub struct MemProbe {
    // Field order is drop order: the pipeline and set before the device they use.
    kernel: ProbeKernel,
    sums: crate::memory::Buffer,
    /// Kept alive for the descriptor set that points at it.
    _array: Split,
    elements: u64,
    invocations: u32,
    dev: Device,
}

impl MemProbe {
    /// Allocates `span_bytes` of device memory (split like the mesh's tets), `invocations`
    /// result words, and fills every element i with i.
    pub fn new(
        ctx: &Arc<Context>,
        span_bytes: u64,
        invocations: u32,
        max_buffer_bytes: Option<u64>,
    ) -> VkResult<MemProbe> {
        let mut dev = Device::new(ctx, 1 << 20, max_buffer_bytes)?;
        let elements = span_bytes / ELEMENT_BYTES;
        // The shader's grid-stride init and u32 indices need span + invocations < 2^32.
        if elements == 0 || elements + u64::from(invocations) >= 1 << 32 {
            return Err(VkError::TooLarge {
                name: "memory probe span".into(),
                bytes: span_bytes,
                limit: ((1u64 << 32) - 1 - u64::from(invocations)) * ELEMENT_BYTES,
                what: "u32 element indices",
            });
        }
        let per_buffer = (dev.max_buffer() / ELEMENT_BYTES).min(u64::from(u32::MAX));
        let parts = elements.div_ceil(per_buffer);
        if parts > u64::from(MAX_CHUNKS) {
            let limit = per_buffer * u64::from(MAX_CHUNKS) * ELEMENT_BYTES;
            return Err(VkError::TooLarge {
                name: "memory probe span".into(),
                bytes: span_bytes,
                limit,
                what: "split buffers",
            });
        }
        let usage = vk::BufferUsageFlags::STORAGE_BUFFER;
        let mut buffers = Vec::new();
        for k in 0..parts {
            let n = per_buffer.min(elements - k * per_buffer);
            let desc = BufferDesc::device(MemKind::Structure, n * ELEMENT_BYTES, usage);
            buffers.push(dev.create_buffer(desc, format!("probe array {k}"), None)?);
        }
        let per_chunk = if parts > 1 { per_buffer as u32 } else { 0 };
        let array = Split { parts: buffers, per_chunk };
        let sums_desc = BufferDesc::device(
            MemKind::Query,
            u64::from(invocations) * 4,
            vk::BufferUsageFlags::STORAGE_BUFFER | vk::BufferUsageFlags::TRANSFER_SRC,
        );
        let sums = dev.create_buffer(sums_desc, "probe sums", None)?;
        let mut bindings = Binding::split(B_TETS, B_TETS_HI, Some(&array), dev.unbound()).to_vec();
        bindings.push(Binding::buffer(B_OUT, &sums));
        let program = Program::Compute(shaders::MEMPROBE);
        let desc = Descriptors::new(ctx, &bindings, program.stages())?;
        let spec = Spec::default().set(sc::TETS_CHUNK, per_chunk);
        let pipeline = program.pipeline(&mut dev, desc.layout, false, &spec)?;
        let mut probe =
            MemProbe { kernel: ProbeKernel { pipeline, desc }, sums, _array: array, elements, invocations, dev };
        let init = probe.params(MEMPROBE_INIT, 0, elements);
        probe.dev.run(|r| probe.kernel.record(r, &init))?;
        Ok(probe)
    }

    fn params(&self, mode: u32, reads: u32, span_elements: u64) -> Params {
        Params { counts: [self.invocations, reads, span_elements as u32, mode], ..Default::default() }
    }
}

/// The probe's pipeline and descriptor set.
struct ProbeKernel {
    pipeline: Pipeline,
    desc: Descriptors,
}

impl ProbeKernel {
    fn record(&self, r: &Recording, params: &Params) {
        let groups = u64::from(params.counts[0]).div_ceil(WORKGROUP) as u32;
        // SAFETY: recording into a command buffer in the recording state, with live objects.
        unsafe {
            r.dev.cmd_bind_pipeline(r.cmd, self.pipeline.bind_point, self.pipeline.pipeline);
            r.dev.cmd_bind_descriptor_sets(r.cmd, self.pipeline.bind_point, self.desc.layout, 0, &[self.desc.set], &[]);
            r.dev.cmd_push_constants(r.cmd, self.desc.layout, self.desc.stages, 0, bytemuck::bytes_of(params));
            r.dev.cmd_dispatch(r.cmd, groups, 1, 1);
        }
    }
}

impl MemProbe {
    /// Each invocation's sum of the values it read (the tests compare with [`expected_sums`]).
    pub fn sums(&mut self, pattern: Pattern, reads: u32, span_bytes: u64) -> VkResult<Vec<u32>> {
        let p = self.params(pattern.mode(), reads, self.span_elements(span_bytes));
        self.dev.run(|r| self.kernel.record(r, &p))?;
        let mut out = vec![0u8; self.invocations as usize * 4];
        self.dev.download(&self.sums, 0, &mut out)?;
        Ok(bytemuck::pod_collect_to_vec(&out))
    }

    fn span_elements(&self, span_bytes: u64) -> u64 {
        (span_bytes / ELEMENT_BYTES).clamp(1, self.elements)
    }

    /// Median GPU seconds of `repeats` runs.
    pub fn time(&mut self, pattern: Pattern, reads: u32, span_bytes: u64, repeats: usize) -> VkResult<f64> {
        let p = self.params(pattern.mode(), reads, self.span_elements(span_bytes));
        let mut times = self.dev.time_runs(repeats, |r| self.kernel.record(r, &p))?;
        times.sort_by(f64::total_cmp);
        Ok(times[times.len() / 2])
    }
}

/// Every span and pattern of `opts`, on one allocation of the largest span.
pub fn random_reads(ctx: &Arc<Context>, opts: &MemProbeOptions) -> VkResult<Vec<MemProbeRow>> {
    let Some(&largest) = opts.spans.iter().max() else { return Ok(Vec::new()) };
    let mut probe = MemProbe::new(ctx, largest, opts.invocations, opts.max_buffer_bytes)?;
    let t = Instant::now();
    while t.elapsed().as_secs_f64() < opts.warmup_seconds {
        probe.time(Pattern::Independent, opts.reads, largest, 1)?;
    }
    let mut rows = Vec::new();
    for &span in &opts.spans {
        for pattern in Pattern::ALL {
            let median_s = probe.time(pattern, opts.reads, span, opts.repeats.max(1))?;
            let reads = u64::from(opts.invocations) * u64::from(opts.reads);
            rows.push(MemProbeRow {
                device: ctx.info().name.clone(),
                span_bytes: probe.span_elements(span) * ELEMENT_BYTES,
                pattern: pattern.name(),
                reads,
                median_s,
                reads_per_s: reads as f64 / median_s,
            });
        }
    }
    Ok(rows)
}

/// The shader's hash (lowbias32).
fn hash(mut x: u32) -> u32 {
    x ^= x >> 16;
    x = x.wrapping_mul(0x7feb_352d);
    x ^= x >> 15;
    x = x.wrapping_mul(0x846c_a68b);
    x ^= x >> 16;
    x
}

/// What each invocation's sum must be: the shader's address sequence, on the host, over an
/// array whose element i holds i.
pub fn expected_sums(pattern: Pattern, invocations: u32, reads: u32, span_elements: u32) -> Vec<u32> {
    (0..invocations)
        .map(|id| {
            let mut i = match pattern {
                Pattern::Sequential => id % span_elements,
                _ => hash(id) % span_elements,
            };
            let mut sum = 0u32;
            for k in 0..reads {
                let v = i;
                sum = sum.wrapping_add(v);
                i = match pattern {
                    Pattern::Sequential => ((u64::from(i) + u64::from(invocations)) % u64::from(span_elements)) as u32,
                    Pattern::Dependent => {
                        hash(v.wrapping_add(id.wrapping_mul(0x9e37_79b9)).wrapping_add(k)) % span_elements
                    }
                    Pattern::Independent => {
                        hash(id.wrapping_mul(reads).wrapping_add(k).wrapping_add(1)) % span_elements
                    }
                };
            }
            sum
        })
        .collect()
}
