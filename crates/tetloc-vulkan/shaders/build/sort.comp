#version 460
// Morton keys of the prims' box centres (tets, or a mixed mesh's cells: tl_prim_box) and
// their radix sort (src/build/sort.rs), the first stage of the BVH build; the same codes as
// tetloc_core::bvh::morton (21 bits an axis over the centres' bounds), sorted by code then
// prim id, so the tree is the CPU builder's.
//   BOUNDS        the centres' bounds, by atomics on order-preserving words;
//   KEYS          each prim's code (params: the bounds' min and the host's scale) and id;
//   SORT_COUNT    one bit of an LSD radix sort: the zeros of each chunk of SCAN_CHUNK keys;
//   SORT_SCATTER  (after the scan of those counts) each key and id to its stable slot.
// params.counts: prims, the bit, the source half, 0.
#extension GL_GOOGLE_include_directive : require
#include "interface.glsl" // generated from src/interface.rs (build.rs)
#include "common/mesh.glsl"
#include "build/build.glsl"

layout(local_size_x = TL_BUILD_GROUP) in;

const uint PER = TL_SCAN_CHUNK / TL_BUILD_GROUP;

// Floats as words that compare in the same order.
uint tl_ordered(float f) {
    uint b = floatBitsToUint(f);
    return (b & 0x80000000u) != 0u ? ~b : b | 0x80000000u;
}

// Bit `bit` of axis value v goes to bit 3 bit + axis of the code (x in bit 0).
uvec2 tl_spread(uint v, uint axis) {
    uvec2 code = uvec2(0u);
    for (uint b = 0u; b < 21u; b++) {
        uint pos = 3u * b + axis;
        uint bit = (v >> b) & 1u;
        if (pos < 32u) {
            code.x |= bit << pos;
        } else {
            code.y |= bit << (pos - 32u);
        }
    }
    return code;
}

// The box centre of prim t, as Aabb::centre.
vec3 tl_centre(uint t) {
    vec3 lo, hi;
    tl_prim_box(t, lo, hi);
    precise vec3 c = 0.5 * (lo + hi);
    return c;
}

void main() {
    uint n = params.counts.x;
    if (BUILD_PASS == TL_BUILD_BOUNDS) {
        uint t = tl_build_index();
        if (t < n) {
            vec3 c = tl_centre(t);
            for (int a = 0; a < 3; a++) {
                atomicMin(tl_levels[TL_BUILD_AT_BOUNDS + a], tl_ordered(c[a]));
                atomicMax(tl_levels[TL_BUILD_AT_BOUNDS + 3 + a], tl_ordered(c[a]));
            }
        }
    } else if (BUILD_PASS == TL_BUILD_KEYS) {
        uint t = tl_build_index();
        if (t < n) {
            // Morton::code: ((p - lo) * scale) truncated, capped at the last cell.
            vec3 c = tl_centre(t);
            precise vec3 x = (c - params.lo_tmin.xyz) * params.hi_tmax.xyz;
            uvec3 q = uvec3(min(x, vec3(2097151.0)));
            tl_key_set(t, tl_spread(q.x, 0u) | tl_spread(q.y, 1u) | tl_spread(q.z, 2u));
            tl_id_set(t, t);
        }
    } else {
        uint bit = params.counts.y, src = params.counts.z * n, dst = (1u - params.counts.z) * n;
        uint chunk = gl_WorkGroupID.y * gl_NumWorkGroups.x + gl_WorkGroupID.x;
        uint chunks = (n + TL_SCAN_CHUNK - 1u) / TL_SCAN_CHUNK;
        if (chunk >= chunks) {
            return; // the whole workgroup: a row of the 2-D grid past the last chunk
        }
        uint first = chunk * TL_SCAN_CHUNK + gl_LocalInvocationID.x * PER;
        uint zeros = 0u;
        for (uint k = 0u; k < PER; k++) {
            if (first + k < n) {
                uvec2 key = tl_key(src + first + k);
                uint b = bit < 32u ? (key.x >> bit) & 1u : (key.y >> (bit - 32u)) & 1u;
                zeros += 1u - b;
            }
        }
        uint total;
        uint before = tl_group_scan(zeros, total);
        if (BUILD_PASS == TL_BUILD_SORT_COUNT) {
            if (gl_LocalInvocationID.x == 0u) {
                tl_scan[chunk] = total;
            }
            return;
        }
        uint all_zeros = tl_scan[chunks];
        uint z = tl_scan[chunk] + before; // zeros before this invocation's first key
        for (uint k = 0u; k < PER; k++) {
            uint i = first + k;
            if (i < n) {
                uvec2 key = tl_key(src + i);
                uint b = bit < 32u ? (key.x >> bit) & 1u : (key.y >> (bit - 32u)) & 1u;
                uint slot = b == 0u ? z : all_zeros + i - z;
                z += 1u - b;
                tl_key_set(dst + slot, key);
                tl_id_set(dst + slot, tl_id(src + i));
            }
        }
    }
}
