// The GPU build of soft-bvh's structure (src/build): the buffers its passes share and the
// helpers they agree on. Every pass runs in workgroups of BUILD_GROUP invocations over a 2-D
// grid of workgroups (src/build/mod.rs `dispatch`), linearised by tl_build_index.
#ifndef TL_BUILD_GLSL
#define TL_BUILD_GLSL

// The arrays that grow with the mesh are split (src/build/mod.rs `split`): element i of an
// array of S-byte elements lives in buffer i / (BUILD_CHUNK_BYTES / S) of its binding array,
// so no buffer passes the device's limit and no index passes 32 bits (indices count
// elements, never words). Read and write them through their accessors: NAME(i), NAME_set(i, x).
#define TL_SPLIT_ARRAY(T, name, slot)                                                           \
    layout(std430, binding = slot) buffer name##_block { T v[]; } name##_parts[TL_MAX_CHUNKS]; \
    const uint name##_per = BUILD_CHUNK_BYTES / uint(sizeof_##T);                                \
    T name(uint i) { return name##_parts[nonuniformEXT(i / name##_per)].v[i % name##_per]; }   \
    void name##_set(uint i, T x) { name##_parts[nonuniformEXT(i / name##_per)].v[i % name##_per] = x; }

// Element sizes in bytes (std430, arrays of these are tightly packed).
const uint sizeof_uint = 4u;
const uint sizeof_uvec2 = 8u;
const uint sizeof_uvec4 = 16u;
const uint sizeof_ivec4 = 16u;
// A binary node's box: min xyz, max xyz.
struct TlBox {
    float lx, ly, lz, hx, hy, hz;
};
const uint sizeof_TlBox = 24u;
// A face record of the neighbour search: its other two vertices, 4 tet + local face.
struct TlFace {
    uint b, c, code;
};
const uint sizeof_TlFace = 12u;
// A 4-wide node (tetloc_core::bvh::QNode4) as four uvec4.
struct TlQNode {
    uvec4 w[4];
};
const uint sizeof_TlQNode = 64u;

// Morton keys (low word, high word of a 63-bit code) and prim ids: two halves of n each, the
// radix sort's source and destination (params name the half).
TL_SPLIT_ARRAY(uvec2, tl_key, TL_B_BUILD_KEYS)
TL_SPLIT_ARRAY(uint, tl_id, TL_B_BUILD_IDS)
// Scan scratch: the values being scanned, then each level's chunk sums (src/build/scan.rs).
layout(std430, binding = TL_B_BUILD_SCAN) buffer TlBuildScan { uint tl_scan[]; };
// Counters (BUILD_AT_*), then per level 8 words: indirect dispatch size (x, y, z), 0, the
// level's first and end entry, 0, 0. Binary levels first, then BUILD_MAX_LEVELS 4-wide ones.
layout(std430, binding = TL_B_BUILD_LEVELS) buffer TlBuildLevels { uint tl_levels[]; };
// Binary nodes: first and end sorted prim, first child (the second is next to it) or
// BUILD_LEAF, 4-wide nodes in the subtree when this node heads one (0 for leaves).
TL_SPLIT_ARRAY(uvec4, tl_bnode, TL_B_BUILD_NODES)
// Their boxes.
TL_SPLIT_ARRAY(TlBox, tl_bbox, TL_B_BUILD_BOXES)
// The 4-wide nodes, each 4-wide node's (own index, binary node) and (parent, level; 0 until
// made), each prim's home node.
TL_SPLIT_ARRAY(TlQNode, tl_wide, TL_B_BUILD_WIDE)
TL_SPLIT_ARRAY(uvec2, tl_work, TL_B_BUILD_WORK)
TL_SPLIT_ARRAY(uvec2, tl_tree, TL_B_BUILD_TREE)
TL_SPLIT_ARRAY(uint, tl_home, TL_B_BUILD_HOME)
// The neighbour search's face records and the neighbours (a tet's four, as the walk reads them).
TL_SPLIT_ARRAY(TlFace, tl_face_rec, TL_B_BUILD_FACES)
TL_SPLIT_ARRAY(ivec4, tl_build_nb, TL_B_BUILD_NEIGHBORS)

vec3 tl_box_lo(uint b) {
    TlBox x = tl_bbox(b);
    return vec3(x.lx, x.ly, x.lz);
}

vec3 tl_box_hi(uint b) {
    TlBox x = tl_bbox(b);
    return vec3(x.hx, x.hy, x.hz);
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

// The box of prim p: tet p's, or with CELL_BOXES the union of cell p's decomposition tets'
// (kernels::prim_box; min and max are exact, so any order gives the same box).
void tl_prim_box(uint p, out vec3 lo, out vec3 hi) {
    uvec2 tets = tl_prim_tets(p);
    tl_tet_box(tets.x, lo, hi);
    for (uint t = tets.x + 1u; t < tets.y; t++) {
        vec3 l, h;
        tl_tet_box(t, l, h);
        lo = min(lo, l);
        hi = max(hi, h);
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
