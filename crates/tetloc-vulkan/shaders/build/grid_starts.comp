#version 460
// soft-bvh's entry grid, last pass (src/build/grid.rs): each cell's walk start, as
// EntryGrid::new picks it: the tet holding the cell's centre, found by the shaders' own
// traversal from the cell's node, else the (first tet of the) lowest prim whose box overlaps
// the cell. The centres come from the host per axis (EntryGrid::centre's arithmetic, no
// division here).
// params.counts: cells, dims.
#extension GL_GOOGLE_include_directive : require
#extension GL_EXT_control_flow_attributes : require
#include "interface.glsl" // generated from src/interface.rs (build.rs)
#include "common/mesh.glsl"
#include "common/tet.glsl"
#include "common/soft_bvh.glsl"

layout(local_size_x = TL_BUILD_GROUP) in;

layout(std430, binding = TL_B_BUILD_GRID) buffer TlBuildGrid { uint tl_build_grid[]; };
// Lowest home, highest home, lowest prim (cells each), then the centres' x, y, z coordinates.
layout(std430, binding = TL_B_BUILD_CELLS) readonly buffer TlBuildCells { uint tl_cells[]; };

void main() {
    uint i = (gl_WorkGroupID.y * gl_NumWorkGroups.x + gl_WorkGroupID.x) * TL_BUILD_GROUP + gl_LocalInvocationID.x;
    uint n = params.counts.x;
    uvec3 dims = params.counts.yzw;
    if (i >= n) {
        return;
    }
    uint node = tl_grid[8u + i];
    uint start = TL_EMPTY;
    if (node != TL_EMPTY) {
        uvec3 c = uvec3(i % dims.x, (i / dims.x) % dims.y, i / (dims.x * dims.y));
        uint at = 3u * n;
        vec3 p = uintBitsToFloat(uvec3(tl_cells[at + c.x], tl_cells[at + dims.x + c.y],
                                       tl_cells[at + dims.x + dims.y + c.z]));
        uvec4 ids;
        vec4 bary;
        int tet = tl_traverse(node, p, ids, bary);
        // Else the lowest prim's (first) tet.
        start = tet >= 0 ? uint(tet) : tl_prim_tets(tl_cells[2u * n + i]).x;
    }
    tl_build_grid[8u + n + i] = start;
}
