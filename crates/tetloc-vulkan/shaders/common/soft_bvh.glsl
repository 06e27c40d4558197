// soft-bvh traversal (the paper's cuda-bvh), shared by the point-location kernel
// (soft_bvh.comp) and the volume ray marcher: depth-first traversal of a 4-wide BVH with
// quantized child boxes, in software, returning at the tet that holds the point strictly
// inside, or for a point on faces the lowest id that holds it (the tie rule, geom::lowest_claim).
// Its prims are tets, or the cells of a mixed mesh (CELL_BOXES: a leaf tests a cell's tets).
// Needs interface.glsl, mesh.glsl and tet.glsl first, and GL_EXT_control_flow_attributes.
#ifndef TL_SOFT_BVH_GLSL
#define TL_SOFT_BVH_GLSL

#include "common/walk.glsl" // paths resolve against shaders/ (build.rs)

// Nodes as four uvec4 (tetloc_core::bvh::QNode4): w0 = origin.xyz, scale.x;
// w1 = scale.yz, quantized lower/upper x; w2 = quantized lower/upper y, z (one byte per
// child); w3 = child references.
layout(std430, binding = TL_B_ACCEL) readonly buffer TlNodes { uvec4 tl_nodes[]; };
// NODES_CHUNK: nodes per buffer when the nodes are split over several (mesh.glsl), 0: one buffer.
layout(std430, binding = TL_B_ACCEL_HI) readonly buffer TlNodesHi { uvec4 v[]; } tl_nodes_hi[TL_MAX_CHUNKS - 1];

// Word k of node r.
uvec4 tl_node_word(uint r, uint k) {
    if (NODES_CHUNK == 0u || r < NODES_CHUNK) {
        return tl_nodes[4u * r + k];
    }
    uint c = r / NODES_CHUNK - 1u, o = 4u * (r % NODES_CHUNK) + k;
    TL_RETURN_HI(tl_nodes_hi, c, o)
}
layout(std430, binding = TL_B_PRIMS) readonly buffer TlPrims { uint tl_prims[]; };
// PRIM_BITS != 0: the prims packed (packed.glsl).
uint tl_prim_word(uint w) {
    return tl_prims[w];
}
TL_PACKED_READER(tl_prim_field, tl_prim_word, PRIM_BITS)
// DIRECT_LEAVES: one prim (tet, or cell: CELL_BOXES) per leaf, its id in the reference itself
// (no tl_prims lookup).
// GRID_START: start below the root, at the node the entry grid names for the point's cell
// (tetloc_core::bvh::EntryGrid::words: header dims.xyz, 0, inv.xyz as bits, 0; then the cells).
layout(std430, binding = TL_B_GRID) readonly buffer TlGrid { uint tl_grid[]; };
// WALK_START: walk from the tet the entry grid names for the point's cell (after the cells'
// nodes; header word 3 = number of cells), at most WALK_MAX steps; traversal from the cell's
// node when the walk leaves the mesh, runs out of steps or ends on a face (so the answer is
// the traversal's).

// tetloc_core::bvh::grid::cell_coord: the same f32 operations, so CPU and GPU agree on the cell.
uint tl_cell_coord(float p, float lo, float inv, uint dim) {
    precise float x = (p - lo) * inv;
    return uint(clamp(floor(x), 0.0, float(dim - 1u)));
}

// Bytes 0..3 of a word, one per child.
vec4 tl_bytes(uint w) {
    return vec4((uvec4(w) >> uvec4(0u, 8u, 16u, 24u)) & 0xffu);
}

// Depth-first traversal from node reference `ref` (0: the root). `ties` false: the first tet
// in traversal order that holds p (tl_on_boundary says whether on its boundary); true: the
// tet that holds p strictly inside, else the lowest id of the tets that hold it on their
// boundary, whatever the order (tetloc_core::bvh::WideBvh::locate). TL_OUTSIDE when none
// (TL_DEFERRED: undecided, DEFER_EXACT). tl_traverse runs both.
int tl_traverse_pass(uint ref, vec3 p, const bool ties, out uvec4 ids, out vec4 bary) {
    uint stack[STACK_SIZE];
    uint sp = 0u;
    int tie = TL_OUTSIDE; // the lowest tet holding p on its boundary so far
    while (true) {
        if ((ref & TL_LEAF) != 0u) {
            // A direct leaf holds its tet id in all 31 bits (tetloc_core::bvh::wide).
            uint first = DIRECT_LEAVES ? ref & ~TL_LEAF : ref & TL_LEAF_FIRST_MAX;
            uint count = DIRECT_LEAVES ? 1u : ((ref >> TL_LEAF_COUNT_SHIFT) & 3u) + 1u;
            for (uint k = 0u; k < count; k++) {
                uint prim = DIRECT_LEAVES ? first : PRIM_BITS != 0u ? tl_prim_field(first + k) : tl_prims[first + k];
                uvec2 tets = tl_prim_tets(prim); // the tet, or a cell's tets (CELL_BOXES)
                for (uint tet = tets.x; tet < tets.y; tet++) {
                    ids = tl_tet(tet);
                    int exit_face;
                    if (tl_test(ids, p, bary, exit_face)) {
                        if (!ties || !tl_on_boundary) {
                            return int(tet); // (strictly inside: no other tet holds p)
                        }
                        tie = tie == TL_OUTSIDE ? int(tet) : min(tie, int(tet));
                    }
                    if (DEFER_EXACT && tl_undecided) {
                        return TL_DEFERRED;
                    }
                }
            }
        } else {
            uvec4 w0 = tl_node_word(ref, 0u), w1 = tl_node_word(ref, 1u);
            uvec4 w2 = tl_node_word(ref, 2u), w3 = tl_node_word(ref, 3u);
            vec3 org = uintBitsToFloat(w0.xyz);
            vec3 scl = uintBitsToFloat(uvec3(w0.w, w1.x, w1.y));
            // Dequantize exactly as the CPU did when it made the boxes conservative.
            precise vec4 lox = org.x + tl_bytes(w1.z) * scl.x, hix = org.x + tl_bytes(w1.w) * scl.x;
            precise vec4 loy = org.y + tl_bytes(w2.x) * scl.y, hiy = org.y + tl_bytes(w2.y) * scl.y;
            precise vec4 loz = org.z + tl_bytes(w2.z) * scl.z, hiz = org.z + tl_bytes(w2.w) * scl.z;
            bvec4 hit = bvec4(uvec4(greaterThanEqual(vec4(p.x), lox)) & uvec4(lessThanEqual(vec4(p.x), hix))
                & uvec4(greaterThanEqual(vec4(p.y), loy)) & uvec4(lessThanEqual(vec4(p.y), hiy))
                & uvec4(greaterThanEqual(vec4(p.z), loz)) & uvec4(lessThanEqual(vec4(p.z), hiz))
                & uvec4(notEqual(w3, uvec4(TL_EMPTY))));
            uint next = TL_EMPTY;
            [[unroll]] for (int c = 0; c < 4; c++) {
                if (hit[c]) {
                    if (next == TL_EMPTY) {
                        next = w3[c];
                    } else if (sp < STACK_SIZE) { // never full: STACK_SIZE comes from the tree depth
                        stack[sp++] = w3[c];
                    }
                }
            }
            if (next != TL_EMPTY) {
                ref = next;
                continue;
            }
        }
        if (sp == 0u) {
            if (ties && tie != TL_OUTSIDE && OUTPUT_MODE != TL_OUT_IDS) {
                // The tie's vertices and weights again, for its values (rare: not worth
                // registers held through the traversal; and none of it where only ids are
                // asked for, whose kernels would carry the test's code for nothing).
                ids = tl_tet(uint(tie));
                int exit_face;
                tl_test(ids, p, bary, exit_face);
            }
            return tie;
        }
        ref = stack[--sp];
    }
}

// The tie rule over the traversal: the first pass as fast as before the rule (it stops at
// the first tet that holds p); only where that tet holds p on its boundary, a second pass
// that goes on past such claims (measured on the H100: one pass doing both cost 6-8 % on
// the paper's uniform points, which never tie).
int tl_traverse(uint ref, vec3 p, out uvec4 ids, out vec4 bary) {
    int tet = tl_traverse_pass(ref, p, false, ids, bary);
    if (tet >= 0 && tl_on_boundary) {
        tet = tl_traverse_pass(ref, p, true, ids, bary);
    }
    return tet;
}

int tl_locate(vec3 p, out uvec4 ids, out vec4 bary) {
    uint ref = 0u; // the root
    if (GRID_START || WALK_START) {
        uvec3 dims = uvec3(tl_grid[0], tl_grid[1], tl_grid[2]);
        vec3 inv = uintBitsToFloat(uvec3(tl_grid[4], tl_grid[5], tl_grid[6]));
        vec3 lo = params.lo_tmin.xyz;
        uint cx = tl_cell_coord(p.x, lo.x, inv.x, dims.x);
        uint cy = tl_cell_coord(p.y, lo.y, inv.y, dims.y);
        uint cz = tl_cell_coord(p.z, lo.z, inv.z, dims.z);
        uint cell = (cz * dims.y + cy) * dims.x + cx;
        ref = tl_grid[8u + cell];
        if (ref == TL_EMPTY) {
            return TL_OUTSIDE; // no tet's box overlaps this cell
        }
        if (WALK_START) {
            int tet = tl_walk(int(tl_grid[8u + tl_grid[3] + cell]), p, WALK_MAX, ids, bary);
            if (tet == TL_DEFERRED) {
                return TL_DEFERRED;
            }
            // Strictly inside: the only tet holding p, the one traversal would find too.
            if (tet >= 0 && !tl_on_boundary) {
                return tet;
            }
        }
    }
    return tl_traverse(ref, p, ids, bary);
}

#endif
