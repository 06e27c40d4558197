#version 460
// Exclusive prefix sums over tl_scan (src/build/scan.rs records the recursion): SCAN_LOCAL
// scans each chunk of SCAN_CHUNK values in place and writes the chunk's total to the sums
// (or, for a single chunk, after the values); SCAN_ADD adds each chunk's scanned sum to its
// values and copies the grand total after them. params.counts: values, their first word,
// the sums' first word, 1 when there is a single chunk.
#extension GL_GOOGLE_include_directive : require
#include "interface.glsl" // generated from src/interface.rs (build.rs)
#include "common/mesh.glsl"
#include "build/build.glsl"

layout(local_size_x = TL_BUILD_GROUP) in;

const uint PER = TL_SCAN_CHUNK / TL_BUILD_GROUP;

void main() {
    uint n = params.counts.x, at = params.counts.y, sums = params.counts.z;
    uint chunk = gl_WorkGroupID.y * gl_NumWorkGroups.x + gl_WorkGroupID.x;
    if (BUILD_PASS == TL_BUILD_SCAN_LOCAL) {
        if (chunk * TL_SCAN_CHUNK >= n) {
            return; // the whole workgroup: a row of the 2-D grid past the last chunk
        }
        uint first = chunk * TL_SCAN_CHUNK + gl_LocalInvocationID.x * PER;
        uint v[PER];
        uint sum = 0u;
        for (uint k = 0u; k < PER; k++) {
            v[k] = first + k < n ? tl_scan[at + first + k] : 0u;
            sum += v[k];
        }
        uint total;
        uint offset = tl_group_scan(sum, total);
        for (uint k = 0u; k < PER; k++) {
            if (first + k < n) {
                tl_scan[at + first + k] = offset;
            }
            offset += v[k];
        }
        if (gl_LocalInvocationID.x == 0u) {
            tl_scan[params.counts.w == 1u ? at + n : sums + chunk] = total;
        }
    } else {
        uint i = tl_build_index();
        uint chunks = (n + TL_SCAN_CHUNK - 1u) / TL_SCAN_CHUNK;
        if (i < n) {
            tl_scan[at + i] += tl_scan[sums + i / TL_SCAN_CHUNK];
        }
        if (i == 0u) {
            tl_scan[at + n] = tl_scan[sums + chunks];
        }
    }
}
