//! The GPU build of soft-bvh's structure (issue 12.1): the same structure that
//! `tetloc_core`'s CPU builder makes (`Bvh::build`, `WideBvh::collapse`, `EntryGrid::new`,
//! `Mesh::neighbors`), bit for bit, in compute shaders (`shaders/build/`), from the mesh
//! already on the device. One module a stage:
//!
//! - [`sort`]: Morton codes of the prims' box centres (tets, or a mixed mesh's cells: one box
//!   a cell), radix-sorted with their ids;
//! - [`hierarchy`]: the binary tree top down (a level a dispatch), boxes and 4-wide counts
//!   bottom up, the 4-wide quantized nodes top down in the CPU's depth-first numbering;
//! - [`grid`]: the entry grid's nodes and walk starts;
//! - [`neighbors`]: the tets' face neighbours (faces bucketed by their smallest vertex);
//! - [`scan`]: the prefix sums the sort and the neighbours use;
//! - [`pack`]: the neighbours and leaf prims packed to fewer bits (`compact`, `small`).
//!
//! Why the same bits: the same tree is the same search, node for node, so the tests can
//! compare the two exactly (the answers, ties included, do not depend on the order since the
//! tie rule takes the lowest id, but the costs and the structure's bytes do).

mod grid;
mod hierarchy;
mod neighbors;
mod pack;
mod scan;
mod sort;
#[cfg(test)]
mod tests;

pub(crate) use grid::prims_per_cell;

use crate::device::{Device, Recording, Split};
use crate::error::{VkError, VkResult};
use crate::interface::*;
use crate::kernels::Inputs;
use crate::memory::{Buffer, BufferDesc, MemKind};
use crate::pipeline::{Binding, Descriptors, Pipeline, Program, Spec};
use crate::shaders::{self, Shader};
use ash::vk;
use std::collections::HashMap;
use std::fmt;
use std::str::FromStr;
use std::time::Instant;

/// Where soft-bvh builds its structure.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum BuildOn {
    /// In compute shaders, from the mesh on the device (the default), its arrays split over
    /// up to MAX_CHUNKS buffers each. Meshes beyond that (or past ~1.07B tets) are built on
    /// the CPU (said in the build stages).
    #[default]
    Gpu,
    /// On the host with tetloc_core's builder (the reference), then uploaded.
    Cpu,
}

impl fmt::Display for BuildOn {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            BuildOn::Gpu => "gpu",
            BuildOn::Cpu => "cpu",
        })
    }
}

impl FromStr for BuildOn {
    type Err = String;
    fn from_str(s: &str) -> Result<BuildOn, String> {
        match s {
            "gpu" => Ok(BuildOn::Gpu),
            "cpu" => Ok(BuildOn::Cpu),
            _ => Err(format!("unknown build '{s}' (known: gpu, cpu)")),
        }
    }
}

/// soft-bvh's structure on the device, however it was built.
pub(crate) struct Structure {
    /// The 4-wide nodes (`QNode4`).
    pub nodes: Split,
    /// Leaf prims, unless every leaf holds one tet (`direct`).
    pub prims: Option<Buffer>,
    pub direct: bool,
    /// Levels of 4-wide nodes (the traversal stack is 3 depth + 1).
    pub depth: usize,
    /// The entry grid's words (`EntryGrid::words`) and the neighbours, when asked for.
    pub grid: Option<Buffer>,
    pub neighbors: Option<Split>,
    /// Bits a field of the packed neighbours and prims (`crate::packed`; 0: not packed).
    pub neighbor_bits: u32,
    pub prim_bits: u32,
    /// Wall seconds of each stage, in order.
    pub stages: Vec<(String, f64)>,
}

/// What the GPU build makes, from the options.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Wanted {
    pub max_leaf: u32,
    /// The entry grid (about `prims_per_cell` prims a cell) and, with walk starts, the neighbours.
    pub grid: bool,
    pub walk: bool,
    pub prims_per_cell: usize,
    /// Pack the neighbours and leaf prims (`crate::packed`) where each fits one buffer, in at
    /// least `pack_min_bits` bits (`LocatorOptions::pack_min_bits`).
    pub pack: bool,
    pub pack_min_bits: u32,
}

/// Bits a field of the packed neighbours (tet + 1) of `n_tets` tets and leaf prims of
/// `n_prims` prims, when `want` packs them, the structure has them (neighbours with walk
/// starts, prims unless `direct`) and each packed array fits a buffer of `max_buffer` bytes
/// (0: not packed).
pub(crate) fn packed_bits(want: &Wanted, n_tets: u64, n_prims: u64, direct: bool, max_buffer: u64) -> (u32, u32) {
    let width = |on: bool, max: u64, fields: u64| match on && want.pack {
        true => crate::packed::width(max, fields, want.pack_min_bits, max_buffer),
        false => 0,
    };
    (width(want.walk, n_tets, 4 * n_tets), width(!direct, n_prims.saturating_sub(1), n_prims))
}

/// Bytes of each buffer of a split build array: the device's largest buffer (or a test's
/// smaller one), rounded down to a multiple of 192 so that every element size divides it.
fn chunk_bytes(dev: &Device) -> u64 {
    (dev.max_buffer() / 192 * 192).clamp(192, 0xFFFF_FF40)
}

/// Builds soft-bvh's structure on the GPU, or `None` when the mesh is beyond what it
/// addresses (an array over MAX_CHUNKS buffers, a single buffer over the device's limit, or
/// 4 faces a tet past 32-bit indices); the caller builds on the CPU then.
pub(crate) fn build(dev: &mut Device, input: &Inputs, want: Wanted) -> VkResult<Option<Structure>> {
    // The tree's prims (tets, or a mixed mesh's cells), and the tets (the neighbours').
    let (n, n_tets) = (crate::kernels::n_prims(input.mesh) as u64, input.mesh.n_tets() as u64);
    let n_points = input.mesh.points.len() as u64;
    let chunk = chunk_bytes(dev);
    // Split arrays: elements and element bytes (the 4-wide nodes: at most one a prim).
    let split = [(2 * n, 8), (2 * n, 4), (2 * n, 24), (2 * n, 16), (n, 64), (n, 8), (4 * n_tets, 12), (n_tets, 16)];
    let too_many = split.iter().any(|&(elems, bytes)| elems.div_ceil(chunk / bytes) > MAX_CHUNKS as u64);
    // Arrays in one buffer: the scan (sized by vertices), the leaf prims.
    let single = [4 * scan::words(n_points.max(n.div_ceil(SCAN_CHUNK as u64))), 4 * n];
    let too_big = single.iter().any(|&b| b > dev.device_max_buffer());
    if too_many || too_big || 4 * n_tets + BUILD_GROUP as u64 * 65535 > u32::MAX as u64 {
        return Ok(None);
    }
    let mut stages = vec![];
    let mut timed = |name: String, t: Instant| stages.push((name, t.elapsed().as_secs_f64()));
    let t = Instant::now();
    let mut b = Builder::new(dev, input, chunk)?;
    let sorted = sort::run(&mut b, dev, input)?;
    timed("gpu: Morton codes, radix sort (pipelines included)".into(), t);
    let t = Instant::now();
    let tree = hierarchy::run(&mut b, dev, sorted, want.max_leaf)?;
    let [split, refit, collapse] = tree.seconds;
    timed(
        format!(
            "gpu: binary tree ({} levels; split {split:.3} s, refit {refit:.3} s), 4-wide nodes ({} levels; {collapse:.3} s)",
            tree.binary_levels, tree.depth
        ),
        t,
    );
    let t = Instant::now();
    let grid = want.grid.then(|| grid::run(&mut b, dev, input, &tree, want)).transpose()?;
    if want.grid {
        timed("gpu: entry grid".into(), t);
    }
    let t = Instant::now();
    let mut neighbors = want.walk.then(|| neighbors::run(&mut b, dev, input, &tree.scan)).transpose()?;
    if want.walk {
        timed("gpu: neighbours".into(), t);
    }
    let t = Instant::now();
    let (neighbor_bits, prim_bits) = packed_bits(&want, n_tets, n, tree.direct, dev.device_max_buffer());
    let mut prims = tree.prims;
    if let (Some(nb), true) = (&neighbors, neighbor_bits > 0) {
        let packed = pack::run(&mut b, dev, pack::Source::Neighbors(nb), neighbor_bits, "tet neighbours (packed)")?;
        neighbors = Some(Split::whole(packed));
    }
    if let (Some(p), true) = (&prims, prim_bits > 0) {
        prims = Some(pack::run(&mut b, dev, pack::Source::Prims(p), prim_bits, "bvh prims (packed)")?);
    }
    if neighbor_bits + prim_bits > 0 {
        timed(format!("gpu: packed ids (neighbours {neighbor_bits} bits, prims {prim_bits} bits)"), t);
    }
    Ok(Some(Structure {
        nodes: tree.nodes,
        prims,
        direct: tree.direct,
        depth: tree.depth,
        grid,
        neighbors,
        neighbor_bits,
        prim_bits,
        stages,
    }))
}

/// A build program: its name (the pipelines' key) and shader.
#[derive(Clone, Copy)]
pub(crate) struct Prog(&'static str, Shader);

const SORT: Prog = Prog("sort", shaders::BUILD_SORT);
const SCAN: Prog = Prog("scan", shaders::BUILD_SCAN);
const HIERARCHY: Prog = Prog("hierarchy", shaders::BUILD_HIERARCHY);
const GRID: Prog = Prog("grid", shaders::BUILD_GRID);
const GRID_STARTS: Prog = Prog("grid starts", shaders::BUILD_GRID_STARTS);
const NEIGHBORS: Prog = Prog("neighbours", shaders::BUILD_NEIGHBORS);
const PACK: Prog = Prog("pack", shaders::BUILD_PACK);

/// How many workgroups a pass runs.
pub(crate) enum Groups<'a> {
    /// One invocation per item.
    Items(u64),
    /// This many workgroups.
    Workgroups(u64),
    /// As many as the words at this byte offset of the buffer say.
    Indirect(&'a Buffer, u64),
}

/// The build's descriptor set (every build binding, the mesh's, and the locate bindings the
/// shared GLSL declares) and its pipelines, made on first use.
pub(crate) struct Builder {
    // Field order is drop order: the pipelines before their layout.
    pipelines: HashMap<(&'static str, u32), Pipeline>,
    desc: Descriptors,
    spec: Spec,
    f64: bool,
    /// The tree's prims (`kernels::n_prims`: tets, or a mixed mesh's cells), and the tets.
    n: u32,
    n_tets: u32,
    /// Bytes of each buffer of a split array.
    chunk: u64,
}

impl Builder {
    fn new(dev: &mut Device, input: &Inputs, chunk: u64) -> VkResult<Builder> {
        let unbound = dev.unbound();
        let mut bindings = input.mesh_bindings.to_vec();
        bindings.extend(
            [
                B_QUERIES,
                B_OUT,
                B_DEFER,
                B_ORDER_POINTS,
                B_ORDER_PERM,
                B_PRIMS,
                B_GRID,
                B_BUILD_SCAN,
                B_BUILD_LEVELS,
                B_BUILD_GRID,
                B_BUILD_CELLS,
                B_PACKED,
            ]
            .map(|slot| Binding::buffer(slot, unbound)),
        );
        bindings.push(Binding::array(B_FIELD, &[], MAX_FIELDS, unbound));
        bindings.extend(SPLIT_SLOTS.map(|slot| Binding::parts(slot, None, unbound)));
        bindings.extend(Binding::split(B_ACCEL, B_ACCEL_HI, None, unbound));
        bindings.extend(Binding::split(B_NEIGHBORS, B_NEIGHBORS_HI, None, unbound));
        let desc = Descriptors::new(dev.ctx(), &bindings, vk::ShaderStageFlags::COMPUTE)?;
        let spec = Spec::default()
            .set(sc::POINTS_CHUNK, input.points.per_chunk)
            .set(sc::TETS_CHUNK, input.tets.per_chunk)
            .set(sc::TET_BITS, input.tet_bits)
            .set(sc::ORIENT_ERR_BOUND_F32, tetloc_core::geom::ORIENT_ERR_BOUND_F32.to_bits())
            .set(sc::BARY_F32_TRUST, tetloc_core::geom::BARY_F32_TRUST.to_bits())
            .set(sc::BUILD_CHUNK_BYTES, chunk as u32)
            .set(sc::CELL_BOXES, input.cell_boxes as u32);
        let (n, n_tets) = (crate::kernels::n_prims(input.mesh) as u32, input.mesh.n_tets() as u32);
        Ok(Builder { pipelines: HashMap::new(), desc, spec, f64: input.f64, n, n_tets, chunk })
    }

    /// Points `slot` at `buf` (or at nothing, before `buf` is freed).
    fn bind(&self, slot: u32, buf: &Buffer) {
        self.desc.write(&[Binding::buffer(slot, buf)]);
    }

    /// Points the split array binding `slot` at `array`'s buffers (`None`: at nothing).
    fn bind_split(&self, slot: u32, array: Option<&Split>, unbound: &Buffer) {
        self.desc.write(&[Binding::parts(slot, array, unbound)]);
    }

    /// A split array of `elems` elements of `elem` bytes, in buffers of `self.chunk` bytes
    /// (the last one shorter); `per_chunk` is 0 when it fits one buffer, as the locate
    /// shaders read it.
    fn split(&self, dev: &mut Device, kind: MemKind, name: &str, elems: u64, elem: u64) -> VkResult<Split> {
        let per = self.chunk / elem;
        let n_parts = elems.div_ceil(per).max(1);
        let parts = (0..n_parts)
            .map(|k| {
                let bytes = elem * (elems - k * per).min(per).max(1);
                let label = if n_parts == 1 { name.to_string() } else { format!("{name} {}/{n_parts}", k + 1) };
                dev.create_buffer(BufferDesc::io(kind, bytes), label, None)
            })
            .collect::<VkResult<Vec<_>>>()?;
        Ok(Split { parts, per_chunk: if n_parts == 1 { 0 } else { per as u32 } })
    }

    /// Makes the pipelines of `prog`'s `passes`, with `extra` constants on top of the build's.
    fn prepare(&mut self, dev: &mut Device, prog: Prog, passes: &[u32], extra: &Spec) -> VkResult<()> {
        for &pass in passes {
            if !self.pipelines.contains_key(&(prog.0, pass)) {
                let spec = self.spec.clone().concat(extra).set(sc::BUILD_PASS, pass);
                let p = Program::Compute(prog.1).pipeline(dev, self.desc.layout, self.f64, &spec)?;
                self.pipelines.insert((prog.0, pass), p);
            }
        }
        Ok(())
    }

    /// Records pass `pass` of `prog` (prepared) with push constants `counts` (and `lo`, `hi`).
    fn record(&self, r: &Recording, prog: Prog, pass: u32, counts: [u32; 4], lo_hi: [[f32; 4]; 2], groups: Groups) {
        let p = &self.pipelines[&(prog.0, pass)];
        let params = Params { counts, lo_tmin: lo_hi[0], hi_tmax: lo_hi[1], ..Default::default() };
        let (dev, cmd) = (r.dev, r.cmd);
        // SAFETY: recording into a command buffer in the recording state, with a live pipeline
        // and descriptor set of the same layout.
        unsafe {
            dev.cmd_bind_pipeline(cmd, p.bind_point, p.pipeline);
            dev.cmd_bind_descriptor_sets(cmd, p.bind_point, self.desc.layout, 0, &[self.desc.set], &[]);
            dev.cmd_push_constants(cmd, self.desc.layout, self.desc.stages, 0, bytemuck::bytes_of(&params));
        }
        let groups = match groups {
            Groups::Items(n) => n.div_ceil(BUILD_GROUP as u64),
            Groups::Workgroups(g) => g,
            Groups::Indirect(buf, offset) => {
                // SAFETY: as above; the buffer holds a dispatch size at `offset` (written by an
                // earlier pass, behind a barrier).
                unsafe { dev.cmd_dispatch_indirect(cmd, buf.buffer, offset) };
                return;
            }
        };
        let x = groups.min(r.ctx.limits.max_workgroup_count[0] as u64).max(1);
        // SAFETY: as above.
        unsafe { dev.cmd_dispatch(cmd, x as u32, groups.div_ceil(x) as u32, 1) };
    }
}

/// The bindings of the split build arrays (shaders/build/build.glsl `TL_SPLIT_ARRAY`).
const SPLIT_SLOTS: [u32; 10] = [
    B_BUILD_KEYS,
    B_BUILD_IDS,
    B_BUILD_NODES,
    B_BUILD_BOXES,
    B_BUILD_WIDE,
    B_BUILD_WORK,
    B_BUILD_TREE,
    B_BUILD_HOME,
    B_BUILD_FACES,
    B_BUILD_NEIGHBORS,
];

/// Copies `count` elements of `elem` bytes of the split array `src` (buffers of `chunk`
/// bytes) from element `first` into `dst` at byte 0, buffer by buffer.
fn copy_out(r: &Recording, src: &Split, chunk: u64, elem: u64, first: u64, count: u64, dst: &Buffer) {
    let per = chunk / elem;
    let (mut at, end) = (first, first + count);
    while at < end {
        let (part, offset) = ((at / per) as usize, at % per);
        let take = (per - offset).min(end - at);
        let region = vk::BufferCopy { src_offset: offset * elem, dst_offset: (at - first) * elem, size: take * elem };
        // SAFETY: recording; both buffers are live and hold the regions (the split's buffers
        // hold `per` elements each, the last its remainder).
        unsafe { r.dev.cmd_copy_buffer(r.cmd, src.parts[part].buffer, dst.buffer, &[region]) };
        at += take;
    }
}

/// A scratch buffer of the build (device-local, transfers in and out).
fn scratch(dev: &mut Device, name: &str, bytes: u64) -> VkResult<Buffer> {
    dev.create_buffer(BufferDesc::io(MemKind::Scratch, bytes), name, None)
}

/// A buffer of the finished structure.
fn structure(dev: &mut Device, name: &str, bytes: u64) -> VkResult<Buffer> {
    dev.create_buffer(BufferDesc::io(MemKind::Structure, bytes), name, None)
}

/// Fills `bytes` of `buf` from `offset` with the word `value`.
fn fill(r: &Recording, buf: &Buffer, offset: u64, bytes: u64, value: u32) {
    // SAFETY: recording; the buffer is live, a transfer destination, and holds the range.
    unsafe { r.dev.cmd_fill_buffer(r.cmd, buf.buffer, offset, bytes, value) };
}

/// Reads `n` words of `buf` from word `at`.
fn read_words(dev: &mut Device, buf: &Buffer, at: u64, n: usize) -> VkResult<Vec<u32>> {
    let mut w = vec![0u32; n];
    dev.download(buf, 4 * at, bytemuck::cast_slice_mut(&mut w))?;
    Ok(w)
}

fn fail(msg: String) -> VkError {
    VkError::Mesh(format!("soft-bvh GPU build: {msg}"))
}
