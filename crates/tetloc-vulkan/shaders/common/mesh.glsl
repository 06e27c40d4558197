// The mesh as the GPU sees it: f32 vertices (3 floats each, tightly packed), canonical
// u32x4 tets (or packed, TET_BITS), and the scalar fields being sampled (per vertex or per
// cell, one buffer each).
#ifndef TL_MESH_GLSL
#define TL_MESH_GLSL
#extension GL_EXT_nonuniform_qualifier : require
#include "common/packed.glsl"

layout(std430, binding = TL_B_POINTS) readonly buffer TlPoints { float tl_points[]; };
layout(std430, binding = TL_B_TETS) readonly buffer TlTets { uvec4 tl_tets[]; };
// Field f's values: tl_fields[f].v (a launch reads its fields with a loop index, the same in
// every invocation: no nonuniformEXT).
layout(std430, binding = TL_B_FIELD) readonly buffer TlField { float v[]; } tl_fields[TL_MAX_FIELDS];
// A mixed mesh's cells (CELL_BOXES): n_cells + 1 words, each cell's first decomposition tet,
// the last the number of tets.
layout(std430, binding = TL_B_CELL_TETS) readonly buffer TlCellTets { uint tl_cell_tets[]; };

// Arrays larger than one buffer may be (maxMemoryAllocationSize, maxStorageBufferRange: 4 GiB
// on the H100) are split into buffers of a fixed number of elements N each (src/device.rs
// `Split`): element i lives in buffer i / N, buffer 0 being the binding above and buffer
// k >= 1 element k - 1 of the matching _HI binding. N is a specialization constant, 0 when
// the array fits one buffer: then the split path folds away. Read through the accessors
// (tl_vertex, tl_tet, tl_node_word, tl_neighbors4), not the arrays. POINTS_CHUNK: vertices
// per buffer, TETS_CHUNK: tets per buffer.
layout(std430, binding = TL_B_POINTS_HI) readonly buffer TlPointsHi { float v[]; } tl_points_hi[TL_MAX_CHUNKS - 1];
layout(std430, binding = TL_B_TETS_HI) readonly buffer TlTetsHi { uvec4 v[]; } tl_tets_hi[TL_MAX_CHUNKS - 1];
// With REFINE_BARY: each vertex's residual (its file coordinates minus tl_vertex, working
// frame), split as the vertices are (POINTS_CHUNK).
layout(std430, binding = TL_B_RESIDUALS) readonly buffer TlResiduals { float tl_residuals[]; };
layout(std430, binding = TL_B_RESIDUALS_HI) readonly buffer TlResidualsHi { float v[]; } tl_residuals_hi[TL_MAX_CHUNKS - 1];

// `return arr[c].v[o];` for a lane-varying c (needs shaderStorageBufferArrayNonUniformIndexing,
// which the context enables; a switch over constant indices compiled for minutes on lavapipe).
#define TL_RETURN_HI(arr, c, o) return arr[nonuniformEXT(c)].v[o];

vec3 tl_vertex(uint i) {
    if (POINTS_CHUNK == 0u || i < POINTS_CHUNK) {
        return vec3(tl_points[3 * i], tl_points[3 * i + 1], tl_points[3 * i + 2]);
    }
    uint c = i / POINTS_CHUNK - 1u, o = 3u * (i % POINTS_CHUNK);
    return vec3(tl_points_hi[nonuniformEXT(c)].v[o], tl_points_hi[nonuniformEXT(c)].v[o + 1u], tl_points_hi[nonuniformEXT(c)].v[o + 2u]);
}

vec3 tl_residual(uint i) {
    if (POINTS_CHUNK == 0u || i < POINTS_CHUNK) {
        return vec3(tl_residuals[3 * i], tl_residuals[3 * i + 1], tl_residuals[3 * i + 2]);
    }
    uint c = i / POINTS_CHUNK - 1u, o = 3u * (i % POINTS_CHUNK);
    return vec3(tl_residuals_hi[nonuniformEXT(c)].v[o], tl_residuals_hi[nonuniformEXT(c)].v[o + 1u], tl_residuals_hi[nonuniformEXT(c)].v[o + 2u]);
}

// TET_BITS != 0: the tets packed (packed.glsl) in one buffer, 4 fields a tet.
uint tl_tet_word(uint w) {
    return tl_tets[w >> 2u][w & 3u];
}
TL_PACKED4_READER(tl_tet_packed, tl_tet_word, TET_BITS)

uvec4 tl_tet(uint i) {
    if (TET_BITS != 0u) {
        return tl_tet_packed(i);
    }
    if (TETS_CHUNK == 0u || i < TETS_CHUNK) {
        return tl_tets[i];
    }
    uint c = i / TETS_CHUNK - 1u, o = i % TETS_CHUNK;
    TL_RETURN_HI(tl_tets_hi, c, o)
}

// The tets [x, y) of BVH prim p: tet p itself, or with CELL_BOXES the decomposition tets of
// cell p (consecutive), which the kernels that take one box a cell test in order.
uvec2 tl_prim_tets(uint p) {
    return CELL_BOXES ? uvec2(tl_cell_tets[p], tl_cell_tets[p + 1u]) : uvec2(p, p + 1u);
}

#endif
