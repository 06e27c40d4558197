#version 460
// soft-bvh's entry grid (src/build/grid.rs), the cells' nodes as tetloc_core's EntryGrid::new
// makes them. The 4-wide nodes are numbered depth first, so the lowest common ancestor of a
// cell's nodes is that of the lowest and the highest of them:
//   GRID_RASTER  each prim's box over the cells it overlaps (grid::cell_coord's arithmetic):
//                the lowest and highest home node, and the lowest prim id, per cell;
//   GRID_CELLS   each cell's node: the common ancestor of those two, or EMPTY.
// params.counts: prims (GRID_RASTER) or cells (GRID_CELLS), dims; params.lo_tmin.xyz: the
// grid's origin; hi_tmax.xyz: cells per unit length. The cells' scratch: lowest home, highest
// home, lowest prim (a word a cell each).
#extension GL_GOOGLE_include_directive : require
#include "interface.glsl" // generated from src/interface.rs (build.rs)
#include "common/mesh.glsl"
#include "build/build.glsl"

layout(local_size_x = TL_BUILD_GROUP) in;

layout(std430, binding = TL_B_BUILD_GRID) buffer TlBuildGrid { uint tl_build_grid[]; };
layout(std430, binding = TL_B_BUILD_CELLS) buffer TlBuildCells { uint tl_cells[]; };

uint tl_cell_coord(float p, float lo, float inv, uint dim) {
    precise float x = (p - lo) * inv;
    return uint(clamp(floor(x), 0.0, float(dim - 1u)));
}

// WideBvh::lca: climb from the deeper node, then from both.
uint tl_lca(uint a, uint b) {
    while (tl_tree(a).y > tl_tree(b).y) {
        a = tl_tree(a).x;
    }
    while (tl_tree(b).y > tl_tree(a).y) {
        b = tl_tree(b).x;
    }
    while (a != b) {
        a = tl_tree(a).x;
        b = tl_tree(b).x;
    }
    return a;
}

void main() {
    uint i = tl_build_index(), n = params.counts.x;
    uvec3 dims = params.counts.yzw;
    uint cells = dims.x * dims.y * dims.z;
    if (i >= n) {
        return;
    }
    if (BUILD_PASS == TL_BUILD_GRID_RASTER) {
        vec3 lo, hi;
        tl_prim_box(i, lo, hi);
        vec3 org = params.lo_tmin.xyz, inv = params.hi_tmax.xyz;
        uvec3 c0, c1;
        for (int a = 0; a < 3; a++) {
            c0[a] = tl_cell_coord(lo[a], org[a], inv[a], dims[a]);
            c1[a] = tl_cell_coord(hi[a], org[a], inv[a], dims[a]);
        }
        uint home = tl_home(i);
        for (uint z = c0.z; z <= c1.z; z++) {
            for (uint y = c0.y; y <= c1.y; y++) {
                for (uint x = c0.x; x <= c1.x; x++) {
                    uint cell = (z * dims.y + y) * dims.x + x;
                    atomicMin(tl_cells[cell], home);
                    atomicMax(tl_cells[cells + cell], home);
                    atomicMin(tl_cells[2u * cells + cell], i);
                }
            }
        }
    } else {
        uint low = tl_cells[i];
        tl_build_grid[8u + i] = low == TL_EMPTY ? TL_EMPTY : tl_lca(low, tl_cells[cells + i]);
    }
}
