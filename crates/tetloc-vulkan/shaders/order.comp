#version 460
// Query ordering: a counting sort of one launch's points by the Morton key of their cell in a
// grid of 2^(3 ORDER_AXIS_BITS) cells over the mesh bounds, so that neighbouring invocations
// locate neighbouring points and read the same pages of the mesh. Random points over a large
// mesh otherwise miss the GPU's address-translation caches on nearly every read (NOTES.md,
// "The random-query collapse"). Four passes (ORDER_PASS), one dispatch each:
//   KEYS         each point's key (generated points are recorded first), bins counted;
//   SCAN_BINS    one workgroup a block of ORDER_GROUP bins: counts -> offsets in the block,
//                the block's total to the blocks array;
//   SCAN_BLOCKS  one workgroup: block totals -> block offsets;
//   SCATTER      each point to its slot (block offset + offset in the block, bumped).
// The order inside a bin is that of the atomics; answers do not depend on it.
// With ORDER_TET_FIRST (random points), the same counting sort runs first on the sample
// indices, binned by their tet (TET_KEYS, the two scans, TET_SCATTER into tl_order_perm), and
// KEYS then makes sample tl_order_perm[j] in invocation j: neighbouring invocations read
// neighbouring tets (the points, keys and bins are the same; only who makes them changes).
#extension GL_GOOGLE_include_directive : require
#extension GL_EXT_control_flow_attributes : require
#include "interface.glsl" // generated from src/interface.rs (build.rs)
#include "common/mesh.glsl"
#include "common/samples.glsl"

layout(local_size_x = TL_ORDER_GROUP) in;

layout(std430, binding = TL_B_ORDER_KEYS) buffer TlOrderKeys { uint tl_order_keys[]; };
layout(std430, binding = TL_B_ORDER_BINS) buffer TlOrderBins { uint tl_order_bins[]; };
layout(std430, binding = TL_B_ORDER_BLOCKS) buffer TlOrderBlocks { uint tl_order_blocks[]; };

shared uint tl_scan[TL_ORDER_GROUP];

// The bits of v (< 1024) spread to every third bit.
uint tl_spread3(uint v) {
    v = (v * 0x00010001u) & 0xFF0000FFu;
    v = (v * 0x00000101u) & 0x0F00F00Fu;
    v = (v * 0x00000011u) & 0xC30C30C3u;
    v = (v * 0x00000005u) & 0x49249249u;
    return v;
}

// The Morton key of p's cell; points outside the bounds go to the border cells.
uint tl_order_key(vec3 p) {
    const float cells = float(1u << TL_ORDER_AXIS_BITS);
    vec3 lo = params.lo_tmin.xyz, extent = params.hi_tmax.xyz - lo;
    vec3 scale = vec3(greaterThan(extent, vec3(0.0))) * cells / max(extent, vec3(1e-30));
    uvec3 c = uvec3(clamp((p - lo) * scale, vec3(0.0), vec3(cells - 1.0)));
    return tl_spread3(c.x) | (tl_spread3(c.y) << 1) | (tl_spread3(c.z) << 2);
}

// Exclusive prefix sum of `v` over the workgroup (Hillis-Steele in shared memory); `total`
// gets the sum of all.
uint tl_group_scan(uint v, out uint total) {
    uint t = gl_LocalInvocationID.x;
    tl_scan[t] = v;
    barrier();
    [[unroll]] for (uint d = 1u; d < TL_ORDER_GROUP; d <<= 1u) {
        uint add = t >= d ? tl_scan[t - d] : 0u;
        barrier();
        tl_scan[t] += add;
        barrier();
    }
    total = tl_scan[TL_ORDER_GROUP - 1u];
    return tl_scan[t] - v;
}

void main() {
    uint i = (gl_WorkGroupID.y * gl_NumWorkGroups.x + gl_WorkGroupID.x) * gl_WorkGroupSize.x + gl_LocalInvocationID.x;
    if (ORDER_PASS == TL_ORDER_TET_KEYS) {
        if (i < params.counts.x) {
            // Bins of 2^shift consecutive tets, ORDER_BINS of them over the mesh.
            int shift = max(findMSB(max(params.counts.z, 2u) - 1u) + 1 - 3 * TL_ORDER_AXIS_BITS, 0);
            uint key = tl_random_tet(tl_random_state(i)) >> uint(shift);
            tl_order_keys[i] = key;
            atomicAdd(tl_order_bins[key], 1u);
        }
    } else if (ORDER_PASS == TL_ORDER_TET_SCATTER) {
        if (i < params.counts.x) {
            uint key = tl_order_keys[i];
            tl_order_perm[tl_order_blocks[key / TL_ORDER_GROUP] + atomicAdd(tl_order_bins[key], 1u)] = i;
        }
    } else if (ORDER_PASS == TL_ORDER_KEYS) {
        if (i < params.counts.x) {
            if (ORDER_TET_FIRST) {
                i = tl_order_perm[i];
            }
            vec3 p = tl_sample(i);
            tl_record(i, p);
            uint key = tl_order_key(p);
            tl_order_keys[i] = key;
            atomicAdd(tl_order_bins[key], 1u);
        }
    } else if (ORDER_PASS == TL_ORDER_SCAN_BINS) {
        uint total;
        uint offset = tl_group_scan(tl_order_bins[i], total);
        tl_order_bins[i] = offset;
        if (gl_LocalInvocationID.x == 0u) {
            tl_order_blocks[gl_WorkGroupID.x] = total;
        }
    } else if (ORDER_PASS == TL_ORDER_SCAN_BLOCKS) {
        // One workgroup: each invocation scans PER consecutive blocks.
        const uint PER = TL_ORDER_BLOCKS / TL_ORDER_GROUP;
        uint first = gl_LocalInvocationID.x * PER, sum = 0u;
        [[unroll]] for (uint k = 0u; k < PER; k++) {
            sum += tl_order_blocks[first + k];
        }
        uint total;
        uint offset = tl_group_scan(sum, total);
        [[unroll]] for (uint k = 0u; k < PER; k++) {
            uint count = tl_order_blocks[first + k];
            tl_order_blocks[first + k] = offset;
            offset += count;
        }
    } else if (i < params.counts.x) {
        uint key = tl_order_keys[i];
        uint slot = tl_order_blocks[key / TL_ORDER_GROUP] + atomicAdd(tl_order_bins[key], 1u);
        tl_order_points[3 * slot] = tl_queries[3 * i];
        tl_order_points[3 * slot + 1] = tl_queries[3 * i + 1];
        tl_order_points[3 * slot + 2] = tl_queries[3 * i + 2];
        tl_order_perm[slot] = i;
    }
}
