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
use std::io::Write as _;
use std::time::Instant;

/// Levels recorded per submission before the host looks whether the tree has ended.
const BATCH: u32 = 8;

/// The tree: 4-wide nodes, leaf prims (unless direct), and what the entry grid needs (each
/// 4-wide node's parent and level, each prim's home node), with the scratch the grid and the
/// neighbours reuse.
pub(super) struct Tree {
    pub nodes: Split,
    pub prims: Option<Buffer>,
    pub direct: bool,
    pub depth: usize,
    pub binary_levels: u32,
    /// Wall seconds of the top-down split, the refit and the collapse.
    pub seconds: [f64; 3],
    pub tree: Split,
    pub home: Split,
    /// Only held: the descriptor set names it until the build ends.
    pub _levels: Buffer,
    pub scan: Buffer,
}

/// The tree (its 4-wide nodes, at most one a prim, fit: `build` checked).
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
    let t = Instant::now();
    let binary_levels = levels(b, dev, &s.levels, false, [BUILD_SPLIT, BUILD_NEXT_LEVEL], [nn, 0, s.half, 0])?;
    let mut seconds = [t.elapsed().as_secs_f64(), 0.0, 0.0];
    b.bind_split(B_BUILD_KEYS, None, dev.unbound());
    drop(s.keys);
    // The boxes only now (the refit writes them), after the keys are gone and for the nodes
    // made (far fewer than 2n with four prims a leaf): the build's peak is lower.
    let made = read_words(dev, &s.levels, BUILD_AT_NODES as u64, 1)?[0] as u64;
    let boxes = b.split(dev, MemKind::Scratch, "build binary boxes", made, 24)?;
    b.bind_split(B_BUILD_BOXES, Some(&boxes), dev.unbound());
    // Bottom up: boxes and 4-wide counts.
    let t = Instant::now();
    dev.run(|r| {
        for k in (0..binary_levels).rev() {
            let at = Groups::Indirect(&s.levels, level_offset(false, k));
            b.record(r, HIERARCHY, BUILD_REFIT, [nn, k, s.half, 0], [[0.0; 4]; 2], at);
            r.barrier();
        }
    })?;
    let root = read_words(dev, &bnodes.parts[0], 0, 4)?;
    seconds[1] = t.elapsed().as_secs_f64();
    let n_wide = if root[2] == BUILD_LEAF { 1 } else { root[3] as u64 };

    // Top down: the 4-wide nodes.
    let nodes = b.split(dev, MemKind::Structure, "bvh nodes", n_wide, 64)?;
    let work = b.split(dev, MemKind::Scratch, "build 4-wide sources", n_wide, 8)?;
    let tree = b.split(dev, MemKind::Scratch, "build node levels", n_wide, 8)?;
    let home = b.split(dev, MemKind::Scratch, "build homes", n, 4)?;
    // Level 0 marks "not made yet" (the collapse runs a level's nodes by their level).
    dev.run(|r| tree.parts.iter().for_each(|p| super::fill(r, p, 0, p.size, 0)))?;
    dev.write(&tree.parts[0], 0, bytemuck::cast_slice(&[0u32, 1]))?; // the root: its own parent, level 1
    dev.write(&work.parts[0], 0, bytemuck::cast_slice(&[0u32, 0]))?; // 4-wide node 0 from binary node 0
    for (slot, array) in [(B_BUILD_WIDE, &nodes), (B_BUILD_WORK, &work), (B_BUILD_TREE, &tree), (B_BUILD_HOME, &home)] {
        b.bind_split(slot, Some(array), dev.unbound());
    }
    let t = Instant::now();
    let counts = [nn, 0, s.half, n_wide as u32];
    let depth = levels(b, dev, &s.levels, true, [BUILD_COLLAPSE, BUILD_NEXT_WIDE_LEVEL], counts)?;
    seconds[2] = t.elapsed().as_secs_f64();
    let err = read_words(dev, &s.levels, BUILD_AT_ERROR as u64, 1)?[0];
    if err & BUILD_ERR_EXTENT != 0 {
        return Err(fail("a node box is too large for f32 node scales".into()));
    }
    if err & BUILD_ERR_LEAF != 0 {
        return Err(fail(format!("{n} prims (tets, or a mixed mesh's cells): leaves of several prims hold prim indices below 2^29 (one prim a leaf, the default preset, takes ids up to 2^31)")));
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
    let depth = depth as usize;
    Ok(Tree { nodes, prims, direct, depth, binary_levels, seconds, tree, home, _levels: s.levels, scan: s.scan })
}

/// Byte offset of level `k`'s dispatch size in the level table.
fn level_offset(wide: bool, k: u32) -> u64 {
    4 * (BUILD_LEVELS_AT + 8 * if wide { BUILD_MAX_LEVELS + k } else { k }) as u64
}

/// Runs `passes` (a level's pass, then the next-level pass) level by level from level 0 until
/// a level is empty; returns the number of non-empty levels. Each dispatch's size is the
/// level table's (indirect): a binary level's entries, or every 4-wide node (`counts[3]` of
/// them) for a 4-wide level, none past the last.
fn levels(
    b: &Builder,
    dev: &mut Device,
    table: &Buffer,
    wide: bool,
    passes: [u32; 2],
    counts: [u32; 4],
) -> VkResult<u32> {
    let mut first = 0;
    // TETLOC_BUILD_PROFILE=1: each batch's levels, entries and seconds on stderr (a measurement
    // hook: the binary tree's time against its node counts, BENCHMARKS.md).
    let profile = std::env::var_os("TETLOC_BUILD_PROFILE").is_some();
    let batch = if profile { 1 } else { BATCH };
    loop {
        let last = (first + batch).min(BUILD_MAX_LEVELS - 1);
        let t = Instant::now();
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
        if profile {
            let sizes: Vec<u32> = (0..(last - first) as usize).map(|k| words[8 * k + 5] - words[8 * k + 4]).collect();
            let what = if wide { "4-wide" } else { "binary" };
            let _ = writeln!(
                std::io::stderr(),
                "{what} levels {first}..{last}: {:.4} s, entries {sizes:?}",
                t.elapsed().as_secs_f64()
            );
        }
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
