// The GPU build of soft-bvh's structure (src/build): the buffers its passes share and the
// helpers they agree on. Every pass runs in workgroups of BUILD_GROUP invocations over a 2-D
// grid of workgroups (src/build/mod.rs `dispatch`), linearised by tl_build_index.
#ifndef TL_BUILD_GLSL
#define TL_BUILD_GLSL

// Morton keys (low word, high word of a 63-bit code) and prim ids: two halves of n each, the
// radix sort's source and destination (params name the half).
layout(std430, binding = TL_B_BUILD_KEYS) buffer TlBuildKeys { uvec2 tl_keys[]; };
layout(std430, binding = TL_B_BUILD_IDS) buffer TlBuildIds { uint tl_ids[]; };
// Scan scratch: the values being scanned, then each level's chunk sums (src/build/scan.rs).
layout(std430, binding = TL_B_BUILD_SCAN) buffer TlBuildScan { uint tl_scan[]; };
// Counters (BUILD_AT_*), then per level 8 words: indirect dispatch size (x, y, z), 0, the
// level's first and end entry, 0, 0. Binary levels first, then BUILD_MAX_LEVELS 4-wide ones.
layout(std430, binding = TL_B_BUILD_LEVELS) buffer TlBuildLevels { uint tl_levels[]; };
// Binary nodes: first and end sorted prim, first child (the second is next to it) or
// BUILD_LEAF, 4-wide nodes in the subtree when this node heads one (0 for leaves).
layout(std430, binding = TL_B_BUILD_NODES) buffer TlBuildNodes { uvec4 tl_bnodes[]; };
// Their boxes: min xyz, max xyz (6 floats a node).
layout(std430, binding = TL_B_BUILD_BOXES) buffer TlBuildBoxes { float tl_bboxes[]; };

vec3 tl_box_lo(uint b) {
    return vec3(tl_bboxes[6u * b], tl_bboxes[6u * b + 1u], tl_bboxes[6u * b + 2u]);
}

vec3 tl_box_hi(uint b) {
    return vec3(tl_bboxes[6u * b + 3u], tl_bboxes[6u * b + 4u], tl_bboxes[6u * b + 5u]);
}

uint tl_build_index() {
    return (gl_WorkGroupID.y * gl_NumWorkGroups.x + gl_WorkGroupID.x) * TL_BUILD_GROUP + gl_LocalInvocationID.x;
}

// Word w of level k's entry of the binary (wide = false) or 4-wide level table.
uint tl_level_word(bool wide, uint k, uint w) {
    return TL_BUILD_LEVELS_AT + 8u * (wide ? TL_BUILD_MAX_LEVELS + k : k) + w;
}

// The box of tet t, as geom::tet_bounds (min and max are exact: any order gives the same).
void tl_tet_box(uint t, out vec3 lo, out vec3 hi) {
    uvec4 ids = tl_tet(t);
    lo = tl_vertex(ids.x);
    hi = lo;
    for (int k = 1; k < 4; k++) {
        vec3 q = tl_vertex(ids[k]);
        lo = min(lo, q);
        hi = max(hi, q);
    }
}

// Exclusive prefix sum over the workgroup (Hillis-Steele in shared memory); `total`: the sum.
shared uint tl_group[TL_BUILD_GROUP];
uint tl_group_scan(uint v, out uint total) {
    uint t = gl_LocalInvocationID.x;
    tl_group[t] = v;
    barrier();
    for (uint d = 1u; d < TL_BUILD_GROUP; d <<= 1u) {
        uint add = t >= d ? tl_group[t - d] : 0u;
        barrier();
        tl_group[t] += add;
        barrier();
    }
    total = tl_group[TL_BUILD_GROUP - 1u];
    uint r = tl_group[t] - v;
    barrier();
    return r;
}

#endif
