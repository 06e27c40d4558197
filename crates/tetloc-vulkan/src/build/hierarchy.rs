//! The binary tree over the sorted keys and its collapse into 4-wide quantized nodes
//! (`shaders/build/hierarchy.comp`), level by level: each level's dispatch size is written by
//! a one-invocation pass after the level before it (indirect dispatches), and the host reads
//! the level table back every `BATCH` levels to see where the tree ends.

use super::sort::Sorted;
use super::{fail, read_words, structure, Builder, Groups, HIERARCHY};
use crate::device::{Device, Split};
use crate::error::VkResult;
use crate::interface::*;
use crate::memory::{Buffer, MemKind};
use crate::pipeline::Spec;

/// Levels recorded per submission before the host looks whether the tree has ended.
const BATCH: u32 = 8;

/// The tree: 4-wide nodes, leaf prims (unless direct), and what the entry grid needs (each
/// 4-wide node's parent and level, each tet's home node), with the scratch the grid and the
/// neighbours reuse.
pub(super) struct Tree {
    pub nodes: Split,
    pub prims: Option<Buffer>,
    pub direct: bool,
    pub depth: usize,
    pub binary_levels: u32,
    pub tree: Split,
    pub home: Split,
    /// Only held: the descriptor set names it until the build ends.
    pub _levels: Buffer,
    pub scan: Buffer,
}

/// The tree (its 4-wide nodes, at most one a tet, fit: `build` checked).
pub(super) fn run(b: &mut Builder, dev: &mut Device, s: Sorted, max_leaf: u32) -> VkResult<Tree> {
    let (n, nn) = (b.n as u64, b.n);
    let direct = max_leaf == 1 || nn == 1;
    let spec = Spec::default().set(sc::BUILD_MAX_LEAF, max_leaf).set(sc::DIRECT_LEAVES, direct as u32);
    let passes = [BUILD_SPLIT, BUILD_NEXT_LEVEL, BUILD_REFIT, BUILD_COLLAPSE, BUILD_NEXT_WIDE_LEVEL];
    b.prepare(dev, HIERARCHY, &passes, &spec)?;
    let max_nodes = 2 * n - 1;
    let bnodes = b.split(dev, MemKind::Scratch, "build binary nodes", max_nodes, 16)?;
    dev.write(&bnodes.parts[0], 0, bytemuck::cast_slice(&[0, nn, 0, 0]))?;
    b.bind_split(B_BUILD_NODES, Some(&bnodes), dev.unbound());

    // Top down: split ranges until the leaves. The keys are not read after that.
    let binary_levels = levels(b, dev, &s.levels, false, [BUILD_SPLIT, BUILD_NEXT_LEVEL], [nn, 0, s.half, 0])?;
    b.bind_split(B_BUILD_KEYS, None, dev.unbound());
    drop(s.keys);
    // The boxes only now (the refit writes them), after the keys are gone and for the nodes
    // made (far fewer than 2n with four tets a leaf): the build's peak is lower.
    let made = read_words(dev, &s.levels, BUILD_AT_NODES as u64, 1)?[0] as u64;
    let boxes = b.split(dev, MemKind::Scratch, "build binary boxes", made, 24)?;
    b.bind_split(B_BUILD_BOXES, Some(&boxes), dev.unbound());
    // Bottom up: boxes and 4-wide counts.
    dev.run(|r| {
        for k in (0..binary_levels).rev() {
            let at = Groups::Indirect(&s.levels, level_offset(false, k));
            b.record(r, HIERARCHY, BUILD_REFIT, [nn, k, s.half, 0], [[0.0; 4]; 2], at);
            r.barrier();
        }
    })?;
    let root = read_words(dev, &bnodes.parts[0], 0, 4)?;
    let n_wide = if root[2] == BUILD_LEAF { 1 } else { root[3] as u64 };

    // Top down: the 4-wide nodes.
    let nodes = b.split(dev, MemKind::Structure, "bvh nodes", n_wide, 64)?;
    let work = b.split(dev, MemKind::Scratch, "build worklist", n_wide, 8)?;
    let tree = b.split(dev, MemKind::Scratch, "build node levels", n_wide, 8)?;
    let home = b.split(dev, MemKind::Scratch, "build homes", n, 4)?;
    dev.write(&tree.parts[0], 0, bytemuck::cast_slice(&[0u32, 1]))?; // the root: its own parent, level 1
    dev.write(&work.parts[0], 0, bytemuck::cast_slice(&[0u32, 0]))?; // 4-wide node 0 from binary node 0
    for (slot, array) in [(B_BUILD_WIDE, &nodes), (B_BUILD_WORK, &work), (B_BUILD_TREE, &tree), (B_BUILD_HOME, &home)] {
        b.bind_split(slot, Some(array), dev.unbound());
    }
    let depth = levels(b, dev, &s.levels, true, [BUILD_COLLAPSE, BUILD_NEXT_WIDE_LEVEL], [nn, 0, s.half, 0])?;
    let err = read_words(dev, &s.levels, BUILD_AT_ERROR as u64, 1)?[0];
    if err & BUILD_ERR_EXTENT != 0 {
        return Err(fail("a node box is too large for f32 node scales".into()));
    }
    if err & BUILD_ERR_LEAF != 0 {
        return Err(fail(format!("{n} tets: leaves of several tets hold prim indices below 2^29 (one tet a leaf, the default preset, takes ids up to 2^31)")));
    }
    let prims = if direct {
        None
    } else {
        let p = structure(dev, "bvh prims", 4 * n)?;
        let chunk = b.chunk;
        dev.run(|r| super::copy_out(r, &s.ids, chunk, 4, n * s.half as u64, n, &p))?;
        Some(p)
    };
    // Free the scratch no later stage reads (unbound first: the set stays in use).
    let unbound = dev.unbound();
    for slot in [B_BUILD_IDS, B_BUILD_NODES, B_BUILD_BOXES, B_BUILD_WORK, B_BUILD_WIDE] {
        b.bind_split(slot, None, unbound);
    }
    drop((s.ids, bnodes, boxes, work));
    Ok(Tree { nodes, prims, direct, depth: depth as usize, binary_levels, tree, home, _levels: s.levels, scan: s.scan })
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
