//! The entry grid (`shaders/build/grid.comp`, `grid_starts.comp`), as `EntryGrid::new`
//! makes it: the grid's shape and the cells' centres per axis from the host (the same
//! functions), each prim's box rasterized into the cells (lowest and highest home node, lowest
//! prim, by atomics), each cell's node the common ancestor of its lowest and highest home (the
//! nodes are numbered depth first), and each cell's walk start by the shaders' traversal.

use super::hierarchy::Tree;
use super::{scratch, structure, Builder, Groups, Wanted, GRID, GRID_STARTS};
use crate::device::Device;
use crate::error::VkResult;
use crate::interface::*;
use crate::kernels::Inputs;
use crate::memory::Buffer;
use crate::pipeline::{Binding, Spec};
use tetloc_core::bvh::EntryGrid;

pub(super) fn run(b: &mut Builder, dev: &mut Device, input: &Inputs, tree: &Tree, want: Wanted) -> VkResult<Buffer> {
    let mesh = input.mesh;
    let (lo, hi) = (mesh.info.bounds_min, mesh.info.bounds_max);
    let (dims, inv) = EntryGrid::shape(b.n as usize, (lo, hi), want.prims_per_cell);
    let cells = dims[0] * dims[1] * dims[2];
    let starts_at = if want.walk { cells } else { 0 };
    let header = [dims[0], dims[1], dims[2], starts_at, inv[0].to_bits(), inv[1].to_bits(), inv[2].to_bits(), 0];
    let words = 8 + cells as u64 * if want.walk { 2 } else { 1 };
    let grid = structure(dev, "entry grid", 4 * words)?;
    dev.write(&grid, 0, bytemuck::cast_slice(&header))?;
    // Per cell: lowest home, highest home, lowest prim; then the centres on each axis.
    let centres: Vec<u32> =
        (0..3).flat_map(|a| (0..dims[a]).map(move |c| EntryGrid::centre_coord(lo[a], inv[a], c).to_bits())).collect();
    let scratch_cells = scratch(dev, "build grid cells", 4 * (3 * cells as u64 + centres.len() as u64))?;
    dev.write(&scratch_cells, 4 * 3 * cells as u64, bytemuck::cast_slice(&centres))?;
    b.bind_split(B_BUILD_TREE, Some(&tree.tree), dev.unbound());
    b.bind_split(B_BUILD_HOME, Some(&tree.home), dev.unbound());
    b.bind(B_BUILD_GRID, &grid);
    b.bind(B_BUILD_CELLS, &scratch_cells);
    b.bind(B_GRID, &grid);
    b.prepare(dev, GRID, &[BUILD_GRID_RASTER, BUILD_GRID_CELLS], &Spec::default())?;
    if want.walk {
        let spec = Spec::default()
            .set(sc::STACK_SIZE, (3 * tree.depth + 1) as u32)
            .set(sc::DIRECT_LEAVES, tree.direct as u32)
            .set(sc::NODES_CHUNK, tree.nodes.per_chunk);
        b.prepare(dev, GRID_STARTS, &[0], &spec)?;
        b.desc.write(&Binding::split(B_ACCEL, B_ACCEL_HI, Some(&tree.nodes), dev.unbound()));
        b.bind(B_PRIMS, tree.prims.as_ref().unwrap_or(dev.unbound()));
    }
    let (n, c4) = (b.n, cells as u64 * 4);
    let grid_params = [[lo[0], lo[1], lo[2], 0.0], [inv[0], inv[1], inv[2], 0.0]];
    dev.run(|r| {
        super::fill(r, &scratch_cells, 0, c4, u32::MAX);
        super::fill(r, &scratch_cells, c4, c4, 0);
        super::fill(r, &scratch_cells, 2 * c4, c4, u32::MAX);
        r.barrier();
        b.record(r, GRID, BUILD_GRID_RASTER, [n, dims[0], dims[1], dims[2]], grid_params, Groups::Items(n as u64));
        r.barrier();
        b.record(
            r,
            GRID,
            BUILD_GRID_CELLS,
            [cells, dims[0], dims[1], dims[2]],
            grid_params,
            Groups::Items(cells as u64),
        );
        r.barrier();
        if want.walk {
            b.record(r, GRID_STARTS, 0, [cells, dims[0], dims[1], dims[2]], grid_params, Groups::Items(cells as u64));
        }
    })?;
    let unbound = dev.unbound();
    for slot in [B_BUILD_GRID, B_BUILD_CELLS, B_GRID, B_PRIMS] {
        b.bind(slot, unbound);
    }
    b.desc.write(&Binding::split(B_ACCEL, B_ACCEL_HI, None, unbound));
    Ok(grid)
}

/// The prims (tets, or a mixed mesh's cells) a cell of the entry grid holds on average:
/// `wanted`, or more when the grid's words or the build's cell scratch (12 B a cell) would not
/// fit one buffer of `limit` bytes (the query shaders read the grid as one buffer). Both
/// builders take this value.
pub(crate) fn prims_per_cell(n_prims: usize, bounds: ([f32; 3], [f32; 3]), wanted: usize, limit: u64) -> usize {
    let mut per = wanted.max(1);
    loop {
        let (dims, _) = EntryGrid::shape(n_prims, bounds, per);
        let cells = dims.iter().map(|&d| d as u64).product::<u64>();
        let centres = dims.iter().map(|&d| d as u64).sum::<u64>();
        if 4 * (3 * cells + centres) <= limit && 4 * (8 + 2 * cells) <= limit {
            return per;
        }
        per += 1;
    }
}
