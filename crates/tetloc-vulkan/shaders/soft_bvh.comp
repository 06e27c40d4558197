#version 460
// soft-bvh (the paper's cuda-bvh): one point per invocation, located by the software BVH
// traversal of common/soft_bvh.glsl.
#extension GL_GOOGLE_include_directive : require
#extension GL_EXT_control_flow_attributes : require
#include "common/types.glsl"
#include "common/mesh.glsl"
#include "common/tet.glsl"
#include "common/samples.glsl"
#include "common/soft_bvh.glsl"

layout(local_size_x_id = 7) in;

void main() {
    uint i = (gl_WorkGroupID.y * gl_NumWorkGroups.x + gl_WorkGroupID.x) * gl_WorkGroupSize.x + gl_LocalInvocationID.x;
    if (i >= params.counts.x) {
        return;
    }
    vec3 p = tl_sample(i);
    tl_record(i, p);
    uvec4 ids;
    vec4 bary;
    int tet = tl_locate(p, ids, bary);
    tl_store(i, tet, OUTPUT_MODE == TL_OUT_IDS ? 0.0 : tl_value(tet, ids, bary));
}
