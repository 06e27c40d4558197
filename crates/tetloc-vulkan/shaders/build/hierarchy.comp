#version 460
// The BVH over the sorted Morton keys and its collapse into soft-bvh's 4-wide quantized
// nodes (src/build/hierarchy.rs): the same tree, node for node, as tetloc_core's CPU builder
// (bvh/build.rs) and WideBvh::collapse (bvh/wide.rs), built level by level.
//   SPLIT            top down, one level a dispatch: a range of more than BUILD_MAX_LEAF
//                    prims splits where its highest differing key bit turns on (the middle
//                    when its keys are equal), children allocated in pairs;
//   NEXT_LEVEL       one invocation: the next level's range and dispatch size;
//   REFIT            bottom up, one level a dispatch: boxes, and each interior node's 4-wide
//                    children (tl_kids) and the count of 4-wide nodes in its subtree;
//   COLLAPSE         top down over the 4-wide levels: each 4-wide node from its binary node,
//                    numbered in depth-first order (as the CPU emits them) from the counts,
//                    a level's nodes in that order;
//   NEXT_WIDE_LEVEL  one invocation: the next 4-wide level's size and dispatch size (every
//                    4-wide node, or none after the last level).
// params.counts: prims, the level, the half of keys and ids that holds the sorted ones, and
// (COLLAPSE) the number of 4-wide nodes.
#extension GL_GOOGLE_include_directive : require
#include "interface.glsl" // generated from src/interface.rs (build.rs)
#include "common/mesh.glsl"
#include "build/build.glsl"

layout(local_size_x = TL_BUILD_GROUP) in;

bool tl_less(uvec2 a, uvec2 b) {
    return a.y < b.y || (a.y == b.y && a.x < b.x);
}

// bvh/build.rs `split`: the first index of the upper half of sorted prims s..e.
uint tl_split(uint s, uint e, uint keys) {
    uvec2 a = tl_key(keys + s), b = tl_key(keys + e - 1u);
    if (a == b) {
        return (s + e) / 2u;
    }
    uvec2 x = a ^ b;
    uint bit = x.y != 0u ? 32u + uint(findMSB(x.y)) : uint(findMSB(x.x));
    // (a with the bits below `bit` cleared) | 1 << bit
    uvec2 target = bit >= 32u ? uvec2(0u, (a.y >> (bit - 32u) | 1u) << (bit - 32u))
                              : uvec2((a.x >> bit | 1u) << bit, a.y);
    uint lo = s, hi = e; // partition point: the first key >= target
    while (lo < hi) {
        uint mid = lo + (hi - lo) / 2u;
        if (tl_less(tl_key(keys + mid), target)) {
            lo = mid + 1u;
        } else {
            hi = mid;
        }
    }
    return lo;
}

bool tl_is_leaf(uint b) {
    return tl_bnode(b).z == TL_BUILD_LEAF;
}

// bvh/wide.rs `area` (no FMA: the CPU's order of operations).
float tl_area(uint b) {
    precise vec3 d = tl_box_hi(b) - tl_box_lo(b);
    precise float a = d.x * d.y + d.y * d.z + d.z * d.x;
    return a;
}

// bvh/wide.rs `Collapse::emit`'s children of interior node b: open the largest interior
// child (the last of equal ones, as Iterator::max_by) until there are four, removing it as
// Vec::swap_remove does and appending its two children.
uint tl_kids(uint b, out uint kids[4]) {
    uint c = tl_bnode(b).z;
    kids[0] = c;
    kids[1] = c + 1u;
    uint nk = 2u;
    while (nk < 4u) {
        int best = -1;
        float best_area = 0.0;
        for (uint j = 0u; j < nk; j++) {
            if (!tl_is_leaf(kids[j])) {
                float a = tl_area(kids[j]);
                if (best < 0 || a >= best_area) {
                    best = int(j);
                    best_area = a;
                }
            }
        }
        if (best < 0) {
            break;
        }
        uint open = kids[best];
        kids[best] = kids[nk - 1u];
        uint oc = tl_bnode(open).z;
        kids[nk - 1u] = oc;
        kids[nk] = oc + 1u;
        nk++;
    }
    return nk;
}

// bvh/wide.rs `dequantize`: one multiply, then one add.
float tl_dequant(float origin, uint q, float scale) {
    precise float d = origin + float(q) * scale;
    return d;
}

float tl_next_up(float s) {
    return uintBitsToFloat(floatBitsToUint(s) + 1u);
}

// bvh/wide.rs `axis_scale`: the smallest scale with lo + 255 scale >= hi (0 for a flat axis).
float tl_axis_scale(float lo, float hi) {
    if (!(hi > lo)) {
        return 0.0;
    }
    precise float extent = hi - lo;
    float s = extent / 255.0;
    if (isinf(s)) {
        atomicOr(tl_levels[TL_BUILD_AT_ERROR], TL_BUILD_ERR_EXTENT);
        return 0.0;
    }
    while (s > 0.0 && tl_dequant(lo, 255u, uintBitsToFloat(floatBitsToUint(s) - 1u)) >= hi) {
        s = uintBitsToFloat(floatBitsToUint(s) - 1u);
    }
    while (tl_dequant(lo, 255u, s) < hi) {
        s = tl_next_up(s);
    }
    if (isinf(s)) {
        atomicOr(tl_levels[TL_BUILD_AT_ERROR], TL_BUILD_ERR_EXTENT);
    }
    return s;
}

// bvh/wide.rs `quantize`: the largest byte whose value is <= lo, the smallest whose value
// is >= hi.
uvec2 tl_quantize(float origin, float scale, float lo, float hi) {
    if (scale == 0.0) {
        return uvec2(0u);
    }
    uint ql = uint(clamp(floor((lo - origin) / scale), 0.0, 255.0));
    while (ql < 255u && tl_dequant(origin, ql + 1u, scale) <= lo) {
        ql++;
    }
    while (ql > 0u && tl_dequant(origin, ql, scale) > lo) {
        ql--;
    }
    uint qh = uint(clamp(ceil((hi - origin) / scale), 0.0, 255.0));
    while (qh > 0u && tl_dequant(origin, qh - 1u, scale) >= hi) {
        qh--;
    }
    while (qh < 255u && tl_dequant(origin, qh, scale) < hi) {
        qh++;
    }
    return uvec2(ql, qh);
}

// Range and dispatch size of the level after `k` (`wide`: of the 4-wide tree), whose
// entries are those made since level k's end. A binary level dispatches its entries; a
// 4-wide level that has any dispatches all params.counts.w 4-wide nodes (COLLAPSE).
void tl_next_level(bool wide, uint k) {
    uint first = tl_levels[tl_level_word(wide, k, 5u)];
    uint end = tl_levels[wide ? TL_BUILD_AT_WORK : TL_BUILD_AT_NODES];
    uint items = wide && end > first ? params.counts.w : end - first;
    uint groups = (items + TL_BUILD_GROUP - 1u) / TL_BUILD_GROUP;
    uint x = min(groups, 65535u);
    uint at = tl_level_word(wide, k + 1u, 0u);
    tl_levels[at] = x;
    tl_levels[at + 1u] = x == 0u ? 1u : (groups + x - 1u) / x;
    tl_levels[at + 2u] = 1u;
    tl_levels[at + 4u] = first;
    tl_levels[at + 5u] = end;
}

void main() {
    uint n = params.counts.x, k = params.counts.y, half_at = params.counts.z * n;
    bool wide = BUILD_PASS == TL_BUILD_COLLAPSE || BUILD_PASS == TL_BUILD_NEXT_WIDE_LEVEL;
    if (BUILD_PASS == TL_BUILD_NEXT_LEVEL || BUILD_PASS == TL_BUILD_NEXT_WIDE_LEVEL) {
        if (tl_build_index() == 0u) {
            tl_next_level(wide, k);
        }
        return;
    }
    uint entry = tl_levels[tl_level_word(wide, k, 4u)] + tl_build_index();
    if (!wide && entry >= tl_levels[tl_level_word(wide, k, 5u)]) {
        return;
    }
    if (BUILD_PASS == TL_BUILD_SPLIT) {
        uint b = entry;
        uvec4 node = tl_bnode(b);
        uvec2 range = node.xy;
        if (range.y - range.x <= BUILD_MAX_LEAF) {
            tl_bnode_set(b, uvec4(node.xy, TL_BUILD_LEAF, node.w));
            return;
        }
        uint m = tl_split(range.x, range.y, half_at);
        uint c = atomicAdd(tl_levels[TL_BUILD_AT_NODES], 2u);
        tl_bnode_set(c, uvec4(range.x, m, 0u, 0u));
        tl_bnode_set(c + 1u, uvec4(m, range.y, 0u, 0u));
        tl_bnode_set(b, uvec4(node.xy, c, node.w));
    } else if (BUILD_PASS == TL_BUILD_REFIT) {
        uint b = entry;
        uvec4 node = tl_bnode(b);
        vec3 lo, hi;
        if (node.z == TL_BUILD_LEAF) {
            tl_prim_box(tl_id(half_at + node.x), lo, hi);
            for (uint j = node.x + 1u; j < node.y; j++) {
                vec3 l, h;
                tl_prim_box(tl_id(half_at + j), l, h);
                lo = min(lo, l);
                hi = max(hi, h);
            }
        } else {
            lo = min(tl_box_lo(node.z), tl_box_lo(node.z + 1u));
            hi = max(tl_box_hi(node.z), tl_box_hi(node.z + 1u));
            uint kids[4];
            uint nk = tl_kids(b, kids);
            uint count = 1u;
            for (uint j = 0u; j < nk; j++) {
                count += tl_bnode(kids[j]).w;
            }
            node.w = count;
            tl_bnode_set(b, node);
        }
        tl_bbox_set(b, TlBox(lo.x, lo.y, lo.z, hi.x, hi.y, hi.z));
    } else if (BUILD_PASS == TL_BUILD_COLLAPSE) {
        // Every 4-wide node (params.counts.w of them) looks whether it is on this level, so
        // that a level's nodes run in depth-first order, which is key order: the arrays are
        // then read and written nearly in order. (Run in the order of a worklist filled by
        // atomics, the reads scattered over 30 GB at 250M tets and the level ran ~100x slower
        // than its share, at the address-translation knee; BENCHMARKS.md.)
        uint w = tl_build_index();
        if (w >= params.counts.w || tl_tree(w).y != k + 1u) {
            return;
        }
        uint b = tl_work(w).y;
        uint kids[4];
        uint nk = 1u;
        kids[0] = b; // a tiny input: the root is a leaf, the one child of one node
        if (!tl_is_leaf(b)) {
            nk = tl_kids(b, kids);
        }
        vec3 origin = tl_box_lo(b), top = tl_box_hi(b);
        vec3 scale = vec3(tl_axis_scale(origin.x, top.x), tl_axis_scale(origin.y, top.y),
                          tl_axis_scale(origin.z, top.z));
        uint q[6] = uint[6](0u, 0u, 0u, 0u, 0u, 0u);
        uvec4 child = uvec4(TL_EMPTY);
        uint next = w + 1u; // depth-first numbering: each child after its elder siblings' subtrees
        for (uint c = 0u; c < 4u; c++) {
            if (c >= nk) {
                for (int a = 0; a < 3; a++) {
                    q[2 * a] |= 255u << (8u * c); // an empty box: lower byte 255 > upper 0
                }
                continue;
            }
            uint kid = kids[c];
            vec3 lo = tl_box_lo(kid), hi = tl_box_hi(kid);
            for (int a = 0; a < 3; a++) {
                uvec2 qa = tl_quantize(origin[a], scale[a], lo[a], hi[a]);
                q[2 * a] |= qa.x << (8u * c);
                q[2 * a + 1] |= qa.y << (8u * c);
            }
            uvec4 kn = tl_bnode(kid);
            if (kn.z == TL_BUILD_LEAF) {
                for (uint j = kn.x; j < kn.y; j++) {
                    tl_home_set(tl_id(half_at + j), w);
                }
                uint first = DIRECT_LEAVES ? tl_id(half_at + kn.x) : kn.x;
                // wide.rs `leaf_ref`, `direct_leaf_ref`: a direct leaf's tet id takes 31 bits.
                if (DIRECT_LEAVES ? first >= ~TL_LEAF : (first > TL_LEAF_FIRST_MAX || kn.y - kn.x > 4u)) {
                    atomicOr(tl_levels[TL_BUILD_AT_ERROR], TL_BUILD_ERR_LEAF);
                }
                child[c] = DIRECT_LEAVES ? TL_LEAF | (first & ~TL_LEAF)
                                         : TL_LEAF | ((kn.y - kn.x - 1u) << TL_LEAF_COUNT_SHIFT) | (first & TL_LEAF_FIRST_MAX);
            } else {
                child[c] = next;
                atomicAdd(tl_levels[TL_BUILD_AT_WORK], 1u); // counts the next level's nodes
                tl_work_set(next, uvec2(next, kid));
                tl_tree_set(next, uvec2(w, k + 2u));
                next += kn.w;
            }
        }
        tl_wide_set(w, TlQNode(uvec4[4](uvec4(floatBitsToUint(origin), floatBitsToUint(scale.x)),
                                       uvec4(floatBitsToUint(scale.y), floatBitsToUint(scale.z), q[0], q[1]),
                                       uvec4(q[2], q[3], q[4], q[5]), child)));
    }
}
