//! The binary tree over the sorted keys and its collapse into 4-wide quantized nodes
//! (`shaders/build/hierarchy.comp`), level by level: each level's dispatch size is written by
//! a one-invocation pass after the level before it (indirect dispatches), and the host reads
//! the level table back every `BATCH` levels to see where the tree ends.

use super::sort::Sorted;
use super::{fail, read_words, scratch, structure, Builder, Groups, HIERARCHY};
use crate::device::Device;
use crate::error::VkResult;
use crate::interface::*;
use crate::memory::Buffer;
use crate::pipeline::Spec;

/// Levels recorded per submission before the host looks whether the tree has ended.
const BATCH: u32 = 8;

/// The tree: 4-wide nodes, leaf prims (unless direct), and what the entry grid needs (each
/// 4-wide node's parent and level, each tet's home node), with the scratch the grid and the
/// neighbours reuse.
pub(super) struct Tree {
    pub nodes: Buffer,
    pub prims: Option<Buffer>,
    pub direct: bool,
    pub depth: usize,
    pub binary_levels: u32,
    pub tree: Buffer,
    pub home: Buffer,
    /// Only held: the descriptor set names it until the build ends.
    pub _levels: Buffer,
    pub scan: Buffer,
}

/// The tree, or `None` when its 4-wide nodes would not fit one buffer.
pub(super) fn run(b: &mut Builder, dev: &mut Device, s: Sorted, max_leaf: u32) -> VkResult<Option<Tree>> {
    let (n, nn) = (b.n as u64, b.n);
    let direct = max_leaf == 1 || nn == 1;
    let spec = Spec::default().set(sc::BUILD_MAX_LEAF, max_leaf).set(sc::DIRECT_LEAVES, direct as u32);
    let passes = [BUILD_SPLIT, BUILD_NEXT_LEVEL, BUILD_REFIT, BUILD_COLLAPSE, BUILD_NEXT_WIDE_LEVEL];
    b.prepare(dev, HIERARCHY, &passes, &spec)?;
    let max_nodes = 2 * n - 1;
    let bnodes = scratch(dev, "build binary nodes", 16 * max_nodes)?;
    let boxes = scratch(dev, "build binary boxes", 24 * max_nodes)?;
    dev.write(&bnodes, 0, bytemuck::cast_slice(&[0, nn, 0, 0]))?;
    b.bind(B_BUILD_NODES, &bnodes);
    b.bind(B_BUILD_BOXES, &boxes);

    // Top down: split ranges until the leaves. The keys are not read after that.
    let binary_levels = levels(b, dev, &s.levels, false, [BUILD_SPLIT, BUILD_NEXT_LEVEL], [nn, 0, s.half, 0])?;
    b.bind(B_BUILD_KEYS, dev.unbound());
    drop(s.keys);
    // Bottom up: boxes and 4-wide counts.
    dev.run(|r| {
        for k in (0..binary_levels).rev() {
            let at = Groups::Indirect(&s.levels, level_offset(false, k));
            b.record(r, HIERARCHY, BUILD_REFIT, [nn, k, s.half, 0], [[0.0; 4]; 2], at);
            r.barrier();
        }
    })?;
    let root = read_words(dev, &bnodes, 0, 4)?;
    let n_wide = if root[2] == BUILD_LEAF { 1 } else { root[3] as u64 };
    if 64 * n_wide > dev.max_buffer() {
        return Ok(None); // the nodes would not fit one buffer (the caller builds on the CPU)
    }

    // Top down: the 4-wide nodes.
    let nodes = structure(dev, "bvh nodes", 64 * n_wide)?;
    let work = scratch(dev, "build worklist", 8 * n_wide)?;
    let tree = scratch(dev, "build node levels", 8 * n_wide)?;
    let home = scratch(dev, "build homes", 4 * n)?;
    dev.write(&tree, 0, bytemuck::cast_slice(&[0u32, 1]))?; // the root: its own parent, level 1
    dev.write(&work, 0, bytemuck::cast_slice(&[0u32, 0]))?; // 4-wide node 0 from binary node 0
    for (slot, buf) in [(B_BUILD_WIDE, &nodes), (B_BUILD_WORK, &work), (B_BUILD_TREE, &tree), (B_BUILD_HOME, &home)] {
        b.bind(slot, buf);
    }
    let depth = levels(b, dev, &s.levels, true, [BUILD_COLLAPSE, BUILD_NEXT_WIDE_LEVEL], [nn, 0, s.half, 0])?;
    let err = read_words(dev, &s.levels, BUILD_AT_ERROR as u64, 1)?[0];
    if err & BUILD_ERR_EXTENT != 0 {
        return Err(fail("a node box is too large for f32 node scales".into()));
    }
    if err & BUILD_ERR_LEAF != 0 {
        return Err(fail(format!("{n} tets: leaf references hold ids below 2^29")));
    }
    let prims = if direct {
        None
    } else {
        let p = structure(dev, "bvh prims", 4 * n)?;
        let region = ash::vk::BufferCopy { src_offset: 4 * n * s.half as u64, dst_offset: 0, size: 4 * n };
        // SAFETY: live buffers holding the region; the copy completes before run returns.
        dev.run(|r| unsafe { r.dev.cmd_copy_buffer(r.cmd, s.ids.buffer, p.buffer, &[region]) })?;
        Some(p)
    };
    // Free the scratch no later stage reads (unbound first: the set stays in use).
    let unbound = dev.unbound();
    for slot in [B_BUILD_IDS, B_BUILD_NODES, B_BUILD_BOXES, B_BUILD_WORK, B_BUILD_WIDE] {
        b.bind(slot, unbound);
    }
    drop((s.ids, bnodes, boxes, work));
    Ok(Some(Tree {
        nodes,
        prims,
        direct,
        depth: depth as usize,
        binary_levels,
        tree,
        home,
        _levels: s.levels,
        scan: s.scan,
    }))
}

/// Byte offset of level `k`'s dispatch size in the level table.
fn level_offset(wide: bool, k: u32) -> u64 {
    4 * (BUILD_LEVELS_AT + 8 * if wide { BUILD_MAX_LEVELS + k } else { k }) as u64
}

/// Runs `passes` (a level's pass, then the next-level pass) level by level from level 0 until
/// a level is empty; returns the number of non-empty levels.
fn levels(
    b: &Builder,
    dev: &mut Device,
    table: &Buffer,
    wide: bool,
    passes: [u32; 2],
    counts: [u32; 4],
) -> VkResult<u32> {
    let mut first = 0;
    loop {
        let last = (first + BATCH).min(BUILD_MAX_LEVELS - 1);
        dev.run(|r| {
            for k in first..last {
                let c = [counts[0], k, counts[2], counts[3]];
                b.record(r, HIERARCHY, passes[0], c, [[0.0; 4]; 2], Groups::Indirect(table, level_offset(wide, k)));
                r.barrier();
                b.record(r, HIERARCHY, passes[1], c, [[0.0; 4]; 2], Groups::Workgroups(1));
                r.barrier();
            }
        })?;
        // Each level's first and end entry.
        let words = read_words(dev, table, level_offset(wide, first) / 4, 8 * (last - first + 1) as usize)?;
        for k in first..=last {
            let w = &words[8 * (k - first) as usize..];
            if w[4] == w[5] {
                return Ok(k);
            }
        }
        if last == BUILD_MAX_LEVELS - 1 {
            return Err(super::fail(format!("the tree is deeper than {} levels", BUILD_MAX_LEVELS - 1)));
        }
        first = last;
    }
}
