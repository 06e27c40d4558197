#version 460
// soft-bvh (the paper's cuda-bvh): one point per invocation, located by the software BVH
// traversal of common/soft_bvh.glsl.
#extension GL_GOOGLE_include_directive : require
#extension GL_EXT_control_flow_attributes : require
#include "interface.glsl" // generated from src/interface.rs (build.rs)
#include "common/mesh.glsl"
#include "common/tet.glsl"
#include "common/samples.glsl"
#include "common/soft_bvh.glsl"
#include "common/answer.glsl"

layout(local_size_x_id = TL_SC_WORKGROUP) in;

// Deferred exact tests (LocatorOptions::defer_exact): the first pass (DEFER_EXACT, walk.glsl)
// decides every test in f32 and appends the samples it cannot decide here; the second pass
// (EXACT_PASS, an indirect dispatch over the list) locates those with the full test. The
// first pass then holds no f64 code at all (registers are allocated per kernel).
layout(std430, binding = TL_B_DEFER) buffer TlDefer {
    uvec3 tl_defer_groups; // indirect dispatch size: x counted up below, y = z = 1
    uint tl_defer_count;
    uint tl_defer_items[];
};

void main() {
    uint i = (gl_WorkGroupID.y * gl_NumWorkGroups.x + gl_WorkGroupID.x) * gl_WorkGroupSize.x + gl_LocalInvocationID.x;
    if (EXACT_PASS) {
        if (i >= tl_defer_count) {
            return;
        }
        i = tl_defer_items[i];
    } else if (i >= params.counts.x) {
        return;
    }
    vec3 p = tl_sample(i);
    tl_record(i, p);
    uvec4 ids;
    vec4 bary;
    int tet = tl_locate(p, ids, bary);
    if (DEFER_EXACT && tet == TL_DEFERRED) {
        uint slot = atomicAdd(tl_defer_count, 1u);
        tl_defer_items[slot] = i;
        if (slot % gl_WorkGroupSize.x == 0u) {
            atomicAdd(tl_defer_groups.x, 1u);
        }
        return;
    }
    tl_answer(i, tet, ids, bary, p);
}
