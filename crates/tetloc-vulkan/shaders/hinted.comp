#version 460
// Locating points from a tet near each (soft-bvh's pathlines: each particle's last tet): a
// walk through face neighbours from the hint, and the entry grid and BVH search where the walk
// fails or ends on a face of its tet, so every answer is the fresh search's, tie rule included
// (stream.comp's lookup, for points the host integrates).
#extension GL_GOOGLE_include_directive : require
#extension GL_EXT_control_flow_attributes : require
#include "interface.glsl" // generated from src/interface.rs (build.rs)
#include "common/mesh.glsl"
#include "common/tet.glsl"
#include "common/soft_bvh.glsl"
#include "common/walk.glsl"

layout(local_size_x_id = TL_SC_WORKGROUP) in;

// Each point's x, y, z (working frame) as float bits, and its hint (a tet; negative: none).
layout(std430, binding = TL_B_HINTED) readonly buffer TlHinted { uvec4 tl_hinted[]; };
layout(std430, binding = TL_B_HINTED_IDS) writeonly buffer TlHintedIds { int tl_hinted_ids[]; };

void main() {
    uint i = gl_GlobalInvocationID.x;
    if (i >= params.counts.x) {
        return;
    }
    uvec4 q = tl_hinted[i];
    vec3 p = uintBitsToFloat(q.xyz);
    int hint = int(q.w);
    uvec4 ids;
    vec4 bary;
    int tet = TL_OUTSIDE;
    if (hint >= 0 && uint(hint) < params.counts.z) {
        tet = tl_walk(hint, p, WALK_MAX, ids, bary);
        // Strictly inside: the only tet holding p, the one the fresh search would find too.
        if (tet >= 0 && !all(greaterThan(bary, vec4(0.0)))) {
            tet = TL_OUTSIDE;
        }
    }
    if (tet < 0) {
        tet = tl_locate(p, ids, bary);
    }
    tl_hinted_ids[i] = tet < 0 ? TL_OUTSIDE : tet;
}
