//! Morton codes of the prims' box centres (tets, or a mixed mesh's cells) and their radix sort (`shaders/build/sort.comp`):
//! the codes of `tetloc_core::bvh::morton` (21 bits an axis over the centres' bounds; the
//! bounds come back to the host, which computes the scale exactly as `Morton::new`), then an
//! LSD radix sort one bit a pass (count the zeros of each chunk, scan, scatter stably), so
//! that equal codes keep prim order: the CPU builder's order.

use super::{read_words, scan, scratch, Builder, Groups, SORT};
use crate::device::{Device, Split};
use crate::error::VkResult;
use crate::interface::*;
use crate::kernels::Inputs;
use crate::memory::{Buffer, BufferDesc, MemKind};
use crate::pipeline::Spec;
use tetloc_core::bvh::morton::Morton;

/// Bits of a Morton code (21 an axis).
const CODE_BITS: u32 = 63;

/// The sorted keys and ids, the buffers the later stages share, and which half holds them.
pub(super) struct Sorted {
    pub keys: Split,
    pub ids: Split,
    pub levels: Buffer,
    pub scan: Buffer,
    pub half: u32,
}

/// The level table as the build starts: counters, the bounds' neutral words, and level 0 of
/// both trees (the root).
fn initial_levels() -> Vec<u32> {
    let mut w = vec![0u32; (BUILD_LEVELS_AT + 16 * BUILD_MAX_LEVELS) as usize];
    w[BUILD_AT_NODES as usize] = 1;
    w[BUILD_AT_WORK as usize] = 1;
    w[BUILD_AT_BOUNDS as usize..][..3].fill(u32::MAX);
    for at in [BUILD_LEVELS_AT, BUILD_LEVELS_AT + 8 * BUILD_MAX_LEVELS] {
        w[at as usize..][..8].copy_from_slice(&[1, 1, 1, 0, 0, 1, 0, 0]);
    }
    w
}

/// A word of `tl_ordered` back to its float.
fn unordered(u: u32) -> f32 {
    f32::from_bits(if u & 0x8000_0000 != 0 { u & 0x7FFF_FFFF } else { !u })
}

pub(super) fn run(b: &mut Builder, dev: &mut Device, input: &Inputs) -> VkResult<Sorted> {
    let n = b.n as u64;
    let points = input.mesh.points.len() as u64;
    let levels_words = initial_levels();
    let keys = b.split(dev, MemKind::Scratch, "build keys", 2 * n, 8)?;
    let ids = b.split(dev, MemKind::Scratch, "build ids", 2 * n, 4)?;
    let mut desc = BufferDesc::io(MemKind::Scratch, 4 * levels_words.len() as u64);
    desc.usage |= ash::vk::BufferUsageFlags::INDIRECT_BUFFER; // the levels' dispatch sizes
    let levels = dev.create_buffer(desc, "build levels", None)?;
    let scan = scratch(dev, "build scan", 4 * scan::words(points.max(n.div_ceil(SCAN_CHUNK as u64))))?;
    dev.write(&levels, 0, bytemuck::cast_slice(&levels_words))?;
    b.bind_split(B_BUILD_KEYS, Some(&keys), dev.unbound());
    b.bind_split(B_BUILD_IDS, Some(&ids), dev.unbound());
    b.bind(B_BUILD_LEVELS, &levels);
    b.bind(B_BUILD_SCAN, &scan);
    b.prepare(dev, SORT, &[BUILD_BOUNDS, BUILD_KEYS, BUILD_SORT_COUNT, BUILD_SORT_SCATTER], &Spec::default())?;
    scan::prepare(b, dev)?;
    let nn = b.n;
    let none = [[0.0; 4]; 2];

    dev.run(|r| b.record(r, SORT, BUILD_BOUNDS, [nn, 0, 0, 0], none, Groups::Items(n)))?;
    let w = read_words(dev, &levels, BUILD_AT_BOUNDS as u64, 6)?;
    let lo: [f32; 3] = std::array::from_fn(|a| unordered(w[a]));
    let hi: [f32; 3] = std::array::from_fn(|a| unordered(w[3 + a]));
    let (lo, scale) = Morton::new(lo, hi, 21).lo_scale();
    let chunks = nn.div_ceil(SCAN_CHUNK);
    dev.run(|r| {
        let lo_hi = [[lo[0], lo[1], lo[2], 0.0], [scale[0], scale[1], scale[2], 0.0]];
        b.record(r, SORT, BUILD_KEYS, [nn, 0, 0, 0], lo_hi, Groups::Items(n));
        r.barrier();
        for bit in 0..CODE_BITS {
            let src = bit % 2;
            b.record(r, SORT, BUILD_SORT_COUNT, [nn, bit, src, 0], none, Groups::Workgroups(chunks as u64));
            r.barrier();
            scan::record(b, r, chunks, 0);
            b.record(r, SORT, BUILD_SORT_SCATTER, [nn, bit, src, 0], none, Groups::Workgroups(chunks as u64));
            r.barrier();
        }
    })?;
    Ok(Sorted { keys, ids, levels, scan, half: CODE_BITS % 2 })
}
