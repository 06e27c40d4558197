//! Stream tracing on the GPU (`tetloc_core::ops::trace` with RK4): `shaders/stream.comp` runs
//! each particle's whole line in one invocation, every lookup a walk through face neighbours
//! from the particle's last tet, the entry grid and BVH only when the walk fails. Lines come
//! back in segments: a launch advances every particle until it has written a segment's points
//! (or ended), the host collects them and launches the next, so memory stays bounded whatever
//! the lines' length. Each point comes with the tet its velocity came from ([`Line::tets`])
//! and the line fields there ([`Line::values`]), computed as the GPU's sampler computes them
//! (f32 data, up to MAX_FIELDS components; else the host samples them at those tets,
//! `LineArrays::at_tets`), so no second search runs. Where the kernel has no stream shader
//! (the rt kernels), the integrator is adaptive or the mesh is mixed or higher-order,
//! [`VulkanLocator::trace_lines`] declines and `trace_with` drives the locator one
//! Runge–Kutta stage at a time instead.
//!
//! The GPU integrates in f32 in the mesh's working frame where the CPU integrates in f64, so
//! lines agree to rounding (about 1e-7 of the domain a step), not bit for bit; a step that
//! ends within rounding of the boundary may end one step apart.

use crate::error::{VkError, VkResult};
use crate::interface::*;
use crate::locator::VulkanLocator;
use crate::memory::{Buffer, BufferDesc, MemKind, Recording};
use crate::pipeline::{Binding, Descriptors, Pipeline};
use ash::vk;
use rayon::prelude::*;
use std::time::Instant;
use tetloc_core::geom::Vec3;
use tetloc_core::mesh::FieldLocation;
use tetloc_core::ops::trace::{Integrator, Line, Reason, TraceOptions};

/// Most particles one launch advances; more lines run group after group.
const GROUP: usize = 1 << 22;
/// Bytes of line points (positions, tets and line fields) a segment of a group may write.
const SEGMENT_BYTES: usize = 1 << 30;
const WORKGROUP: u32 = 128;

const _: () = assert!(
    REASON_OUT_OF_DOMAIN == Reason::OutOfDomain as i32
        && REASON_OUT_OF_LENGTH == Reason::OutOfLength as i32
        && REASON_OUT_OF_STEPS == Reason::OutOfSteps as i32
        && REASON_STAGNATION == Reason::Stagnation as i32
        && REASON_OUT_OF_TIME == Reason::OutOfTime as i32
);

/// What a tracing run cost and how its lookups went.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct StreamStats {
    /// Seconds of the tracing launches: GPU timestamps in benchmarks, else the submissions'
    /// host time (transfers between segments excluded).
    pub seconds: f64,
    pub lines: usize,
    /// Steps taken (line points after the seeds).
    pub steps: u64,
    /// Velocity lookups (four a step, one at the seed, and those of a last step that left).
    pub lookups: u64,
    /// Lookups the hint's walk did not answer, so that the entry grid and BVH search ran.
    pub fallbacks: u64,
    /// Tets the walks visited (the hints' and the fresh searches' walk starts).
    pub walk_tets: u64,
    /// Launches (segments).
    pub launches: usize,
}

impl StreamStats {
    fn add(&mut self, particles: &[StreamParticle]) {
        for p in particles {
            self.steps += (p.state[3].max(1) - 1) as u64;
            self.lookups += p.counts[2] as u64;
            self.fallbacks += p.counts[3] as u64;
            self.walk_tets += p.len_walk[2] as u64;
        }
    }
}

/// The stream pipeline over a locator's mesh and structure, with buffers for `group`
/// particles writing `seg` points each per launch.
struct Stream {
    // Field order is drop order: the pipeline before the buffers it names.
    pipeline: Pipeline,
    desc: Descriptors,
    push: Params,
    params: StreamParams,
    params_buf: Buffer,
    particles: Buffer,
    lines: Buffer,
    /// The tet of each line point.
    tets: Buffer,
    /// The line fields at each line point (`fields` a point).
    values: Buffer,
    fields: usize,
    _vector: Buffer,
    _neighbors: Option<Buffer>,
}

/// Points a particle writes per launch for `group` particles with `fields` line fields (a
/// point's position and time, its tet and the fields' values): the whole line when it fits.
fn segment_points(group: usize, max_steps: usize, fields: usize) -> usize {
    // The seed, VTK's max_steps + 1 steps, and room to find that the line has ended.
    let whole = max_steps.saturating_add(3);
    let point_bytes = 16 + 4 + 4 * fields;
    (SEGMENT_BYTES / (point_bytes * group.max(1))).clamp(2, whole.max(2))
}

/// The particles of `jobs` (seed index, backward) at their seeds (the file's coordinates),
/// not yet looked up; a seed with a NaN or infinite coordinate gives no line, as one outside.
fn particles(seeds: &[Vec3], jobs: &[(u32, bool)], frame: tetloc_core::mesh::Frame) -> Vec<StreamParticle> {
    jobs.iter()
        .map(|&(seed, backward)| {
            let p = seeds[seed as usize];
            let status = if tetloc_core::locate::is_finite(p) { STREAM_SEED } else { REASON_OUT_OF_DOMAIN };
            let w = frame.to_working_f32(p);
            StreamParticle {
                seed: [w[0], w[1], w[2], 0.0],
                state: [OUTSIDE, 0, status, 0],
                counts: [0, backward as u32, 0, 0],
                ..Default::default()
            }
        })
        .collect()
}

impl Stream {
    /// `None` where the locator has no stream shader for these options. The components
    /// `line_fields` are sampled at each point where they are f32 data and at most MAX_FIELDS
    /// (else none are: the host samples them).
    fn open(
        loc: &mut VulkanLocator,
        o: &TraceOptions,
        vector: [&str; 3],
        line_fields: &[&str],
        group: usize,
        seg: usize,
        hint: bool,
    ) -> tetloc_core::Result<Option<Stream>> {
        let mesh = loc.mesh().clone();
        if o.integrator != Integrator::Rk4 || mesh.cells.is_some() || mesh.tet_nodes.is_some() {
            return Ok(None);
        }
        let fields = [mesh.field(vector[0])?, mesh.field(vector[1])?, mesh.field(vector[2])?];
        let location = fields[0].location;
        if fields.iter().any(|f| f.location != location) {
            return Ok(None);
        }
        let output = match location {
            FieldLocation::Vertex => OUT_VERTEX,
            FieldLocation::Cell => OUT_CELL,
        };
        if loc.plan().stream.is_none() {
            return Ok(None);
        }
        let sampled = line_fields.len() <= MAX_FIELDS as usize
            && line_fields.iter().all(|c| mesh.field(c).is_ok_and(|f| f.values64.is_none()));
        let line_fields = if sampled { line_fields } else { &[] };
        let cells = match line_fields.is_empty() {
            true => 0,
            false => loc.ensure_fields(line_fields)?.cells,
        };
        let mut res = loc.resources_for(output, !line_fields.is_empty());
        let Some(program) = res.plan.stream else { return Ok(None) };
        let n = fields[0].values.len();
        if (12 * n) as u64 > res.dev.device_max_buffer() {
            return Ok(None); // the batch path reads the components one buffer each
        }
        let interleaved: Vec<f32> = (0..n).flat_map(|i| fields.map(|f| f.values[i])).collect();
        let neighbors = res.bind_own_neighbors("stream tet neighbours")?;
        let dev = res.dev;
        let storage = vk::BufferUsageFlags::STORAGE_BUFFER;
        let vector_buf =
            dev.upload("stream vector field", MemKind::Mesh, storage, bytemuck::cast_slice(&interleaved))?;
        let params_desc = BufferDesc::device(
            MemKind::Query,
            std::mem::size_of::<StreamParams>() as u64,
            storage | vk::BufferUsageFlags::TRANSFER_DST,
        );
        let params_buf = dev.create_buffer(params_desc, "stream parameters", None)?;
        let particle_bytes = (group * std::mem::size_of::<StreamParticle>()) as u64;
        let particles = dev.create_buffer(BufferDesc::io(MemKind::Query, particle_bytes), "stream particles", None)?;
        let lines =
            dev.create_buffer(BufferDesc::io(MemKind::Query, (group * seg * 16) as u64), "stream lines", None)?;
        let tets =
            dev.create_buffer(BufferDesc::io(MemKind::Query, (group * seg * 4) as u64), "stream line tets", None)?;
        let value_bytes = (group * seg * 4 * line_fields.len()).max(4) as u64;
        let values = dev.create_buffer(BufferDesc::io(MemKind::Query, value_bytes), "stream line values", None)?;
        let mut bindings = res.bindings;
        bindings.extend([
            Binding::buffer(B_STREAM, &params_buf),
            Binding::buffer(B_STREAM_VECTOR, &vector_buf),
            Binding::buffer(B_STREAM_PARTICLES, &particles),
            Binding::buffer(B_STREAM_LINES, &lines),
            Binding::buffer(B_STREAM_TETS, &tets),
            Binding::buffer(B_STREAM_VALUES, &values),
        ]);
        let ctx = dev.ctx().clone();
        let desc = Descriptors::new(&ctx, &bindings, program.stages())?;
        let spec = (res.spec.set(sc::STREAM_HINT, hint as u32).set(sc::WORKGROUP, WORKGROUP))
            .set(sc::FIELD_COUNT, line_fields.len() as u32)
            .set(sc::FIELD_CELLS, cells);
        let pipeline = program.pipeline(dev, desc.layout, res.f64, &spec)?;
        let scale = mesh.info.frame.scale;
        let bits = |a: f64, b: f64| {
            let (a, b) = (a.to_bits(), b.to_bits());
            [a as u32, (a >> 32) as u32, b as u32, (b >> 32) as u32]
        };
        let params = StreamParams {
            limits: [o.step as f32, o.max_length as f32, o.max_time as f32, o.terminal_speed as f32],
            limits64_a: bits(o.step, o.max_length),
            limits64_b: bits(o.max_time, o.terminal_speed),
            frame: [scale as f32, 0.0, 0.0, 0.0],
            counts: [0, seg as u32, o.max_steps.min(i32::MAX as usize - 1) as u32, 0],
        };
        Ok(Some(Stream {
            pipeline,
            desc,
            push: res.params,
            params,
            params_buf,
            particles,
            lines,
            tets,
            values,
            fields: line_fields.len(),
            _vector: vector_buf,
            _neighbors: neighbors,
        }))
    }

    /// Records the parameters for `n` particles.
    fn record_params(&self, r: &Recording, n: usize) {
        let p = StreamParams { counts: [n as u32, self.params.counts[1], self.params.counts[2], 0], ..self.params };
        // SAFETY: recording into the device object's command buffer; the update is far below
        // vkCmdUpdateBuffer's 64 KiB limit and a multiple of 4 bytes.
        unsafe { r.dev.cmd_update_buffer(r.cmd, self.params_buf.buffer, 0, bytemuck::bytes_of(&p)) };
        r.barrier();
    }

    /// Records one launch over `n` particles.
    fn record_launch(&self, r: &Recording, n: usize) {
        self.pipeline.record_points(r, &self.desc, &self.push, n, WORKGROUP);
    }
}

impl VulkanLocator {
    /// `tetloc_core::ops::trace::trace`'s lines for `seeds` (the file's coordinates), traced
    /// on the GPU by the kernel's stream shader, with the field components `fields` sampled
    /// at each point where the kernel can ([`Line::values`]: f32 data, at most MAX_FIELDS);
    /// `None` where there is no stream shader for these options (see the module documentation).
    pub fn trace_rk4(
        &mut self,
        seeds: &[Vec3],
        o: &TraceOptions,
        vector: [&str; 3],
        fields: &[&str],
        progress: &mut dyn FnMut(usize) -> tetloc_core::Result<()>,
    ) -> tetloc_core::Result<Option<(Vec<Line>, StreamStats)>> {
        o.check()?;
        let jobs = o.jobs(seeds.len());
        let group = jobs.len().clamp(1, GROUP);
        // As Stream::open decides: at most MAX_FIELDS components, else the host samples them.
        let k = if fields.len() <= MAX_FIELDS as usize { fields.len() } else { 0 };
        let seg = segment_points(group, o.max_steps, k);
        self.trace_in_segments(seeds, o, vector, fields, seg, true, progress)
    }

    /// [`Self::trace_rk4`] with `seg` points a particle per launch, with or without the hint.
    #[allow(clippy::too_many_arguments)]
    fn trace_in_segments(
        &mut self,
        seeds: &[Vec3],
        o: &TraceOptions,
        vector: [&str; 3],
        fields: &[&str],
        seg: usize,
        hint: bool,
        progress: &mut dyn FnMut(usize) -> tetloc_core::Result<()>,
    ) -> tetloc_core::Result<Option<(Vec<Line>, StreamStats)>> {
        let jobs = o.jobs(seeds.len());
        let group = jobs.len().clamp(1, GROUP);
        let Some(s) = Stream::open(self, o, vector, fields, group, seg, hint)? else { return Ok(None) };
        let k = s.fields;
        let frame = self.mesh().info.frame;
        let mut stats = StreamStats { lines: jobs.len(), ..Default::default() };
        let mut lines = Vec::new();
        let mut done = 0;
        for chunk in jobs.chunks(group) {
            let n = chunk.len();
            let init = particles(seeds, chunk, frame);
            let dev = self.device();
            dev.write(&s.particles, 0, bytemuck::cast_slice(&init))?;
            let mut state = init;
            let mut points: Vec<Vec<[f64; 3]>> = vec![Vec::new(); n];
            let mut times: Vec<Vec<f64>> = vec![Vec::new(); n];
            let mut tets: Vec<Vec<i32>> = vec![Vec::new(); n];
            let mut values: Vec<Vec<f32>> = vec![Vec::new(); n];
            // Zeroed by the allocator (pages fault in on every core as the read-back fills
            // them): `vec![Vec4::default(); ..]` wrote its 512 MB on one core, batch after batch.
            let mut written: Vec<Vec4> = bytemuck::zeroed_vec(n * seg);
            let mut written_tets: Vec<i32> = bytemuck::zeroed_vec(n * seg);
            let mut written_values: Vec<f32> = bytemuck::zeroed_vec(n * seg * k);
            loop {
                let t = Instant::now();
                dev.run(|r| {
                    s.record_params(r, n);
                    s.record_launch(r, n);
                })?;
                stats.seconds += t.elapsed().as_secs_f64();
                stats.launches += 1;
                dev.download(&s.particles, 0, bytemuck::cast_slice_mut(&mut state))?;
                let last = state.iter().rposition(|p| p.counts[0] > 0).map_or(0, |j| j + 1);
                dev.download(&s.lines, 0, bytemuck::cast_slice_mut(&mut written[..last * seg]))?;
                dev.download(&s.tets, 0, bytemuck::cast_slice_mut(&mut written_tets[..last * seg]))?;
                if k > 0 {
                    dev.download(&s.values, 0, bytemuck::cast_slice_mut(&mut written_values[..last * seg * k]))?;
                }
                // Each particle's new points onto its line, on every core: particle j's from
                // slot j·seg on.
                let (w, t, v) = (&written, &written_tets, &written_values);
                let lines_so_far = (points.par_iter_mut().zip(times.par_iter_mut()))
                    .zip(tets.par_iter_mut().zip(values.par_iter_mut()));
                (lines_so_far.zip(&state[..last]).enumerate()).for_each(
                    |(j, (((points, times), (tets, values)), p))| {
                        let slots = j * seg..j * seg + p.counts[0] as usize;
                        points.extend(w[slots.clone()].iter().map(|w| frame.to_file([w.0[0], w.0[1], w.0[2]])));
                        times.extend(w[slots.clone()].iter().map(|w| w.0[3] as f64));
                        tets.extend_from_slice(&t[slots.clone()]);
                        values.extend_from_slice(&v[slots.start * k..slots.end * k]);
                    },
                );
                let live = state.iter().filter(|p| p.state[2] == STREAM_LIVE).count();
                progress(done + n - live)?;
                if live == 0 {
                    break;
                }
            }
            done += n;
            stats.add(&state);
            for (((((&(seed, backward), p), points), time), tets), values) in
                chunk.iter().zip(&state).zip(points).zip(times).zip(tets).zip(values)
            {
                if points.len() > 1 {
                    lines.push(Line { seed, backward, points, time, tets, values, reason: reason(p.state[2])? });
                }
            }
        }
        Ok(Some((lines, stats)))
    }

    /// GPU time of tracing `seeds` to their ends (every launch in one submission, the line
    /// points written but not read back), with `hint` or with a fresh search for every lookup:
    /// the median of `repeats` runs after a warm-up of at least a second. `None` where the
    /// locator has no stream shader for these options.
    pub fn bench_trace(
        &mut self,
        seeds: &[Vec3],
        o: &TraceOptions,
        vector: [&str; 3],
        hint: bool,
        repeats: usize,
    ) -> tetloc_core::Result<Option<StreamStats>> {
        o.check()?;
        let jobs = o.jobs(seeds.len());
        let n = jobs.len();
        if n == 0 || n > GROUP {
            return Err(tetloc_core::Error::Invalid(format!("trace benchmark: {n} lines (1 to {GROUP})")));
        }
        let seg = segment_points(n, o.max_steps, 0);
        let Some(s) = Stream::open(self, o, vector, &[], n, seg, hint)? else { return Ok(None) };
        let frame = self.mesh().info.frame;
        let init = particles(seeds, &jobs, frame);
        let dev = self.device();
        let start = dev.create_buffer(
            BufferDesc::io(MemKind::Query, (n * std::mem::size_of::<StreamParticle>()) as u64),
            "stream start",
            Some(bytemuck::cast_slice(&init)),
        )?;
        // Each launch ends every particle or fills its segment: this many end them all.
        let launches = (o.max_steps.saturating_add(3)).div_ceil(seg);
        let bytes = start.size;
        let run = |r: &Recording| {
            let copy = vk::BufferCopy { src_offset: 0, dst_offset: 0, size: bytes };
            // SAFETY: both buffers are live, large enough, and made with the transfer usages.
            unsafe { r.dev.cmd_copy_buffer(r.cmd, start.buffer, s.particles.buffer, &[copy]) };
            s.record_params(r, n);
            for _ in 0..launches {
                s.record_launch(r, n);
            }
        };
        let warm = Instant::now();
        while warm.elapsed().as_secs_f64() < 1.0 {
            dev.time_runs(1, run)?;
        }
        let mut times = dev.time_runs(repeats.max(1), run)?;
        times.sort_by(f64::total_cmp);
        let mut state = init;
        dev.download(&s.particles, 0, bytemuck::cast_slice_mut(&mut state))?;
        let mut stats = StreamStats { seconds: times[times.len() / 2], lines: n, launches, ..Default::default() };
        stats.add(&state);
        if let Some(p) = state.iter().find(|p| p.state[2] == STREAM_LIVE || p.state[2] == STREAM_SEED) {
            return Err(VkError::Mesh(format!(
                "trace benchmark: a particle is still running after {launches} launches: {p:?}"
            ))
            .into());
        }
        Ok(Some(stats))
    }
}

/// A 16-byte line point as the shader writes it (position, time).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, bytemuck::Pod, bytemuck::Zeroable)]
struct Vec4([f32; 4]);

fn reason(code: i32) -> VkResult<Reason> {
    Ok(match code {
        REASON_OUT_OF_DOMAIN => Reason::OutOfDomain,
        REASON_OUT_OF_LENGTH => Reason::OutOfLength,
        REASON_OUT_OF_STEPS => Reason::OutOfSteps,
        REASON_STAGNATION => Reason::Stagnation,
        REASON_OUT_OF_TIME => Reason::OutOfTime,
        _ => return Err(VkError::Mesh(format!("stream tracing: a particle ended with status {code}"))),
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::context::{test_context, Context};
    use crate::{Kernel, LocatorOptions};
    use std::sync::Arc;
    use tetloc_core::gen::{self, Shape};
    use tetloc_core::locate::LineTracer;
    use tetloc_core::mesh::{Mesh, RawMesh};
    use tetloc_core::ops::trace::{self, Direction};
    use tetloc_core::CpuLocator;

    /// A torus with the tokamak flow of `gen --vector`, and seeds: tet centres, one outside,
    /// one NaN.
    fn fusion() -> (Arc<Mesh>, Vec<Vec3>) {
        let raw = gen::generate(Shape::Fusion, 20_000, 5);
        let mut fields = gen::flow::vector_fields(Shape::Fusion, &raw.points);
        // A sink at a tet's centre, where lines stagnate.
        let t = raw.tets[raw.tets.len() / 2].map(|v| raw.points[v as usize]);
        let sink: Vec3 = std::array::from_fn(|k| (t[0][k] + t[1][k] + t[2][k] + t[3][k]) / 4.0);
        for c in 0..3 {
            let values = raw.points.iter().map(|p| sink[c] - p[c]).collect();
            fields.push(tetloc_core::Field {
                values64: None,
                name: format!("s[{c}]"),
                location: tetloc_core::FieldLocation::Vertex,
                values,
            });
        }
        let m = Arc::new(Mesh::new(RawMesh { fields, ..raw }, "fusion+v").unwrap());
        let mut seeds: Vec<Vec3> = (0..m.n_tets()).step_by(m.n_tets() / 40).map(|t| m.tet_center(t)).collect();
        seeds.push([1e3, 0.0, 0.0]);
        seeds.push([f32::NAN, 0.0, 0.0]);
        (m, seeds)
    }

    /// The device for test `test` (`None`: skipped, as [`test_context`] says), the fusion mesh
    /// and its seeds.
    fn setup(test: &str) -> Option<(Arc<Context>, Arc<Mesh>, Vec<Vec3>)> {
        let ctx = test_context(test)?;
        let (m, seeds) = fusion();
        Some((ctx, m, seeds))
    }

    /// A soft-bvh locator of `m`.
    fn soft_bvh(ctx: &Arc<Context>, m: &Arc<Mesh>, opts: LocatorOptions) -> VulkanLocator {
        VulkanLocator::new(ctx.clone(), m.clone(), Kernel::SoftBvh, opts).unwrap()
    }

    const V: [&str; 3] = ["v[0]", "v[1]", "v[2]"];
    const SINK: [&str; 3] = ["s[0]", "s[1]", "s[2]"];

    /// Options (and the field they trace) that end lines for every reason.
    fn options(m: &Mesh) -> Vec<(TraceOptions, [&'static str; 3])> {
        let (edge, step) = (m.info.mean_edge_length as f64, 0.2 * m.info.mean_edge_length as f64);
        let o = TraceOptions { step, max_steps: 150, direction: Direction::Both, ..Default::default() };
        vec![
            (o.clone(), V),
            (TraceOptions { max_length: 37.5 * step, ..o.clone() }, V),
            (TraceOptions { max_time: 0.01, max_steps: 1000, ..o.clone() }, V),
            (TraceOptions { terminal_speed: 2.0 * edge, ..o.clone() }, SINK),
        ]
    }

    /// The f64 kernel integrates as the CPU does, in the same order of operations, on the
    /// same f32 lookups: the same lines, reasons and point counts, the points equal up to
    /// the f32 rounding of the written points; every limit reached; the hint answers most
    /// lookups.
    #[test]
    fn gpu_lines_are_the_cpu_lines() {
        let Some((ctx, m, seeds)) = setup("gpu_lines_are_the_cpu_lines") else { return };
        let cpu = CpuLocator::new(m.clone());
        let mut gpu = soft_bvh(&ctx, &m, LocatorOptions::default());
        let extent = (0..3).map(|k| m.info.bounds_max[k] - m.info.bounds_min[k]).fold(0f32, f32::max) as f64;
        let mut reasons = std::collections::BTreeSet::new();
        let fields = trace::line_fields(&m, &tetloc_core::ops::fields::resolve(&m, "v").unwrap());
        let components: Vec<&str> = fields.iter().flat_map(|g| g.component_refs()).collect();
        for (o, vector) in options(&m) {
            let want = trace::trace(&seeds, &o, &cpu.vector_field(vector).unwrap(), &|_| Ok(())).unwrap();
            let mut calls = 0;
            let (got, stats) = gpu
                .trace_rk4(&seeds, &o, vector, &components, &mut |_| {
                    calls += 1;
                    Ok(())
                })
                .unwrap()
                .expect("soft-bvh traces RK4 lines itself");
            assert_eq!(got.len(), want.len(), "{o:?}");
            assert!(calls >= 1 && stats.launches >= 1);
            for (a, b) in got.iter().zip(&want) {
                let what = (a.seed, a.backward, a.reason, a.points.len());
                assert_eq!(what, (b.seed, b.backward, b.reason, b.points.len()), "{o:?}");
                for ((p, q), (s, t)) in a.points.iter().zip(&b.points).zip(a.time.iter().zip(&b.time)) {
                    let d = (0..3).map(|k| (p[k] - q[k]).abs()).fold(0.0, f64::max);
                    assert!(d <= 1e-6 * extent, "{what:?}: {p:?} vs {q:?}");
                    assert!((s - t).abs() <= 1e-6 * t.abs().max(1e-3), "{what:?}: time {s} vs {t}");
                }
                reasons.insert(a.reason as i32);
            }
            // Every line's first lookup is a fresh one; after that the hint answers most.
            assert!(
                stats.lookups > 0 && 4 * stats.fallbacks.saturating_sub(2 * seeds.len() as u64) < stats.lookups,
                "{stats:?}"
            );
            // Each point carries the tet the locator gives it and the line fields the GPU's
            // sampler gives there (a second search on the GPU samples the same, bit for bit);
            // sampled on the host at those tets, in f64, they agree to f32 rounding.
            let traced = trace::LineArrays::from_tracer(&got, &fields).expect("GPU lines carry their fields");
            let at = trace::LineArrays::at_tets(&got, &m, &fields).unwrap().expect("GPU lines carry their tets");
            let again = trace::LineArrays::new(&got, &mut gpu, &fields).unwrap();
            assert_eq!(at.fields.ids, again.fields.ids, "{o:?}");
            assert_eq!(traced.fields.ids, again.fields.ids, "{o:?}");
            for (((_, a), (_, b)), (_, c)) in
                at.fields.arrays.iter().zip(&again.fields.arrays).zip(&traced.fields.arrays)
            {
                assert!(a.iter().zip(b).all(|(x, y)| (x - y).abs() <= 1e-5 * y.abs().max(1.0)), "{o:?}");
                assert!(c.iter().zip(b).all(|(x, y)| x.to_bits() == y.to_bits()), "{o:?}");
            }
        }
        for r in [Reason::OutOfDomain, Reason::OutOfLength, Reason::OutOfTime, Reason::OutOfSteps, Reason::Stagnation] {
            assert!(reasons.contains(&(r as i32)), "no line ended {r:?}: {reasons:?}");
        }
        assert_eq!(ctx.validation_errors(), 0);
    }

    /// Short launches (two or five points a particle each) and fresh searches for every
    /// lookup (no hint) give the same lines, bit for bit; the hint-less run falls back on
    /// every lookup. The benchmark runs both ways to the end.
    #[test]
    fn segments_and_hints_change_nothing() {
        let Some((ctx, m, seeds)) = setup("segments_and_hints_change_nothing") else { return };
        let mut gpu = soft_bvh(&ctx, &m, LocatorOptions::default());
        let (o, _) = options(&m).remove(0);
        // The line fields sampled as the kernel goes (here the vector's own components).
        let mut run =
            |seg, hint| gpu.trace_in_segments(&seeds, &o, V, &V, seg, hint, &mut |_| Ok(())).unwrap().unwrap();
        let (whole, one) = run(o.max_steps + 3, true);
        assert_eq!(one.launches, 1);
        assert!(whole.iter().all(|l| l.values.len() == 3 * l.points.len()));
        for (seg, hint) in [(2, true), (5, true), (o.max_steps + 3, false)] {
            let (lines, stats) = run(seg, hint);
            assert_eq!(lines, whole, "{seg} points a launch, hint {hint}");
            assert_eq!(stats.lookups, one.lookups);
            if hint {
                assert!(stats.launches > (o.max_steps + 1) / seg, "{stats:?}");
            } else {
                assert_eq!(stats.fallbacks, stats.lookups);
            }
        }
        for hint in [true, false] {
            let b = gpu.bench_trace(&seeds, &o, V, hint, 1).unwrap().unwrap();
            assert_eq!((b.lookups, b.lines), (one.lookups, one.lines), "hint {hint}");
            assert!(b.seconds > 0.0);
        }
        // Packed ids (compact; small binds its own neighbour table) change nothing either.
        for preset in ["compact", "small"] {
            let opts = LocatorOptions::preset(preset).expect("a preset");
            let mut packed = soft_bvh(&ctx, &m, opts);
            let traced = packed.trace_in_segments(&seeds, &o, V, &V, o.max_steps + 3, true, &mut |_| Ok(()));
            assert_eq!(traced.unwrap().unwrap().0, whole, "{preset}");
        }
        assert_eq!(ctx.validation_errors(), 0);
    }

    /// A segment's buffers stay within SEGMENT_BYTES with every line field a point, and a
    /// small group writes its whole lines in one launch.
    #[test]
    fn segments_fit_their_bytes() {
        for fields in [0, 5, MAX_FIELDS as usize] {
            for group in [1, 1000, 33_487, GROUP] {
                let seg = segment_points(group, 1000, fields);
                assert!((2..=1003).contains(&seg), "{group} {fields}: {seg}");
                assert!(seg == 2 || group * seg * (20 + 4 * fields) <= SEGMENT_BYTES, "{group} {fields}: {seg}");
            }
            assert_eq!(segment_points(1000, 1000, fields), 1003);
        }
    }

    /// The adaptive integrators, and kernels without a stream shader, leave tracing to the
    /// batch driver (`trace_with`), which gives the same lines as the CPU.
    #[test]
    fn others_decline() {
        let Some((ctx, m, seeds)) = setup("others_decline") else { return };
        let (mut o, _) = options(&m).remove(0);
        o.integrator = Integrator::Rk45;
        let mut gpu = soft_bvh(&ctx, &m, LocatorOptions::default());
        assert!(gpu.trace_lines(&seeds, &o, V, &[], &mut |_| Ok(())).unwrap().is_none());
        if ctx.info().ray_tracing {
            let mut rt = VulkanLocator::new(ctx.clone(), m.clone(), Kernel::RtBvh, LocatorOptions::default()).unwrap();
            o.integrator = Integrator::Rk4;
            assert!(rt.trace_lines(&seeds, &o, V, &[], &mut |_| Ok(())).unwrap().is_none());
        }
    }
}
